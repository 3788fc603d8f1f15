"""The vehicles of one world, stepped together (SPEC §13); no sockets (``sim.server`` serves them).

A world without ``vehicles:`` is a fleet of one (:func:`world_vehicles`): instance 0 at home, seeded with the run's
seed itself, so it flies what the single-vehicle simulator always flew.

Vehicles of one airframe share one :class:`BatchSim` (one compiled call steps them all); a fleet of mixed
airframes has one batch per airframe. Each vehicle has its own seeded streams (gusts, sensor noise, obstacle
sensor), derived from the world's seed and its instance only (:func:`vehicle_seed`), so adding a vehicle never
shifts another's. Vehicles are physical to each other: two whose collision spheres (``collision_radius_m``, the
half diagonal plus a propeller) overlap are in contact, a COLLISION for both; each vehicle's obstacle sensor sees
the others as spheres of that radius (obstacle id ``len(world.obstacles) + instance``).

Two separations are kept per vehicle, the truth the encounter Monte Carlo judges: ``min_separation_m``, the
closest 3D approach to another vehicle surface to surface (0 is a contact), and ``min_volume_sep_m``, the closest
approach to another airborne vehicle in the default UAV separation volume's own measure, centre to centre:
``max(horizontal, vertical * 10 / 5)``, so below ``UAV_VOLUME_HOR_M`` (10 m) the pair was inside the volume
(closer than 10 m horizontally and than 5 m vertically at once, NAV_TRAFF_U_HOR / NAV_TRAFF_U_VER), and e.g.
16 m is "8 m above or below" or "16 m beside". Vehicles standing on the ground are parked traffic, not in
conflict (pads are spaced for it): the measure counts pairs while both are airborne.

The pairs that came inside that volume are pair-events (``sim.separation_events``): ``volume_pairs`` (both
airborne) and ``volume_pairs_ground`` (one of the two standing on the ground: not a loss of separation in flight,
kept apart to be written with its count), each pair once with the sim time it first came inside.

Each recorded step also folds every vehicle's tilt into ``max_xy2`` (see :func:`tilt_deg`).
"""

from __future__ import annotations

import hashlib
import math

import numpy as np

from sim.batch import BatchSim
from sim.end_reason import EndReason
from sim.fleet_world import FleetSpec, FleetVehicle
from sim.frame_kernel import SensorValues
from sim.obstacle_sensor import ObstacleSensor
from sim.sensors import SensorModel
from sim.separation_kernel import EVENT_CONTACT, EVENT_VOLUME_AIRBORNE, pair_separation_step
from sim.vehicle_config import VehicleConfig
from sim.world import World

_RUNNING = int(EndReason.RUNNING)
#: The default UAV separation volume (the autopilot's NAV_TRAFF_U_HOR / NAV_TRAFF_U_VER defaults): a pair of
#: airborne vehicles is inside it when both closer than 10 m horizontally and than 5 m vertically.
UAV_VOLUME_HOR_M = 10.0
UAV_VOLUME_VER_M = 5.0
#: The name of the one vehicle of a world without ``vehicles:``.
SOLO_NAME = "vehicle"


def vehicle_seed(seed: int, instance: int) -> int:
    """The seed of vehicle ``instance``'s streams in a fleet world run with ``seed`` (63 bits; independent of the
    other vehicles, so adding one shifts no other's streams)."""
    state = np.random.SeedSequence([int(seed) & (2**64 - 1), instance]).generate_state(1, np.uint64)[0]
    return int(state) >> 1


def world_vehicles(fleet: FleetSpec) -> tuple[FleetVehicle, ...]:
    """The vehicles of a world: its ``vehicles:``, or for a world without them the one vehicle at home (instance
    0, MAV_SYS_ID 1)."""
    if fleet.is_fleet:
        return fleet.vehicles
    return (FleetVehicle(0, SOLO_NAME, None, 0.0, 0.0, (), None, None),)


def fleet_seeds(seed: int, fleet: FleetSpec) -> tuple[int, ...]:
    """Each vehicle's seed: :func:`vehicle_seed` per instance in a fleet world, the run's ``seed`` itself for the
    one vehicle of a world without ``vehicles:`` (what the single-vehicle simulator always used)."""
    if not fleet.is_fleet:
        return (seed,)
    return tuple(vehicle_seed(seed, i) for i in range(len(fleet.vehicles)))


def tilt_deg(q_ned_frd: np.ndarray) -> float:
    """Angle between body down and NED down (°): ``acos(R_zz)``, ``R_zz = 1 − 2(x² + y²)``."""
    x, y = float(q_ned_frd[1]), float(q_ned_frd[2])
    return tilt_deg_from_xy2(x * x + y * y)


def tilt_deg_from_xy2(xy2: float) -> float:
    """:func:`tilt_deg` from ``x² + y²`` of the quaternion (monotonic in it: the max tilt is that of the max)."""
    return math.degrees(math.acos(max(-1.0, min(1.0, 1.0 - 2.0 * float(xy2)))))


class FleetSim:
    """The vehicles of a world: their batches, sensors and contacts (row i = instance i)."""

    def __init__(
        self,
        world: World,
        fleet: FleetSpec,
        airframes: tuple[VehicleConfig, ...],
        *,
        seed: int = 0,
        physics_hz: int = 1000,
        control_hz: int = 250,
        sensor_noise: bool = True,
    ) -> None:
        """``airframes[i]`` is vehicle i's (ValueError for a bad rate or vehicles placed in contact)."""
        self.world = world
        self.fleet = fleet
        self.vehicles = vehicles = world_vehicles(fleet)
        n = len(vehicles)
        self.n = n
        self.seeds = fleet_seeds(seed, fleet)
        self.radius_m = np.array([a.collision_radius_m for a in airframes])
        home_ned = np.array([(v.home_north_m, v.home_east_m, 0.0) for v in vehicles]).reshape(n, 3)
        self.batches: list[BatchSim] = []
        self.rows: list[tuple[int, int]] = [(0, 0)] * n  # vehicle -> (batch, row)
        self.members: list[np.ndarray] = []  # batch -> vehicle indices
        for name in dict.fromkeys(a.name for a in airframes):
            members = np.array([i for i in range(n) if airframes[i].name == name])
            batch = BatchSim(
                airframes[members[0]],
                len(members),
                physics_hz=physics_hz,
                control_hz=control_hz,
                world=world,
                seed=np.array([self.seeds[i] for i in members], dtype=np.int64),
            )
            batch.reset(home_ned[members])
            for row, i in enumerate(members):
                self.rows[i] = (len(self.batches), row)
            self.batches.append(batch)
            self.members.append(members)
        # each batch's vehicles as an index: a slice when they are consecutive (one airframe: no fancy indexing)
        self._index = [
            slice(m[0], m[-1] + 1) if np.array_equal(m, np.arange(m[0], m[-1] + 1)) else m for m in self.members
        ]
        self.sensors = [SensorModel(airframes[i], world.home, self.seeds[i], noise=sensor_noise) for i in range(n)]
        self.values = [SensorValues(self.batches[b], self.sensors[i], row) for i, (b, row) in enumerate(self.rows)]
        self.obstacle_sensors = [ObstacleSensor(world, self.seeds[i]) for i in range(n)]
        self._views = len(self.batches) == 1  # one airframe: rows are instances, the arrays are the batch's own
        if self._views:
            batch = self.batches[0]
            self.pos_ned, self.vel_ned = batch.state[:, 0:3], batch.state[:, 3:6]
            self.end_reason, self.on_ground = batch.end_reason, batch.on_ground
        else:
            self.pos_ned = np.zeros((n, 3))
            self.vel_ned = np.zeros((n, 3))
            self.end_reason = np.zeros(n, dtype=np.int8)
            self.on_ground = np.ones(n, dtype=bool)
            self.gather()
        self.contacts: list[tuple[int, int, float]] = []  # (i, j, t_s) of each first contact of a pair
        self._touching = np.zeros((n, n), dtype=bool)
        self.min_separation_m = np.full(n, np.inf)  # closest approach to any other vehicle (surface to surface)
        self.min_volume_sep_m = np.full(n, np.inf)  # closest airborne approach in the volume's measure (centres)
        self.volume_pairs: dict[tuple[int, int], float] = {}  # (i < j) airborne pairs inside the volume -> first t_s
        self.volume_pairs_ground: dict[tuple[int, int], float] = {}  # the same with one of them on the ground
        self._inside_seen = np.zeros((n, n), dtype=bool)
        self._inside_seen_ground = np.zeros((n, n), dtype=bool)
        self._events = np.zeros((n * n, 3), dtype=np.int64)  # the kernel's new pair-events of a step
        self._others_id = len(world.obstacles) + np.arange(n, dtype=np.float64)
        gap = self._gaps()
        if n > 1 and float(gap.min()) <= 0.0:
            i, j = np.unravel_index(int(np.argmin(gap)), gap.shape)
            raise ValueError(
                f"vehicles[{j}].home: {vehicles[j].name} starts in contact with {vehicles[i].name}; "
                "fix: move their homes further apart"
            )
        self._motor_cmd = [np.zeros((len(m), 4)) for m in self.members]
        self.hashes = [hashlib.sha256() for _ in range(n)]
        self.max_xy2 = [0.0] * n  # per vehicle, the max of x² + y² of q_ned_frd recorded: its max tilt
        self._state_rows = [self.state_row(i) for i in range(n)]  # views (the batches' states are updated in place)

    # ---- state ---------------------------------------------------------------------------------------
    @property
    def t_us(self) -> int:
        return self.batches[0].t_us

    @property
    def t_s(self) -> float:
        return self.batches[0].t_s

    @property
    def steps(self) -> int:
        """Control steps taken (the frame number)."""
        return self.batches[0]._steps

    def state_row(self, i: int) -> np.ndarray:
        """Vehicle i's truth state (17,) (a view)."""
        b, row = self.rows[i]
        return self.batches[b].state[row]

    def gather(self) -> None:
        """Refresh ``pos_ned``, ``vel_ned`` and ``end_reason`` (instance order) from the batches (after a step, or
        after writing a batch state directly); nothing to do when they are views of the one batch's."""
        if self._views:
            return
        for batch, members in zip(self.batches, self._index, strict=True):
            self.pos_ned[members] = batch.state[:, 0:3]
            self.vel_ned[members] = batch.state[:, 3:6]
            self.end_reason[members] = batch.end_reason
            self.on_ground[members] = batch.on_ground

    def _gaps(self) -> np.ndarray:
        """(n, n) surface-to-surface distances between vehicles (inf on the diagonal)."""
        d = np.linalg.norm(self.pos_ned[:, None, :] - self.pos_ned[None, :, :], axis=2)
        gap = d - self.radius_m[:, None] - self.radius_m[None, :]
        np.fill_diagonal(gap, np.inf)
        return gap

    @property
    def running(self) -> np.ndarray:
        """(n,) bool: vehicles still integrated (not crashed or ended)."""
        return self.end_reason == _RUNNING

    def any_running(self) -> bool:
        """True while a vehicle is still integrated (a list test: ``running.any()`` costs ~2 µs a step)."""
        return _RUNNING in self.end_reason.tolist()

    # ---- a control step ------------------------------------------------------------------------------
    def set_motors(self, i: int, motors: np.ndarray) -> None:
        """Vehicle i's motor commands (4,) for the next step (0 = stopped)."""
        b, row = self.rows[i]
        self._motor_cmd[b][row] = motors

    def release_payload(self, i: int) -> None:
        b, row = self.rows[i]
        mask = np.zeros(self.batches[b].n, dtype=bool)
        mask[row] = True
        self.batches[b].release_payload(mask)

    def payload_kg(self, i: int) -> float:
        b, row = self.rows[i]
        return float(self.batches[b].payload_kg[row])

    def step(self) -> None:
        """Integrate every batch one control step, then the vehicle-vehicle contacts."""
        for batch, cmd in zip(self.batches, self._motor_cmd, strict=True):
            batch.step(cmd)
        self.gather()
        if self.n > 1:
            self._contacts()

    def _contacts(self) -> None:
        """The step's pairs (``sim.separation_kernel``): separations folded in, new contacts end both vehicles,
        new volume pairs recorded with the time they first came inside."""
        n_events = pair_separation_step(
            self.pos_ned, self.radius_m, self.on_ground, UAV_VOLUME_HOR_M, UAV_VOLUME_VER_M,
            self.min_separation_m, self.min_volume_sep_m,
            self._touching, self._inside_seen, self._inside_seen_ground, self._events,
        )  # fmt: skip
        if n_events == 0:  # the usual step
            return
        t_s = self.t_s
        for i, j, kind in self._events[:n_events].tolist():
            if kind == EVENT_CONTACT:
                self.contacts.append((i, j, t_s))
                self.end(EndReason.COLLISION, [i, j])
            elif kind == EVENT_VOLUME_AIRBORNE:
                self.volume_pairs[(i, j)] = t_s
            else:
                self.volume_pairs_ground[(i, j)] = t_s

    def end(self, reason: EndReason, vehicles: list[int]) -> None:
        """End the running ones of ``vehicles`` with ``reason`` (they freeze)."""
        for i in vehicles:
            b, row = self.rows[i]
            mask = np.zeros(self.batches[b].n, dtype=bool)
            mask[row] = True
            self.batches[b].end(reason, mask)
        self.gather()

    def contacts_of(self, i: int) -> list[int]:
        """The vehicles vehicle i touched."""
        return [b if a == i else a for a, b, _ in self.contacts if i in (a, b)]

    # ---- sensing -------------------------------------------------------------------------------------
    def others_of(self, i: int) -> np.ndarray:
        """(n-1, 5) the other vehicles as obstacle-sensor spheres: north, east, down, radius, obstacle id."""
        rows = np.column_stack((self.pos_ned, self.radius_m, self._others_id))
        return np.delete(rows, i, axis=0)

    def detect(self, i: int) -> tuple:
        """Vehicle i's obstacle detections now (world obstacles and the other vehicles)."""
        state = self._state_rows[i]
        others = self.others_of(i) if self.n > 1 else None
        return self.obstacle_sensors[i].detect(state[0:3], state[6:10], self.t_us, others)

    def record(self) -> None:
        """Add every vehicle's truth state of now to its hash and its tilt to ``max_xy2``."""
        max_xy2 = self.max_xy2
        for i, (h, state) in enumerate(zip(self.hashes, self._state_rows, strict=True)):
            h.update(state)
            qx, qy = state[7:9].tolist()
            xy2 = qx * qx + qy * qy
            if xy2 > max_xy2[i]:
                max_xy2[i] = xy2

    def max_tilt_deg(self, i: int) -> float:
        """Vehicle i's largest tilt over the recorded steps (°)."""
        return tilt_deg_from_xy2(self.max_xy2[i])
