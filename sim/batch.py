"""Vectorized batch stepper: N vehicles of one configuration as arrays, on the shared numba kernel (SPEC §5).

One :meth:`BatchSim.step` is one control step: ``substeps = physics_hz / control_hz`` RK4 steps
(default 1 kHz physics, 250 Hz control). Per-vehicle state lives in one preallocated (N, 17) array;
the named attributes (``pos_ned``, ``vel_ned``, …) are views into it. Each vehicle has its own
deterministic random stream (gusts), seeded from ``seed`` (one int, or one per vehicle) and the
world's wind seed, so a vehicle in a batch and a single vehicle seeded alike agree exactly.
"""

from __future__ import annotations

import math

import numpy as np

from mavlink_bridge.contract.frames import GRAVITY_M_S2, quat_from_euler
from sim import physics as ph
from sim.end_reason import EndReason
from sim.vehicle_config import VehicleConfig
from sim.wind import vehicle_stream_seed
from sim.world import World, empty_world


def pack_vehicle_params(vehicle: VehicleConfig) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Vehicle constants for the kernel: ``vp`` (N_PARAMS,), rotor (x, y) (4, 2) and yaw directions (4,)."""
    vp = np.zeros(ph.N_PARAMS)
    vp[ph.P_MASS_KG] = vehicle.mass_kg
    vp[ph.P_JX], vp[ph.P_JY], vp[ph.P_JZ] = vehicle.inertia_kg_m2
    vp[ph.P_KF] = vehicle.k_f_n_per_rad2_s2
    vp[ph.P_KM] = vehicle.k_m_nm_per_rad2_s2
    vp[ph.P_OMEGA_MAX] = vehicle.omega_max_rad_s
    vp[ph.P_OMEGA_MIN] = vehicle.omega_min_rad_s
    vp[ph.P_TAU_MOTOR] = vehicle.motor_time_constant_s
    vp[ph.P_DRAG_X], vp[ph.P_DRAG_Y], vp[ph.P_DRAG_Z] = vehicle.drag_body_n_per_m2_s2
    vp[ph.P_ROTOR_DRAG] = vehicle.rotor_drag_n_s_per_m
    vp[ph.P_MU] = vehicle.ground_friction_coeff
    vp[ph.P_IMPACT_SPEED] = vehicle.ground_impact_speed_m_s
    vp[ph.P_COLLISION_RADIUS] = vehicle.collision_radius_m
    rotor_xy = np.array(vehicle.rotor_pos_frd_m, dtype=np.float64)
    rotor_dir = np.array(vehicle.rotor_yaw_dir, dtype=np.float64)
    return vp, rotor_xy, rotor_dir


class BatchSim:
    """N quadrotors of one :class:`VehicleConfig` in one :class:`World`, stepped together."""

    def __init__(
        self,
        vehicle: VehicleConfig,
        n: int = 1,
        *,
        physics_hz: int = 1000,
        control_hz: int = 250,
        world: World | None = None,
        seed: int | np.ndarray = 0,
        payload_kg: float | np.ndarray | None = None,
    ) -> None:
        """``payload_kg`` per vehicle (default: the world's payload); ``seed`` one int or one per vehicle."""
        if n < 1:
            raise ValueError(f"n: need at least one vehicle, got {n}")
        if control_hz <= 0 or physics_hz <= 0 or physics_hz % control_hz != 0:
            raise ValueError(f"physics_hz ({physics_hz}) must be a positive multiple of control_hz ({control_hz})")
        self.vehicle = vehicle
        self.world = world or empty_world()
        self.n = n
        self.physics_hz = physics_hz
        self.control_hz = control_hz
        self.substeps = physics_hz // control_hz
        self.physics_dt_s = 1.0 / physics_hz
        self.control_dt_s = 1.0 / control_hz
        self._vp, self._rotor_xy, self._rotor_dir = pack_vehicle_params(vehicle)
        self._obstacle_kinds, self._obstacle_params = self.world.obstacle_arrays()
        wind = self.world.wind
        self._wind_mean_ned = np.array(wind.mean_ned_m_s, dtype=np.float64)
        self._gust_sigma_m_s = float(wind.gust_m_s)
        self._gust_decay = math.exp(-self.physics_dt_s / wind.gust_time_constant_s)
        seeds = np.broadcast_to(np.asarray(seed, dtype=np.int64), (n,))
        self._rng_seed = np.array([vehicle_stream_seed(int(s), wind.seed) for s in seeds], dtype=np.uint64)
        payload = self.world.payload_kg if payload_kg is None else payload_kg
        self._payload_initial_kg = np.broadcast_to(np.asarray(payload, dtype=np.float64), (n,)).copy()
        if np.any(~np.isfinite(self._payload_initial_kg)) or np.any(self._payload_initial_kg < 0.0):
            raise ValueError(f"payload_kg: must be finite and >= 0, got {payload}")
        if np.any(self._payload_initial_kg > vehicle.payload_max_kg + 1e-12):
            raise ValueError(
                f"payload_kg: {self._payload_initial_kg.max()} exceeds {vehicle.name} payload_max_kg "
                f"{vehicle.payload_max_kg}"
            )
        # preallocated state and buffers
        self.state = np.zeros((n, ph.N_STATE))
        self.payload_kg = np.zeros(n)
        self.gust_ned_m_s = np.zeros((n, 3))
        self._rng_state = np.zeros(n, dtype=np.uint64)
        self.end_reason = np.zeros(n, dtype=np.int8)
        self.on_ground = np.zeros(n, dtype=np.bool_)
        self.min_clearance_m = np.full(n, np.inf)
        self.specific_force_frd = np.zeros((n, 3))
        self.payload_released_at_s = np.full(n, np.nan)
        self._motor_cmd = np.zeros((n, 4))
        self._scratch = np.zeros((ph.N_SCRATCH, ph.N_STATE))
        self._steps = 0
        self.reset()

    # ---- state views ------------------------------------------------------------------------------
    @property
    def pos_ned(self) -> np.ndarray:
        """(n, 3) position, m, NED about home (a view: write with ``[...]``)."""
        return self.state[:, ph.POS : ph.POS + 3]

    @property
    def vel_ned(self) -> np.ndarray:
        """(n, 3) velocity, m/s, NED."""
        return self.state[:, ph.VEL : ph.VEL + 3]

    @property
    def q_ned_frd(self) -> np.ndarray:
        """(n, 4) attitude quaternion body FRD → NED, Hamilton, w first."""
        return self.state[:, ph.QUAT : ph.QUAT + 4]

    @property
    def rate_frd(self) -> np.ndarray:
        """(n, 3) body angular rate, rad/s, FRD."""
        return self.state[:, ph.RATE : ph.RATE + 3]

    @property
    def omega_rad_s(self) -> np.ndarray:
        """(n, 4) rotor speeds, rad/s, PX4 motor order."""
        return self.state[:, ph.OMEGA : ph.OMEGA + 4]

    @property
    def t_s(self) -> float:
        """Simulated time since reset (s)."""
        return self._steps / self.control_hz

    @property
    def t_us(self) -> int:
        """Simulated time since reset (µs), exact integer."""
        return self._steps * 1_000_000 // self.control_hz

    @property
    def wind_ned_m_s(self) -> np.ndarray:
        """(n, 3) current wind (mean + gust), m/s, NED (the air's velocity)."""
        return self._wind_mean_ned + self.gust_ned_m_s

    @property
    def mass_kg(self) -> np.ndarray:
        """(n,) current total mass: airframe plus attached payload."""
        return self.vehicle.mass_kg + self.payload_kg

    # ---- control ----------------------------------------------------------------------------------
    def reset(self, pos_ned: np.ndarray | None = None, yaw_rad: float | np.ndarray | None = None) -> None:
        """Restart at t = 0: at rest (motors stopped) at ``pos_ned`` (default home, on the ground), level, ``yaw_rad``.

        Also restores the initial payload, the random streams, clearances and end reasons.
        """
        self.state[:] = 0.0
        if pos_ned is not None:
            self.pos_ned[:] = np.broadcast_to(np.asarray(pos_ned, dtype=np.float64), (self.n, 3))
        yaw = np.broadcast_to(np.asarray(0.0 if yaw_rad is None else yaw_rad, dtype=np.float64), (self.n,))
        self.q_ned_frd[:] = quat_from_euler(np.zeros(self.n), np.zeros(self.n), yaw)
        self.payload_kg[:] = self._payload_initial_kg
        self.gust_ned_m_s[:] = 0.0
        self._rng_state[:] = self._rng_seed
        self.end_reason[:] = EndReason.RUNNING
        self.min_clearance_m[:] = np.inf
        self.payload_released_at_s[:] = np.nan
        self._steps = 0
        self.on_ground[:] = self.pos_ned[:, 2] >= 0.0
        self.specific_force_frd[:] = 0.0
        self.specific_force_frd[self.on_ground, 2] = -GRAVITY_M_S2
        if self._obstacle_kinds.size:
            self.min_clearance_m[:] = self.world.clearance_m(self.pos_ned)

    def step(self, motor_cmd: np.ndarray) -> None:
        """One control step with motor commands ``motor_cmd`` (n, 4) (or (4,) for all) in [0, 1].

        Commands outside [0, 1] act as the nearest bound and non-finite ones stop that motor: the kernel's
        ``omega_command_rad_s`` clamps, so the commands are only copied (broadcast) here, not clipped twice.
        """
        self._motor_cmd[:] = motor_cmd
        ph.step_vehicles(
            self.state,
            self._motor_cmd,
            self.payload_kg,
            self._vp,
            self._rotor_xy,
            self._rotor_dir,
            self._wind_mean_ned,
            self.gust_ned_m_s,
            self._gust_sigma_m_s,
            self._gust_decay,
            self._rng_state,
            self.end_reason,
            self.on_ground,
            self.min_clearance_m,
            self.specific_force_frd,
            self._obstacle_kinds,
            self._obstacle_params,
            self.physics_dt_s,
            self.substeps,
            self._scratch,
        )
        self._steps += 1

    def release_payload(self, mask: np.ndarray | None = None) -> None:
        """Drop the payload of the vehicles in ``mask`` (bool (n,), default all); no-op when already dropped."""
        sel = np.ones(self.n, dtype=bool) if mask is None else np.asarray(mask, dtype=bool)
        sel = sel & (self.payload_kg > 0.0) & (self.end_reason == EndReason.RUNNING)
        self.payload_kg[sel] = 0.0
        self.payload_released_at_s[sel] = self.t_s

    def hover_omega_rad_s(self) -> np.ndarray:
        """(n,) rotor speed that balances the current weight: ``sqrt(m g / (4 k_f))``."""
        return np.sqrt(self.mass_kg * GRAVITY_M_S2 / (4.0 * self.vehicle.k_f_n_per_rad2_s2))

    def end(self, reason: EndReason, mask: np.ndarray | None = None) -> None:
        """End running vehicles (default all) with ``reason`` (e.g. STOPPED, AUTOPILOT_LOST); they freeze."""
        sel = np.ones(self.n, dtype=bool) if mask is None else np.asarray(mask, dtype=bool)
        self.end_reason[sel & (self.end_reason == EndReason.RUNNING)] = int(reason)

    @property
    def running(self) -> np.ndarray:
        """(n,) bool: vehicles still being integrated."""
        return self.end_reason == EndReason.RUNNING
