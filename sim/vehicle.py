"""One simulated vehicle: a :class:`BatchSim` of size 1 seen through 1-D arrays (SPEC §5).

It runs the very same numba kernel as the batch stepper (:func:`sim.physics.step_vehicles`), so a
vehicle here and vehicle i of a batch with the same seed produce identical trajectories.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from mavlink_bridge.contract.frames import GeoPoint, LocalNedFrame
from mavlink_bridge.contract.wire import GroundTruth
from sim.batch import BatchSim
from sim.end_reason import EndReason
from sim.vehicle_config import VehicleConfig
from sim.world import World


class VehicleSim:
    """A single quadrotor; attributes are 1-D views (``pos_ned`` (3,), ``omega_rad_s`` (4,), …)."""

    def __init__(
        self,
        vehicle: VehicleConfig,
        *,
        physics_hz: int = 1000,
        control_hz: int = 250,
        world: World | None = None,
        seed: int = 0,
        payload_kg: float | None = None,
    ) -> None:
        self.batch = BatchSim(
            vehicle, 1, physics_hz=physics_hz, control_hz=control_hz, world=world, seed=seed, payload_kg=payload_kg
        )
        self.vehicle = vehicle
        self.world = self.batch.world
        self._cmd = np.zeros((1, 4))
        self._home_frame = LocalNedFrame(self.world.home)
        self._frames: dict[GeoPoint, LocalNedFrame] = {self.world.home: self._home_frame}

    # views into the batch arrays (row 0)
    @property
    def pos_ned(self) -> np.ndarray:
        """(3,) position, m, NED about home."""
        return self.batch.state[0, 0:3]

    @property
    def vel_ned(self) -> np.ndarray:
        """(3,) velocity, m/s, NED."""
        return self.batch.state[0, 3:6]

    @property
    def q_ned_frd(self) -> np.ndarray:
        """(4,) attitude quaternion body FRD → NED, Hamilton, w first."""
        return self.batch.state[0, 6:10]

    @property
    def rate_frd(self) -> np.ndarray:
        """(3,) body rate, rad/s, FRD."""
        return self.batch.state[0, 10:13]

    @property
    def omega_rad_s(self) -> np.ndarray:
        """(4,) rotor speeds, rad/s, PX4 motor order."""
        return self.batch.state[0, 13:17]

    @property
    def specific_force_frd(self) -> np.ndarray:
        """(3,) accelerometer truth (specific force), m/s², FRD."""
        return self.batch.specific_force_frd[0]

    @property
    def wind_ned_m_s(self) -> np.ndarray:
        """(3,) current wind, m/s, NED."""
        return self.batch.wind_ned_m_s[0]

    @property
    def payload_kg(self) -> float:
        return float(self.batch.payload_kg[0])

    @property
    def mass_kg(self) -> float:
        return float(self.batch.mass_kg[0])

    @property
    def end_reason(self) -> EndReason:
        return EndReason(int(self.batch.end_reason[0]))

    @property
    def on_ground(self) -> bool:
        """True while resting on (loaded by) the ground."""
        return bool(self.batch.on_ground[0])

    @property
    def min_clearance_m(self) -> float:
        return float(self.batch.min_clearance_m[0])

    @property
    def payload_released_at_s(self) -> float:
        return float(self.batch.payload_released_at_s[0])

    @property
    def t_s(self) -> float:
        return self.batch.t_s

    @property
    def t_us(self) -> int:
        return self.batch.t_us

    @property
    def n(self) -> int:
        return 1

    @property
    def substeps(self) -> int:
        return self.batch.substeps

    @property
    def physics_dt_s(self) -> float:
        return self.batch.physics_dt_s

    @property
    def control_dt_s(self) -> float:
        return self.batch.control_dt_s

    def reset(self, pos_ned: np.ndarray | None = None, yaw_rad: float | None = None) -> None:
        """Restart at rest (default: on the ground at home, level)."""
        self.batch.reset(pos_ned, yaw_rad)

    def step(self, motor_cmd: np.ndarray | Sequence[float]) -> None:
        """One control step with motor commands (4,) in [0, 1] (an array or a sequence of 4 floats)."""
        self._cmd[0] = motor_cmd
        self.batch.step(self._cmd)

    def release_payload(self) -> None:
        self.batch.release_payload()

    def end(self, reason: EndReason) -> None:
        self.batch.end(reason)

    def hover_omega_rad_s(self) -> float:
        return float(self.batch.hover_omega_rad_s()[0])

    def ground_truth(self, home: GeoPoint | None = None) -> GroundTruth:
        """The true state as the wire's :class:`GroundTruth` (geodetic about ``home``, default the world's).

        Runs every control step: one ``tolist()`` of the state, scalar geodetic conversion.
        """
        if home is None:
            frame = self._home_frame
        else:
            frame = self._frames.get(home) or self._frames.setdefault(home, LocalNedFrame(home))
        batch = self.batch
        x = batch.state[0].tolist()
        a = batch.specific_force_frd[0].tolist()
        geo = frame.geodetic_from_ned(x[0], x[1], x[2])
        return GroundTruth(
            batch.t_us,
            (x[6], x[7], x[8], x[9]),
            (x[10], x[11], x[12]),
            geo.lat_deg,
            geo.lon_deg,
            geo.alt_amsl_m,
            (x[3], x[4], x[5]),
            (a[0], a[1], a[2]),
        )
