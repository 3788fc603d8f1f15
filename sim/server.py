"""The simulator process: one vehicle in a world, served to an autopilot over the lockstep (SPEC §4, §12).

Loop per control step (``control_hz``, default 250 Hz)::

    sensors(state, t) → values (one numba call, ``sim.frame_kernel``) → datagram (one numba call,
    ``mavlink_bridge.wire.frame_writer``) → send (HIL_* out)
    → record the previous step (truth hash, tilt, truth log: overlaps the autopilot's step)
    → wait (HIL_ACTUATOR_CONTROLS back)
    → apply (armed → motors, else 0; gripper release → payload dropped) → physics (substeps RK4)
    → end checks (vehicle end reason, duration, stop request) → pacing (``--speed``)

Time is owned here and only advances after the answer for the current step arrived, so a
run is a deterministic function of (world, vehicle, seed, autopilot) at any ``speed``; the wall
clock only paces (``speed`` = sim seconds per wall second, None = as fast as possible).
Before the first HEARTBEAT the sim does not advance. On exit a ``SimSummary`` is returned
(and written as ``sim_summary.json`` by the CLI).
"""

from __future__ import annotations

import hashlib
import importlib
import importlib.util
import logging
import math
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Protocol

import numpy as np
import yaml

from mavlink_bridge.contract.wire import ObstacleDetection
from mavlink_bridge.lockstep import DEFAULT_SPIN_S, AutopilotLost, LockstepInterrupted, LockstepServer
from mavlink_bridge.lockstep.answer_kernel import A_ARMED, A_GRIPPER_RELEASE, A_MOTORS
from mavlink_bridge.wire.frame_writer import FrameWriter
from sim.end_reason import EndReason
from sim.frame_kernel import SensorValues
from sim.sensors import SensorModel
from sim.summary_file import SummaryFile
from sim.traffic import DEFAULT_TRAFFIC_RANGE_M
from sim.vehicle import VehicleSim
from sim.vehicle_config import load_vehicle
from sim.world import World, empty_world, load_world

log = logging.getLogger(__name__)

DEFAULT_VEHICLE = "x500"


class SimSetupError(ValueError):
    """The world, vehicle or options were refused; the message says which and why."""


@dataclass(frozen=True, slots=True)
class SimConfig:
    """Everything a simulator run needs (the CLI options of SPEC §12)."""

    listen_url: str = "udpin:127.0.0.1:14560"
    world_path: Path | None = None
    vehicle: str | None = None  # name or path; None: the mission's ``vehicle:`` or DEFAULT_VEHICLE
    seed: int = 0
    speed: float | None = None  # sim s per wall s; None = as fast as possible
    duration_s: float | None = None  # sim time limit; None = until stopped
    physics_hz: int = 1000
    control_hz: int = 250
    autopilot_timeout_s: float = 3.0  # wall seconds of silence before AUTOPILOT_LOST
    start_timeout_s: float | None = None  # wall seconds to wait for the first HEARTBEAT; None = forever
    resend_timeout_s: float = 0.02  # ceiling of the adaptive resend timeout (wall s)
    sensor_noise: bool = True
    truth_log: Path | None = None  # .npz of the truth state at control rate
    recording: Path | None = None  # a fleet world: the world part of the run's Rerun recording (.rrd)
    recording_id: str = ""  # that recording's id (the autopilots' own)
    lockstep_spin_s: float = DEFAULT_SPIN_S  # busy-poll for the answer before sleeping (0 = never)
    loss_fraction: float = 0.0  # > 0: the lockstep drops this share of datagrams each way (seeded; --sim-loss)
    traffic_range_m: float = DEFAULT_TRAFFIC_RANGE_M  # a fleet world's receivers report targets this close (3D)


@dataclass(frozen=True, slots=True)
class SimSummary(SummaryFile):
    """What ``sim_summary.json`` holds (SPEC §12 keys first, then extras)."""

    end_reason: str
    sim_time_s: float
    wall_time_s: float
    real_time_factor: float
    collisions: int
    min_clearance_m: float | None  # None when the world has no obstacles
    payload_released_at_s: float | None
    max_tilt_deg: float
    vehicle: str
    seed: int
    speed: float | None
    autopilot_connected: bool
    frames: int
    resends: int
    stale_answers: int
    malformed: int
    foreign_datagrams: int  # lockstep datagrams from anyone but the autopilot that started it: dropped unread
    invalid_answers: int  # answers stamped ahead of the frame or with motors NaN / outside [0, 1]: never applied
    resend_timeout_us: float  # the adaptive resend timeout at the end of the run
    exchange_us: float  # smoothed frame-to-answer time (the resend timeout's basis)
    loss_dropped: int  # datagrams --sim-loss dropped, both ways (0 without it)
    final_pos_ned_m: tuple[float, float, float]
    truth_sha256: str  # hash of the truth state after every control step (determinism checks)
    sim_step_us: float  # mean wall time per step in the sim itself (all but the answer wait and pacing sleeps)
    answer_wait_us: float  # mean wall time per step waiting for the answer (autopilot step + transport)
    sim_cpu_us_per_step: float  # process CPU time per step (the sim's own work; unlike wall time, load-independent)


class ObstacleSensorLike(Protocol):
    """What ``sim.obstacle_sensor.ObstacleSensor`` provides: detections at ``config.rate_hz``."""

    def detect(self, pos_ned: np.ndarray, q_ned_frd: np.ndarray, time_us: int) -> tuple[ObstacleDetection, ...]: ...


def _load_obstacle_sensor(world: World, seed: int) -> ObstacleSensorLike | None:
    """The world's obstacle sensor when ``sim/obstacle_sensor.py`` exists, else None (no detections)."""
    if importlib.util.find_spec("sim.obstacle_sensor") is None:
        return None
    module = importlib.import_module("sim.obstacle_sensor")
    return module.ObstacleSensor(world, seed)


def mission_vehicle(world_path: Path | None) -> str | None:
    """The ``vehicle:`` of a mission YAML (None: no file, or none named)."""
    if world_path is None:
        return None
    doc: Any = yaml.safe_load(world_path.read_text())
    vehicle = doc.get("vehicle") if isinstance(doc, dict) else None
    return vehicle if isinstance(vehicle, str) else None


def tilt_deg(q_ned_frd: np.ndarray) -> float:
    """Angle between body down and NED down (°): ``acos(R_zz)``, ``R_zz = 1 − 2(x² + y²)``."""
    x, y = float(q_ned_frd[1]), float(q_ned_frd[2])
    return _tilt_deg_from_xy2(x * x + y * y)


def _tilt_deg_from_xy2(xy2: float) -> float:
    """:func:`tilt_deg` from ``x² + y²`` of the quaternion (monotonic in it: the max tilt is that of the max)."""
    return math.degrees(math.acos(max(-1.0, min(1.0, 1.0 - 2.0 * xy2))))


class SimServer:
    """One simulator run: ``run()`` blocks until the end and returns the summary."""

    def __init__(self, config: SimConfig) -> None:
        self.config = config
        if config.speed is not None and not (config.speed > 0.0 and math.isfinite(config.speed)):
            raise SimSetupError(f"speed: expected 'max' or a positive number, got {config.speed}")
        if config.world_path is not None and not config.world_path.is_file():
            raise SimSetupError(f"world: no such file {str(config.world_path)!r}")
        self.world = load_world(config.world_path) if config.world_path else empty_world()
        vehicle_name = config.vehicle or mission_vehicle(config.world_path) or DEFAULT_VEHICLE
        self.vehicle_config = load_vehicle(vehicle_name)
        try:
            self.vehicle = VehicleSim(
                self.vehicle_config,
                physics_hz=config.physics_hz,
                control_hz=config.control_hz,
                world=self.world,
                seed=config.seed,
            )
        except ValueError as exc:
            raise SimSetupError(str(exc)) from exc
        self.sensors = SensorModel(self.vehicle_config, self.world.home, config.seed, noise=config.sensor_noise)
        self._values = SensorValues(self.vehicle, self.sensors)  # this step's measurements and truth
        self._writer = FrameWriter()  # their lockstep datagram (owns the sequence counter)
        self.obstacle_sensor = _load_obstacle_sensor(self.world, config.seed)
        rate_hz = getattr(getattr(self.obstacle_sensor, "config", None), "rate_hz", 10.0)
        self._detection_period_us = round(1e6 / rate_hz)
        self._next_detection_us = 0
        if not 0.0 <= config.loss_fraction < 1.0:
            raise SimSetupError(f"sim loss: expected a fraction in [0, 1), got {config.loss_fraction}")
        self.lockstep = LockstepServer(
            config.listen_url,
            resend_timeout_s=config.resend_timeout_s,
            peer_lost_timeout_s=config.autopilot_timeout_s,
            spin_s=config.lockstep_spin_s,
            loss_fraction=config.loss_fraction,  # --sim-loss: dropped at this end, both ways, seeded
            loss_seed=config.seed,
        )
        self._stop_requested = False
        self._answer_motors = self.lockstep.answer[A_MOTORS : A_MOTORS + 4]  # a view: the answer, in place
        self._motors_off = np.zeros(4)

    @property
    def local_address(self) -> tuple[str, int]:
        """Where the autopilot sends (the lockstep server)."""
        return self.lockstep.local_address

    def request_stop(self) -> None:
        """Finish the run at the next step (signal-handler safe): end reason STOPPED."""
        self._stop_requested = True
        self.lockstep.interrupt()

    def _detections(self) -> tuple[ObstacleDetection, ...]:
        """Obstacle detections of now (at the obstacle sensor's rate, else none)."""
        v = self.vehicle
        if self.obstacle_sensor is None or v.t_us < self._next_detection_us:
            return ()
        self._next_detection_us += self._detection_period_us
        return tuple(self.obstacle_sensor.detect(v.pos_ned, v.q_ned_frd, v.t_us))

    def _datagram(self) -> bytes:
        """Sensors, GPS (10 Hz), truth and obstacle detections of now as the lockstep datagram (two numba calls)."""
        gps_due = self._values.fill()
        return self._writer.write(self._values.values, self.vehicle.t_us, gps_due, self._detections())

    def _apply(self) -> np.ndarray:
        """The motor commands to integrate from the lockstep's answer (checked finite and in [0, 1] at the edge):
        its motors when armed, else stopped; a gripper release drops the payload."""
        answer = self.lockstep.answer
        if answer[A_GRIPPER_RELEASE] == 1.0 and self.vehicle.payload_kg > 0.0:
            self.vehicle.release_payload()
            log.info("payload released at t=%.3f s", self.vehicle.t_s)
        return self._answer_motors if answer[A_ARMED] == 1.0 else self._motors_off

    def run(self) -> SimSummary:
        """Wait for the autopilot, then step in lockstep until an end condition; always returns a summary."""
        cfg, v, lockstep = self.config, self.vehicle, self.lockstep
        truth_hash = hashlib.sha256()
        truth_rows: list[np.ndarray] = []
        max_xy2 = 0.0  # max of x² + y² of q_ned_frd: the max tilt (tilt is monotonic in it)
        unrecorded = False  # a step is integrated but not yet in the hash / tilt / truth log
        state = v.batch.state[0]

        def record() -> None:
            nonlocal max_xy2
            truth_hash.update(state)
            if cfg.truth_log is not None:
                truth_rows.append(np.concatenate(([v.t_s], state)))
            qx, qy = state[7:9].tolist()
            max_xy2 = max(max_xy2, qx * qx + qy * qy)

        connected = False
        wait_s = sleep_s = 0.0  # wall time waiting for answers, pacing sleeps
        wall0 = time.perf_counter()
        cpu0 = time.process_time()
        try:
            connected = self._wait_for_autopilot()
            wall0 = time.perf_counter()
            cpu0 = time.process_time()
            if not connected:
                v.end(EndReason.STOPPED)
            end_codes, running = v.batch.end_reason, EndReason.RUNNING.value  # the raw code: no enum per step
            while end_codes[0] == running:
                if self._stop_requested:
                    v.end(EndReason.STOPPED)
                    break
                if cfg.duration_s is not None and v.t_s >= cfg.duration_s - 1e-9:
                    v.end(EndReason.COMPLETED)
                    break
                try:
                    lockstep.send_datagram(v.t_us, self._datagram())
                    if unrecorded:  # the state is unchanged until the answer: record while the autopilot works
                        record()
                        unrecorded = False
                    wait_start_s = time.perf_counter()
                    lockstep.wait_answer_into()
                    wait_s += time.perf_counter() - wait_start_s
                except AutopilotLost as exc:
                    log.warning("autopilot lost: %s", exc)
                    v.end(EndReason.AUTOPILOT_LOST)
                    break
                except LockstepInterrupted:
                    v.end(EndReason.STOPPED)
                    break
                v.step(self._apply())
                unrecorded = True
                if cfg.speed is not None:
                    ahead_s = wall0 + v.t_s / cfg.speed - time.perf_counter()
                    if ahead_s > 0.0:
                        time.sleep(ahead_s)
                        sleep_s += ahead_s
            if unrecorded:
                record()
        finally:
            wall_s = time.perf_counter() - wall0
            cpu_s = time.process_time() - cpu0
            lockstep.close()
        if cfg.truth_log is not None:
            self._write_truth_log(cfg.truth_log, truth_rows)
        steps = max(self.lockstep.stats.frames, 1)
        timing_us = ((wall_s - wait_s - sleep_s) / steps * 1e6, wait_s / steps * 1e6, cpu_s / steps * 1e6)
        return self._summary(connected, wall_s, _tilt_deg_from_xy2(max_xy2), truth_hash.hexdigest(), timing_us)

    def _wait_for_autopilot(self) -> bool:
        cfg = self.config
        deadline = None if cfg.start_timeout_s is None else time.monotonic() + cfg.start_timeout_s
        log.info("waiting for the autopilot HEARTBEAT on %s:%d", *self.local_address)
        while not self._stop_requested:
            remaining = 0.25 if deadline is None else min(0.25, deadline - time.monotonic())
            if remaining <= 0.0:
                log.warning("no autopilot HEARTBEAT within %.1f s", cfg.start_timeout_s)
                return False
            if self.lockstep.wait_for_autopilot(remaining):
                log.info("autopilot connected")
                return True
        return False

    def _write_truth_log(self, path: Path, rows: list[np.ndarray]) -> None:
        """``t_s`` (n,) and ``state`` (n, 17): pos_ned, vel_ned, q_ned_frd, rate_frd, omega_rad_s."""
        data = np.array(rows) if rows else np.zeros((0, 18))
        path.parent.mkdir(parents=True, exist_ok=True)
        np.savez(path, t_s=data[:, 0], state=data[:, 1:])

    def _summary(
        self,
        connected: bool,
        wall_s: float,
        max_tilt: float,
        truth_sha256: str,
        timing_us: tuple[float, float, float],
    ) -> SimSummary:
        v, stats = self.vehicle, self.lockstep.stats
        sim_s = v.t_s
        clearance = v.min_clearance_m
        released = v.payload_released_at_s
        return SimSummary(
            end_reason=v.end_reason.name,
            sim_time_s=sim_s,
            wall_time_s=wall_s,
            real_time_factor=sim_s / wall_s if wall_s > 0.0 else 0.0,
            collisions=int(v.end_reason is EndReason.COLLISION),
            min_clearance_m=clearance if math.isfinite(clearance) else None,
            payload_released_at_s=released if math.isfinite(released) else None,
            max_tilt_deg=max_tilt,
            vehicle=self.vehicle_config.name,
            seed=self.config.seed,
            speed=self.config.speed,
            autopilot_connected=connected,
            frames=stats.frames,
            resends=stats.resends,
            stale_answers=stats.stale_answers,
            malformed=stats.malformed,
            foreign_datagrams=stats.foreign,
            invalid_answers=stats.invalid_answers,
            resend_timeout_us=stats.resend_timeout_us,
            exchange_us=stats.exchange_us,
            loss_dropped=self.lockstep.dropped,
            final_pos_ned_m=(float(v.pos_ned[0]), float(v.pos_ned[1]), float(v.pos_ned[2])),
            truth_sha256=truth_sha256,
            sim_step_us=timing_us[0],
            answer_wait_us=timing_us[1],
            sim_cpu_us_per_step=timing_us[2],
        )
