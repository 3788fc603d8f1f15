"""What the autopilot reports: the per-step record for listeners, the GCS snapshot, tracking and the summary.

- Reads: the frozen messages of one step (vehicle state, reference, cascade output, commander and navigator
  status) and the ground truth, which is used for the determinism hash only.
- Owns: tracking-error statistics, the truth hash, mission progress (items reached), SYS_STATUS bits (the
  estimator's AHRS/GPS/baro/mag health from ``CommandContext.estimator_status``) and ESTIMATOR_STATUS contents.
- Emits: :class:`StepRecord` (telemetry listeners), ``TelemetrySnapshot`` (GCS links) and the
  ``autopilot_summary.json`` dict (SPEC §12).
"""

from __future__ import annotations

import hashlib
import json
import math
import struct
from collections.abc import Sequence
from dataclasses import dataclass
from enum import Enum
from functools import lru_cache
from pathlib import Path
from typing import Protocol

import numpy as np

from autopilot.commander.state_machine import Commander
from autopilot.control.cascade import ControlSample
from autopilot.estimation import EstimatorStatus, VehicleState
from autopilot.estimation.report import apply_estimator_health, estimator_report
from autopilot.flight_control.controller import FlightControl
from autopilot.flight_tasks.setpoints import NavTarget, Reference
from autopilot.navigation import Navigator
from autopilot.safety.failsafe import BatteryModel, FailsafeKind
from mavlink_bridge.contract.frames import GeoPoint, Vec3
from mavlink_bridge.contract.vehicle_api import (
    EstimatorReport,
    FlightMode,
    LandedState,
    MissionItem,
    Severity,
    StatusText,
    TelemetrySnapshot,
)
from mavlink_bridge.contract.wire import GroundTruth, ObstacleDetection, fast_frozen_init

#: MAV_SYS_STATUS_SENSOR bits: 3D gyro, accel, mag, abs pressure, GPS, rate/attitude/position control,
#: motor outputs, AHRS, battery.
SENSORS_PRESENT = 0x1 | 0x2 | 0x4 | 0x8 | 0x20 | 0x400 | 0x800 | 0x4000 | 0x8000 | 0x200000 | 0x2000000
SENSOR_GPS = 0x20
#: Geofence (healthy = no breach; MAVProxy reports a breach when the bit is absent) and pre-arm checks
#: (healthy = arming checks pass; MAVSDK's ``health.is_armable`` and QGC's "ready to fly" read it).
SENSOR_GEOFENCE = 0x100000
SENSOR_PREARM_CHECK = 0x10000000
SENSORS_REPORTED = SENSORS_PRESENT | SENSOR_GEOFENCE | SENSOR_PREARM_CHECK


def sensors_health(gps_ok: bool, geofence_ok: bool, prearm_ok: bool) -> int:
    """SYS_STATUS health bits: GPS with a 3D fix, no geofence breach, pre-arm checks passing."""
    health = SENSORS_PRESENT if gps_ok else SENSORS_PRESENT & ~SENSOR_GPS
    if geofence_ok:
        health |= SENSOR_GEOFENCE
    if prearm_ok:
        health |= SENSOR_PREARM_CHECK
    return health


@fast_frozen_init
@dataclass(frozen=True, slots=True)
class StepRecord:
    """What one control step did, for passive listeners (frozen messages only). Vectors are local NED about
    the estimator origin, ``home_ned_m`` (home about the origin) too."""

    time_us: int
    state: VehicleState
    target: NavTarget
    reference: Reference
    motor_cmd: tuple[float, float, float, float]
    thrust_ratio: float
    armed: bool
    mode: FlightMode
    landed_state: LandedState
    home_ned_m: Vec3 | None
    mission_seq: int
    reached: tuple[int, ...]
    texts: tuple[StatusText, ...]
    detections: tuple[ObstacleDetection, ...]
    planner_output: object | None  # autopilot.planner.planner_output.PlannerOutput (frozen) while avoiding
    control: ControlSample | None  # the cascade's step (None while idle)
    battery_remaining_pct: float = math.nan
    battery_voltage_v: float = math.nan
    truth: GroundTruth | None = None  # the sim's truth of this step: for estimate-vs-truth logging only
    estimator_status: EstimatorStatus | None = None
    planned_route_home_ned_m: np.ndarray | None = None  # the routed leg (about home); the same array until replanned
    traffic_decision: object | None = None  # autopilot.traffic.TrafficDecision (frozen) of the latest traffic check
    uav_separation: object | None = None  # autopilot.traffic.SeparationVolume in force (NAV_TRAFF_U_HOR, U_VER)

    @property
    def pos_sp_ned_m(self) -> Vec3:
        return self.reference.pos_ned_m


class StepListener(Protocol):
    """A passive observer (the Rerun telemetry, ``autopilot.telemetry.RerunTelemetry``); changes nothing it is given.

    ``on_step`` after every answered lockstep frame; ``on_event`` for status texts that no step carried (e.g.
    answers to GCS commands while the sim is paused); ``on_mission`` / ``on_fence`` when an upload is accepted
    or home moves (items and zones about ``home``).
    """

    def on_step(self, record: StepRecord) -> None: ...

    def on_event(self, text: str, severity: Severity = Severity.INFO, time_us: int | None = None) -> None: ...

    def on_mission(self, items: Sequence[MissionItem], home: GeoPoint) -> None: ...

    def on_fence(self, zones: Sequence[object]) -> None: ...


class AutopilotEndReason(Enum):
    """Why the autopilot loop stopped."""

    STOPPED = "stopped"  # SIGINT/SIGTERM or the caller's stop()
    SIM_LOST = "sim_lost"  # frames came and then stopped for the client's sim_lost_timeout_s
    SIM_NEVER_CONNECTED = "sim_never_connected"  # no frame within the start-up timeout
    ERROR = "error"


@dataclass
class Tracking:
    """Running tracking-error statistics while flying (reference vs estimate)."""

    n: int = 0
    pos_sq_sum: float = 0.0
    pos_max: float = 0.0
    att_sq_sum: float = 0.0
    att_max: float = 0.0
    max_tilt_rad: float = 0.0

    def add(self, pos_err_m: float, att_err_rad: float, tilt_rad: float) -> None:
        self.n += 1
        self.pos_sq_sum += pos_err_m * pos_err_m
        self.att_sq_sum += att_err_rad * att_err_rad
        if pos_err_m > self.pos_max:
            self.pos_max = pos_err_m
        if att_err_rad > self.att_max:
            self.att_max = att_err_rad
        if tilt_rad > self.max_tilt_rad:
            self.max_tilt_rad = tilt_rad

    def summary(self) -> dict[str, float | int]:
        n = self.n
        return {
            "tracking_pos_err_rms_m": math.sqrt(self.pos_sq_sum / n) if n else 0.0,
            "tracking_pos_err_max_m": self.pos_max,
            "tracking_att_err_rms_deg": math.degrees(math.sqrt(self.att_sq_sum / n)) if n else 0.0,
            "tracking_att_err_max_deg": math.degrees(self.att_max),
            "max_tilt_deg": math.degrees(self.max_tilt_rad),
            "flying_steps": n,
        }


class TruthHash:
    """sha256 over every step's ground truth: two flights are the same flight when their hashes are equal."""

    def __init__(self) -> None:
        self._hash = hashlib.sha256()
        self._pack = struct.Struct("<q10d").pack

    def add(self, truth: GroundTruth) -> None:
        self._hash.update(self._pack(truth.time_us, *truth.q_ned_frd, *truth.vel_ned_m_s, truth.lat_deg,
                                     truth.lon_deg, truth.alt_amsl_m))  # fmt: skip

    def hexdigest(self) -> str:
        return self._hash.hexdigest()


class MissionProgress:
    """Items reached: all of them (summary) and those not yet published (snapshot, step record)."""

    def __init__(self) -> None:
        self.reached_seqs: list[int] = []
        self.pending: list[int] = []

    def add(self, reached: tuple[int, ...]) -> None:
        self.reached_seqs += reached
        self.pending += reached

    def take_pending(self) -> list[int]:
        out, self.pending = self.pending, []
        return out


def snapshot(
    state: VehicleState,
    commander: Commander,
    nav: Navigator,
    control: FlightControl,
    battery: BatteryModel,
    progress: MissionProgress,
    origin: GeoPoint | None,
) -> TelemetrySnapshot:
    """The GCS telemetry snapshot of one step (``origin``: the estimator's, home until the vehicle has one)."""
    home = commander.home
    home_geo = home.geo if home is not None else origin
    gps_ok = state.gps_fix_type >= 3
    geofence_ok = FailsafeKind.GEOFENCE.value not in commander.context.failsafe_reasons
    prearm_ok = commander.armed or commander.arming_refusal(state) is None
    health = sensors_health(gps_ok, geofence_ok, prearm_ok)
    status = commander.context.estimator_status
    if status is not None:  # AHRS, GPS, baro and mag health as the estimator uses them (PX4's health checks)
        health = apply_estimator_health(health, status)
    return TelemetrySnapshot(
        time_us=state.time_us,
        armed=commander.armed,
        mode=commander.mode,
        landed_state=commander.landed_state,
        q_ned_frd=state.q_ned_frd,
        rate_frd_rad_s=state.rate_frd_rad_s,
        pos_ned_m=state.pos_ned_m,
        vel_ned_m_s=state.vel_ned_m_s,
        lat_deg=state.lat_deg,
        lon_deg=state.lon_deg,
        alt_amsl_m=state.alt_amsl_m,
        alt_rel_m=commander.alt_rel_home_m(state),
        home_lat_deg=home_geo.lat_deg if home_geo is not None else 0.0,
        home_lon_deg=home_geo.lon_deg if home_geo is not None else 0.0,
        home_alt_amsl_m=home_geo.alt_amsl_m if home_geo is not None else 0.0,
        home_valid=home is not None,
        gps_fix_type=state.gps_fix_type,
        gps_satellites=state.gps_satellites,
        gps_eph_m=state.gps_eph_m if math.isfinite(state.gps_eph_m) else 99.0,
        gps_epv_m=state.gps_epv_m if math.isfinite(state.gps_epv_m) else 99.0,
        battery_voltage_v=battery.voltage_v,
        battery_current_a=battery.current_a(control.thrust_ratio),
        battery_remaining_pct=100.0 * battery.remaining,
        throttle_pct=100.0 * min(1.0, control.thrust_ratio * control.hover_fraction),
        sensors_present=SENSORS_REPORTED,
        sensors_enabled=SENSORS_REPORTED,
        sensors_health=health,
        mission_seq_current=nav.current_seq,
        mission_count=len(nav.mission),
        mission_reached=progress.take_pending(),
        mission_state=int(nav.mission_state),
        estimator=None if status is None else _estimator_report(status),
    )


@lru_cache(maxsize=4)
def _estimator_report(status: EstimatorStatus) -> EstimatorReport:
    """ESTIMATOR_STATUS contents, built once per status object (the estimator keeps one while nothing changes)."""
    return estimator_report(status)


def summary(
    commander: Commander,
    nav: Navigator,
    battery: BatteryModel,
    progress: MissionProgress,
    tracking: Tracking,
    truth_hash: TruthHash,
    flight: dict[str, object],
) -> dict[str, object]:
    """``autopilot_summary.json`` (SPEC §12): ``flight`` (end reason, times, frames, vehicle) first, then mission
    progress, modes, landing, tracking errors and the truth hash."""
    reached = progress.reached_seqs
    return {
        **flight,
        "items_total": len(nav.mission),
        "items_reached": len(set(reached)),
        "reached_seqs": list(reached),
        "items_bypassed": len(set(nav.bypassed_seqs)),  # unreachable (inside a safety volume or the fence margin)
        "bypassed_seqs": list(nav.bypassed_seqs),
        "bypass_reasons": {str(seq): nav.bypass_reasons.get(seq, "") for seq in sorted(set(nav.bypassed_seqs))},
        "mission_state": nav.mission_state.name,
        "mode": commander.mode.name,
        "mode_history": [{"t_s": t / 1e6, "mode": m.name} for t, m in commander.mode_history],
        "armed": commander.armed,
        "landed": commander.landed_state is LandedState.ON_GROUND,
        "disarmed": not commander.armed,
        "payload_released": commander.gripper_release,
        "battery_remaining": round(battery.remaining, 4),
        **tracking.summary(),
        "truth_sha256": truth_hash.hexdigest(),
    }


def write_json(path: Path, content: dict[str, object]) -> Path:
    """Write ``content`` as indented JSON (the folder is created); returns ``path``."""
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(content, indent=2) + "\n")
    return path
