"""The autopilot process: owns the links, schedules the loop and wires the pure parts (issue 4, SPEC §3-§4).

Per lockstep frame (``Autopilot.step``), in sim time only:

    estimator → failsafes → mission executor (AUTO_MISSION) → commander → [planner override]
    → setpoint generator → NLVG-PID cascade → ActuatorCommand (armed flag, gripper channel)

The command is answered *before* the bookkeeping (``Autopilot.after_answer``: truth hash,
battery model, tracking statistics; then the telemetry snapshot, GCS/API polling, the telemetry
listener), so the simulator integrates the next step while the autopilot does the rest. GCS and
API links are polled between frames and never block the lockstep. Positions inside are local NED
about the estimator's origin (the first fix); the mission executor, the geofence and the planner
work about home, so the runner converts at their edge. :class:`VehicleAdapter` is the
``VehicleInterface`` the GCS servers call (commands, missions, parameters).
"""

from __future__ import annotations

import hashlib
import json
import math
import struct
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from enum import Enum
from pathlib import Path
from typing import Protocol

import numpy as np

from autopilot.commander import Commander
from autopilot.control.airframe import Airframe, load_airframe
from autopilot.control.cascade import GRAVITY_M_S2, CascadeController, SingleStep
from autopilot.control.param_decls import gains_from_params, limits_from_params
from autopilot.estimation import Estimator, FrameLike, VehicleState, make_estimator
from autopilot.failsafe import BatteryModel, FailsafeInputs, FailsafeKind, FailsafeMonitor
from autopilot.fence_zones import planner_fence_zones
from autopilot.mission.executor import (
    ActionKind,
    ExecutorConfig,
    ExecutorOutput,
    MissionExecutor,
    MissionRoute,
    NavKind,
    VehicleSample,
)
from autopilot.mission.executor import NavTarget as MissionTarget
from autopilot.mission.fence import FenceError, Geofence, geofence_from_items
from autopilot.mission.validation import MissionLimits, validate_mission
from autopilot.param_schema import make_param_store
from autopilot.params import ParamError, ParamStore
from autopilot.planner.param_decls import PlannerParams
from autopilot.planner.planner import AvoidancePlanner
from autopilot.scripted_commands import CommandScript
from autopilot.setpoints import NavTarget, SetpointGenerator, SetpointLimits, TargetKind
from mavlink_bridge.contract.frames import GeoPoint
from mavlink_bridge.contract.mav_enums import MavCmd, MissionState
from mavlink_bridge.contract.vehicle_api import (
    AltitudeFrame,
    CommandRequest,
    CommandResult,
    FlightMode,
    LandedState,
    LocalPositionTarget,
    ManualInput,
    MissionItem,
    MissionResult,
    MissionType,
    PositionTarget,
    Severity,
    StatusText,
    TelemetrySnapshot,
    VelocityFrame,
    VelocityTarget,
)
from mavlink_bridge.contract.wire import ActuatorCommand, ObstacleDetection, Vec3, fast_frozen_init

#: MAV_SYS_STATUS_SENSOR bits: 3D gyro, accel, mag, abs pressure, GPS, rate/attitude/position control,
#: motor outputs, AHRS, battery.
_SENSORS_PRESENT = 0x1 | 0x2 | 0x4 | 0x8 | 0x20 | 0x400 | 0x800 | 0x4000 | 0x8000 | 0x200000 | 0x2000000
_SENSOR_GPS = 0x20
#: Geofence (healthy = no breach; MAVProxy reports a breach when the bit is absent) and pre-arm checks
#: (healthy = arming checks pass; MAVSDK's ``health.is_armable`` and QGC's "ready to fly" read it).
_SENSOR_GEOFENCE = 0x100000
_SENSOR_PREARM_CHECK = 0x10000000
_SENSORS_REPORTED = _SENSORS_PRESENT | _SENSOR_GEOFENCE | _SENSOR_PREARM_CHECK
#: Publish the telemetry snapshot every this many control steps (62.5 Hz at 250 Hz) and on any event.
_SNAPSHOT_EVERY = 4
#: Controller parameters that are cascade limits rather than gains (the cascade packs them at construction).
_CONTROL_LIMIT_PARAMS = frozenset(
    {"MPC_TILTMAX_DEG", "MPC_ACC_HOR_MAX", "MPC_ACC_UP_MAX", "MPC_ACC_DOWN_MAX", "NV_AACC_RP_MAX", "NV_AACC_Y_MAX"}
)
#: Failsafe conditions are evaluated every this much sim time (µs).
FAILSAFE_PERIOD_US = 100_000
#: Poll the GCS/API links at most this often (wall seconds).
_LINK_POLL_PERIOD_S = 0.004
#: The planner gets the mission route this many CA_LOOKAHEAD_M past its target (the detour rejoins on it and
#: checks it after the rejoin; the benchmark follower hands the same), at most this many points.
ROUTE_AHEAD_LOOKAHEADS = 2.0
ROUTE_MAX_POINTS = 64
#: In AUTO_MISSION the nose (forward camera) faces a route point at least this far ahead (m), none closer than
#: FACE_MIN_M (closer, the heading is kept: no spinning over a waypoint).
FACE_AHEAD_M = 6.0
FACE_MIN_M = 2.0


class StepListener(Protocol):
    """A passive observer (the Rerun telemetry, ``autopilot.telemetry.RerunTelemetry``); changes nothing it is given.

    ``on_step`` after every answered lockstep frame; ``on_event`` for status texts that no step
    carried (e.g. answers to GCS commands while the sim is paused); ``on_mission`` / ``on_fence``
    when an upload is accepted (items and zones about ``home``).
    """

    def on_step(self, record: StepRecord) -> None: ...

    def on_event(self, text: str, severity: Severity = Severity.INFO, time_us: int | None = None) -> None: ...

    def on_mission(self, items: Sequence[MissionItem], home: GeoPoint) -> None: ...

    def on_fence(self, zones: Sequence[object]) -> None: ...


class RoutePlanner(Protocol):
    """The avoidance planner seam (``autopilot.planner.planner.AvoidancePlanner.update``)."""

    def update(
        self,
        time_us: int,
        pos_ned: Sequence[float],
        vel_ned: Sequence[float],
        q_ned_frd: Sequence[float],
        detections: Sequence[ObstacleDetection],
        route_target_ned: Sequence[float],
        route_next_ned: Sequence[float] | np.ndarray | None = None,
    ) -> object: ...


@fast_frozen_init
@dataclass(frozen=True, slots=True)
class StepRecord:
    """What one control step did, for listeners. Vectors are local NED about the origin; ``home_ned_m`` too."""

    time_us: int
    state: VehicleState
    target: NavTarget
    pos_sp_ned_m: Vec3
    vel_sp_ned_m_s: Vec3
    acc_sp_ned_m_s2: Vec3
    yaw_sp_rad: float
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
    planner_output: object | None  # autopilot.planner.planner.PlannerOutput while avoiding (detour, obstacles)
    controller: CascadeController | None  # live diagnostics (overwritten next step)
    battery_remaining_pct: float = math.nan
    battery_voltage_v: float = math.nan


class AutopilotEndReason(Enum):
    """Why the autopilot loop stopped."""

    STOPPED = "stopped"  # SIGINT/SIGTERM or the caller's stop()
    SIM_LOST = "sim_lost"  # frames came and then stopped for the client's sim_lost_timeout_s
    SIM_NEVER_CONNECTED = "sim_never_connected"  # no frame within the start-up timeout
    ERROR = "error"


@dataclass(frozen=True)
class AutopilotConfig:
    """Settings of one autopilot instance (the CLI fills it, SPEC §12)."""

    vehicle: str = "x500"
    estimator: str = "truth"
    params_file: str | None = None
    log_dir: str | None = None
    speed_factor: float = 1.0  # only stretches GCS timeouts when < 1 (the sim owns time)
    avoidance: bool = True  # run the obstacle-avoidance planner in AUTO_MISSION (CA_ENABLE switches detours)


@dataclass
class _Tracking:
    """Running tracking-error statistics while flying (setpoint vs estimate)."""

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


def _mission_to_nav(
    target: MissionTarget, home_ned: Vec3, commander: Commander, face_yaw_rad: float = math.nan
) -> NavTarget:
    """The executor's target (about home) as a commander target (about the origin); a waypoint or return
    without a yaw of its own gets ``face_yaw_rad`` (MPC_YAW_MODE 0: the nose, and the camera, along the path)."""
    p = commander.params.get
    n, e, d = (target.pos_ned_m[i] + home_ned[i] for i in range(3))
    speed = min(target.speed_m_s, p("MPC_XY_VEL_MAX"))
    up, down = p("MPC_Z_VEL_MAX_UP"), p("MPC_Z_VEL_MAX_DN")
    yaw = math.nan if math.isnan(target.yaw_deg) else math.radians(target.yaw_deg)
    if math.isnan(yaw) and target.kind in (NavKind.WAYPOINT, NavKind.RETURN):
        yaw = face_yaw_rad
    kind = target.kind
    if kind is NavKind.IDLE:
        return NavTarget(TargetKind.IDLE, (n, e, d))
    if kind is NavKind.LAND:
        return NavTarget(TargetKind.LAND, (n, e, d), yaw, speed, up, _mission_land_speed(commander))
    if kind is NavKind.TAKEOFF:
        up = p("MPC_TKO_SPEED")
    return NavTarget(TargetKind.POSITION, (n, e, d), yaw, speed, up, down)


def _mission_land_speed(commander: Commander) -> float:
    """The descent speed of a mission LAND at the commander's latest state (MPC_LAND_SPEED before any: the
    vehicle is then taken to be at home's height, below MPC_LAND_ALT2)."""
    state = commander.state
    return commander.land_speed_m_s(state) if state is not None else commander.params.get("MPC_LAND_SPEED")


class Autopilot:
    """Everything between a lockstep frame and its answer, plus the bookkeeping around it (no sockets)."""

    def __init__(
        self,
        config: AutopilotConfig | None = None,
        *,
        params: ParamStore | None = None,
        airframe: Airframe | None = None,
        estimator: Estimator | None = None,
        listener: StepListener | None = None,
        planner: RoutePlanner | None = None,
        script: CommandScript | None = None,
        wall_clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self.config = config or AutopilotConfig()
        self.airframe = airframe or load_airframe(self.config.vehicle)
        self.params = params or make_param_store(
            self.config.params_file, payload_nominal_kg=self.airframe.payload_nominal_kg
        )
        self.estimator = estimator or make_estimator(self.config.estimator)
        self.listener = listener
        if planner is None and self.config.avoidance:
            planner = AvoidancePlanner(PlannerParams.from_store(self.params))
        self.planner = planner
        self.geofence = Geofence()
        self.script = script
        self.wall_clock = wall_clock  # offboard setpoint and joystick ages only (real-time peers, SPEC §3)
        self._offboard_wall_s: float | None = None  # when the last offboard setpoint arrived
        self._manual_wall_s: float | None = None  # when the last joystick input (MANUAL_CONTROL) arrived
        self.commander = Commander(self.params)
        self.setpoints = SetpointGenerator(self._setpoint_limits())
        self.failsafe = FailsafeMonitor(self.params)
        self.battery = BatteryModel(self.params.get("BAT_HOVER_ENDUR"))
        self.executor: MissionExecutor | None = None
        self.controller: CascadeController | None = None
        values = self.params.values()
        self.gains = gains_from_params(values)
        self.limits = limits_from_params(values)
        self.mission: list[MissionItem] = []
        self.fence: list[MissionItem] = []
        self.state: VehicleState | None = None
        self.texts: list[StatusText] = []
        self.reached_seqs: list[int] = []
        self.tracking = _Tracking()
        self.frames = 0
        self.end_reason: AutopilotEndReason | None = None
        self.thrust_ratio = 0.0
        self._hover_thrust_n = self.airframe.mass_kg * GRAVITY_M_S2
        self._payload_released = False  # what the cascade's mass currently assumes
        self._prev_time_us: int | None = None
        self._dt_s = 0.004
        self._last_kind = TargetKind.IDLE
        self._last_mode = self.commander.mode
        self._last_home = None
        self._target = NavTarget(TargetKind.IDLE)
        self._pending_reached: list[int] = []
        self._last_output: ExecutorOutput | None = None
        self._planner_output: object | None = None
        self._route_checked: tuple[object, object] | None = None  # (route, obstacles) last safety-checked
        self._hash = hashlib.sha256()
        self._param_version = 0  # counts parameter changes (invalidates what is cached from parameters)
        self._mission_nav_key: tuple[object, ...] = ()
        self._mission_nav: NavTarget | None = None
        self._mission_nav_faces = False  # the cached mission target's yaw is the per-step heading along the path
        self._pending_truth: object | None = None  # this step's truth, hashed by after_answer
        self._pending_control: SingleStep | None = None  # this step's cascade output, booked by after_answer
        self._pack = struct.Struct("<q10d").pack
        self._motor = (0.0, 0.0, 0.0, 0.0)
        self._gcs_heartbeat_age: Callable[[], float | None] = lambda: None
        self._next_failsafe_us = 0
        self.params.subscribe(self._on_param)
        self.frame_detections: tuple[ObstacleDetection, ...] = ()
        self._warm_up()
        self._apply_altitude_limits()

    def _warm_up(self) -> None:
        """Build the cascade and run it once now: its first call JIT-loads the numba kernels (seconds),
        which must not happen inside the lockstep, where the sim would declare the autopilot lost."""
        controller = CascadeController(self.airframe, self.gains, 1, self._dt_s, self.limits)
        zero = (0.0, 0.0, 0.0)
        controller.update_position_single(zero, zero, (1.0, 0.0, 0.0, 0.0), zero, zero, zero, zero, 0.0)
        controller.reset()
        self.controller = controller

    # ------------------------------------------------------------------ parameters
    def _setpoint_limits(self) -> SetpointLimits:
        p = self.params.get
        return SetpointLimits(
            acc_xy_m_s2=p("MPC_ACC_HOR"),
            acc_up_m_s2=p("MPC_ACC_UP_AUTO"),
            acc_down_m_s2=p("MPC_ACC_DN_AUTO"),
            jerk_m_s3=p("MPC_JERK_AUTO"),
            yaw_rate_rad_s=math.radians(p("MPC_YAWRAUTO_MAX")),
        )

    def _on_param(self, name: str, value: float) -> None:
        """Parameter changes take effect at once (in flight too)."""
        self._param_version += 1  # values cached per step (the mission target) are rebuilt
        if name.startswith(("MPC_ACC", "MPC_JERK", "MPC_YAWRAUTO")):
            self.setpoints.limits = self._setpoint_limits()
        if name.startswith("NV_") or name in _CONTROL_LIMIT_PARAMS:
            self._update_controller_params()
        elif name == "PLD_MASS_KG":
            self._apply_payload_mass()
        elif name == "BAT_HOVER_ENDUR":
            self.battery.hover_endurance_s = value
        elif name.startswith("MIS_") and self.executor is not None:
            self.executor.configure(ExecutorConfig.from_params(self.params))
        elif name.startswith("CA_") and isinstance(self.planner, AvoidancePlanner):
            self.planner.set_params(PlannerParams.from_store(self.params))
        elif name.startswith("GF_MAX_VER"):
            self._apply_altitude_limits()
        if name == "CA_RSAFE_M" and hasattr(self.listener, "safety_radius_m"):
            self.listener.safety_radius_m = value  # type: ignore[union-attr]  # drawn safety spheres follow R_safe

    def _update_controller_params(self) -> None:
        """Gains change live (integrators kept); a limit change rebuilds the cascade with its state carried over.

        A ValueError from inconsistent values (e.g. δ2 <= δ1) leaves the gains in force and is reported.
        """
        values = self.params.values()
        try:
            gains = gains_from_params(values)
            limits = limits_from_params(values)
        except ValueError as exc:
            self._say(f"Controller parameters not applied: {exc}", Severity.WARNING)
            return
        self.gains = gains
        if limits != self.limits:
            self.limits = limits
            if self.controller is not None:
                self.controller = self._rebuild_controller(self.controller)
        elif self.controller is not None:
            self.controller.set_gains(gains)

    def _rebuild_controller(self, old: CascadeController | None) -> CascadeController:
        """A cascade with the gains and limits in force; integrators, held outputs and mass carried over
        from ``old`` so a limit change is bumpless (the state layout does not depend on the limits)."""
        controller = CascadeController(self.airframe, self.gains, 1, self._dt_s, self.limits)
        if old is not None:
            controller._work[:] = old._work  # the cascade has no public state transfer
        controller.set_mass_kg(self._controller_mass_kg())
        return controller

    def _controller_mass_kg(self) -> float:
        """Nominal mass, minus ``PLD_MASS_KG`` once the payload is released (at least 10 % of nominal)."""
        mass = self.airframe.mass_kg
        if self._payload_released:
            return max(mass - self.params.get("PLD_MASS_KG"), 0.1 * mass)
        return mass

    def _apply_payload_mass(self) -> None:
        """Tell the cascade the mass it now carries (gripper release / grab, PLD_MASS_KG changes)."""
        self._payload_released = self.commander.gripper_release
        mass = self._controller_mass_kg()
        self._hover_thrust_n = mass * GRAVITY_M_S2
        if self.controller is not None:
            self.controller.set_mass_kg(mass)

    def _apply_altitude_limits(self) -> None:
        """GF_MAX_VER_DIST (when set) is a ceiling for detours too."""
        if isinstance(self.planner, AvoidancePlanner):
            ceiling = self.params.get("GF_MAX_VER_DIST")
            self.planner.set_altitude_limits(0.0, ceiling if ceiling > 0.0 else math.inf)

    def _set_geofence(self, fence: Geofence) -> None:
        """The uploaded FENCE (zones about home) for the breach failsafe and the avoidance planner."""
        self.geofence = fence
        self.failsafe.geofence = fence
        if isinstance(self.planner, AvoidancePlanner):
            self.planner.set_fences(planner_fence_zones(fence))

    # ------------------------------------------------------------------ geography
    @property
    def home_geo(self) -> GeoPoint | None:
        """Home if armed once, else the estimator's origin (where home will be), else None."""
        if self.commander.home is not None:
            return self.commander.home.geo
        return self.estimator.origin

    @property
    def home_ned(self) -> Vec3:
        return self.commander.home.pos_ned_m if self.commander.home is not None else (0.0, 0.0, 0.0)

    def _say(self, text: str, severity: Severity = Severity.INFO) -> None:
        self.texts.append(StatusText(severity, text))

    # ------------------------------------------------------------------ missions (VehicleAdapter calls these)
    def replace_mission(self, mission_type: MissionType, items: list[MissionItem]) -> tuple[MissionResult, str]:
        home = self.home_geo
        if mission_type not in (MissionType.MISSION, MissionType.FENCE):
            return MissionResult.UNSUPPORTED, f"mission type {mission_type.name} is not supported"
        if home is None:
            return MissionResult.ERROR, "no position fix yet: upload again once the vehicle has a position"
        if mission_type is MissionType.FENCE:
            try:
                fence = geofence_from_items(items, home)
            except FenceError as exc:
                return MissionResult.INVALID, str(exc)
            self.fence = list(items)
            self._set_geofence(fence)
            self._say(f"Geofence: {len(items)} items")
            if self.listener is not None:
                self.listener.on_fence(fence.zones)
            return MissionResult.ACCEPTED, ""
        result, reason = validate_mission(items, home, MissionLimits.from_params(self.params))
        if result is not MissionResult.ACCEPTED:
            return result, reason
        executor = self._executor()
        if executor is None:
            return MissionResult.ERROR, "no position fix yet"
        executor.set_mission(items)
        self.mission = list(items)
        self.commander.mission_ready = bool(items)
        self._say(f"Mission: {len(items)} items")
        if self.listener is not None:
            self.listener.on_mission(items, home)
        return MissionResult.ACCEPTED, ""

    def mission_items(self, mission_type: MissionType) -> list[MissionItem]:
        if mission_type is MissionType.FENCE:
            return list(self.fence)
        return list(self.mission) if mission_type is MissionType.MISSION else []

    def set_current_mission_item(self, seq: int) -> bool:
        executor = self.executor
        return executor is not None and executor.set_current(seq)

    # ------------------------------------------------------------------ offboard (VehicleAdapter calls these)
    def set_position_target(self, target: PositionTarget) -> bool:
        """An offboard position setpoint (local NED about the origin, or global); False without a local frame."""
        frame = self.estimator.local_frame
        if isinstance(target, LocalPositionTarget):
            pos = target.pos_ned_m
        elif frame is None:
            return False
        else:
            alt_amsl = target.alt_m
            if target.alt_frame is AltitudeFrame.ABOVE_HOME:
                home = self.home_geo
                if home is None:
                    return False
                alt_amsl += home.alt_amsl_m
            pos = frame.ned_from_geodetic(target.lat_deg, target.lon_deg, alt_amsl)
        self.commander.set_offboard_target((float(pos[0]), float(pos[1]), float(pos[2])), target.yaw_rad)
        self._offboard_heard()
        return True

    def set_velocity_target(self, target: VelocityTarget) -> bool:
        """An offboard velocity setpoint; a body-frame one is turned with the heading of each control step
        (``Commander.set_offboard_velocity``)."""
        body = target.frame is VelocityFrame.BODY
        self.commander.set_offboard_velocity(target.vel_m_s, target.yaw_rad, target.yaw_rate_rad_s, body=body)
        self._offboard_heard()
        return True

    def _offboard_heard(self) -> None:
        self._offboard_wall_s = self.wall_clock()
        self.commander.offboard_streaming = True

    def set_manual_input(self, sticks: ManualInput) -> bool:
        """Joystick input (MANUAL_CONTROL); POSCTL flies it while it keeps coming (COM_RC_LOSS_T)."""
        self.commander.set_manual_input(sticks)
        self._manual_wall_s = self.wall_clock()
        self.commander.manual_fresh = True
        return True

    def _link_age_s(self, heard_wall_s: float | None) -> float | None:
        """Wall seconds since ``heard_wall_s``, stretched by 1/speed when the sim runs slower than real time
        (like the GCS link timeouts); None if never heard."""
        if heard_wall_s is None:
            return None
        age = self.wall_clock() - heard_wall_s
        speed = self.config.speed_factor
        return age * speed if 0.0 < speed < 1.0 else age

    def offboard_setpoint_age_s(self) -> float | None:
        """Wall seconds since the last offboard setpoint (see ``_link_age_s``); None if none ever came."""
        return self._link_age_s(self._offboard_wall_s)

    def _update_manual_fresh(self) -> None:
        age = self._link_age_s(self._manual_wall_s)
        self.commander.manual_fresh = age is not None and age <= self.params.get("COM_RC_LOSS_T")

    def _update_offboard_streaming(self) -> float | None:
        age = self.offboard_setpoint_age_s()
        self.commander.offboard_streaming = age is not None and age <= self.params.get("COM_OF_LOSS_T")
        return age

    def handle_command(self, request: CommandRequest) -> CommandResult:
        self._update_offboard_streaming()
        result = self.commander.handle_command(request)
        if request.command == MavCmd.MISSION_START and result is CommandResult.ACCEPTED and self.executor is not None:
            first = request.params[0]
            seq = int(first) if math.isfinite(first) and first >= 1.0 else None
            if not self.executor.start(self._now_us(), seq):
                return CommandResult.DENIED
        return result

    def _now_us(self) -> int:
        return self.state.time_us if self.state is not None else 0

    def _executor(self) -> MissionExecutor | None:
        if self.executor is None and self.home_geo is not None:
            self.executor = MissionExecutor(self.home_geo, ExecutorConfig.from_params(self.params))
        return self.executor

    # ------------------------------------------------------------------ the step
    def step(self, frame: FrameLike) -> ActuatorCommand:
        """Answer one lockstep frame (everything here is a function of the frames and commands so far)."""
        if self._pending_truth is not None or self._pending_control is not None:
            self.after_answer()  # the caller did not: the previous step's bookkeeping first
        t_us = frame.sensor.time_us
        if self._prev_time_us is not None and t_us > self._prev_time_us:
            self._dt_s = (t_us - self._prev_time_us) * 1e-6
        self._prev_time_us = t_us
        self.frames += 1
        self.frame_detections = getattr(frame, "detections", ())
        state = self.estimator.update(frame)
        self._pending_truth = frame.truth
        if state is None:
            return ActuatorCommand(t_us, (0.0, 0.0, 0.0, 0.0), False, self.commander.gripper_release)
        self.state = state
        commander = self.commander
        commander.local_frame = self.estimator.local_frame
        # each stage's own "nothing to do" test inline: the calls are a good part of a step's cost
        if commander.home is not self._last_home:
            self._track_home()
        script = self.script
        if script is not None and script.next_at_us <= state.time_us:
            self._run_script(state)
        if state.time_us >= self._next_failsafe_us:
            self._run_failsafes(state)
        if self.executor is not None and commander.mode is FlightMode.AUTO_MISSION:
            self._run_mission(state)
        target = commander.update(state, self.thrust_ratio)
        if commander.gripper_release is not self._payload_released:
            self._apply_payload_mass()
        if commander.mode is not self._last_mode:
            self._follow_mode_changes(state)
        self._target = target
        motor = self._control(state, target)
        self._motor = motor
        return ActuatorCommand(t_us, motor, commander.armed, commander.gripper_release)

    def _run_script(self, state: VehicleState) -> None:
        """Scripted commands due at this sim time, through the same path as GCS commands."""
        assert self.script is not None
        for step in self.script.due(state.time_us):
            request = step.request()
            if request is not None:
                result = self.handle_command(request)
            else:  # goto: metres about home
                n, e, alt = step.args
                home = self.home_ned
                self.commander.goto(state, (home[0] + n, home[1] + e, home[2] - alt))
                result = CommandResult.ACCEPTED
            reason = f" ({self.commander.last_reason})" if result is not CommandResult.ACCEPTED else ""
            self._say(f"Script {step.cmd}: {result.name}{reason}")

    def _track_home(self) -> None:
        home = self.commander.home
        if home is not self._last_home:
            self._last_home = home
            if home is not None:
                executor = self._executor()
                if executor is not None:
                    executor.set_home(home.geo)
                if self.fence:
                    self._set_geofence(geofence_from_items(self.fence, home.geo))
                if self.listener is not None:  # redraw what is drawn about home
                    if self.mission:
                        self.listener.on_mission(self.mission, home.geo)
                    if self.fence:
                        self.listener.on_fence(self.geofence.zones)

    def _run_failsafes(self, state: VehicleState) -> None:
        """Failsafe checks at FAILSAFE_PERIOD_US of sim time (PX4's commander runs them at 10 Hz too)."""
        if state.time_us < self._next_failsafe_us:
            return
        self._next_failsafe_us = state.time_us + FAILSAFE_PERIOD_US
        commander = self.commander
        offboard_age = self._update_offboard_streaming()
        self._update_manual_fresh()
        events = self.failsafe.update(
            FailsafeInputs(
                armed=commander.armed,
                in_air=commander.in_air,
                gcs_heartbeat_age_s=self._gcs_heartbeat_age(),
                offboard_setpoint_age_s=offboard_age if commander.mode is FlightMode.OFFBOARD else None,
                battery_remaining=self.battery.remaining,
                pos_ned_m=state.pos_ned_m,
                home_ned_m=self.home_ned,
            )
        )
        for event in events:
            commander.apply_failsafe(event)
        commander.failsafe_reasons = {kind.value for kind in self.failsafe.active}

    def _run_mission(self, state: VehicleState) -> None:
        commander, executor = self.commander, self.executor
        if executor is None or commander.mode is not FlightMode.AUTO_MISSION:
            return
        home = self.home_ned
        pos = (state.pos_ned_m[0] - home[0], state.pos_ned_m[1] - home[1], state.pos_ned_m[2] - home[2])
        landed = commander.landed_state is LandedState.ON_GROUND
        sample = VehicleSample(state.time_us, pos, state.vel_ned_m_s, landed)
        out = self._last_output = executor.step(sample)
        if self._skip_covered_target(state.time_us):  # never fly toward a waypoint inside an obstacle
            then = executor.step(sample)
            out = self._last_output = replace(
                then, reached=out.reached + then.reached, actions=out.actions + then.actions
            )
        for seq in out.reached:
            self._pending_reached.append(seq)
            self.reached_seqs.append(seq)
            self._say(f"Reached item {seq}")
        for action in out.actions:
            commander.set_gripper(release=action.kind is ActionKind.GRIPPER_RELEASE)
        target = out.target
        if target is None:
            commander.set_mission_target(None)
            return
        face = self._face_along_path(pos, target)
        # built once per executor target, home and parameter set (and LAND descent speed, which changes at
        # MPC_LAND_ALT2); a target that faces along the path gets this step's heading (the only field that changes)
        key: tuple[object, ...] = (target, home, self._param_version)
        if target.kind is NavKind.LAND:
            key = (*key, _mission_land_speed(commander))
        nav = self._mission_nav
        if key != self._mission_nav_key or nav is None:
            self._mission_nav_key = key
            nav = _mission_to_nav(target, home, commander, face)
            self._mission_nav_faces = math.isnan(target.yaw_deg) and target.kind in (NavKind.WAYPOINT, NavKind.RETURN)
        elif self._mission_nav_faces:
            nav = NavTarget(nav.kind, nav.pos_ned_m, face, nav.speed_xy_m_s, nav.speed_up_m_s, nav.speed_down_m_s)
        self._mission_nav = nav
        commander.set_mission_target(nav)

    def _face_along_path(self, pos: Vec3, target: MissionTarget) -> float:
        """Heading (rad) toward where the vehicle is going, about home: the detour's look-ahead point while
        avoiding, else the first route point at least FACE_AHEAD_M away (dense patterns), else the target.
        NaN (keep the heading) with MPC_YAW_MODE 1 or nothing far enough away."""
        if self.params.get("MPC_YAW_MODE") >= 0.5:
            return math.nan
        look = getattr(self._planner_output, "look_ahead_ned", None)
        if look is None or getattr(self._planner_output, "setpoint", None) is None:
            look = target.pos_ned_m
            if target.kind is NavKind.WAYPOINT and math.hypot(look[0] - pos[0], look[1] - pos[1]) < FACE_AHEAD_M:
                route = self._mission_route()
                if route is not None:
                    for row in route.pos_ned_m.tolist()[1:]:
                        look = row
                        if math.hypot(row[0] - pos[0], row[1] - pos[1]) >= FACE_AHEAD_M:
                            break
        dn, de = look[0] - pos[0], look[1] - pos[1]
        return math.atan2(de, dn) if math.hypot(dn, de) >= FACE_MIN_M else math.nan

    def _follow_mode_changes(self, state: VehicleState) -> None:
        mode = self.commander.mode
        if mode is self._last_mode:
            return
        executor = self.executor
        if executor is not None:
            if mode is FlightMode.AUTO_MISSION and executor.state is not MissionState.ACTIVE:
                executor.start(state.time_us)
            elif self._last_mode is FlightMode.AUTO_MISSION:
                executor.pause(state.time_us)
        self._last_mode = mode

    def _control(self, state: VehicleState, target: NavTarget) -> tuple[float, float, float, float]:
        commander, gen = self.commander, self.setpoints
        if target.kind is TargetKind.IDLE:
            self._last_kind = TargetKind.IDLE
            gen.update(target, self._dt_s, state.pos_ned_m)
            self.thrust_ratio = 0.0
            idle = self.params.get("MOT_SPIN_IDLE") if commander.armed else 0.0
            return (idle, idle, idle, idle)
        controller = self.controller
        if controller is None or abs(controller.dt_s - self._dt_s) > 1e-9:
            controller = self.controller = self._rebuild_controller(controller)
        if self._last_kind is TargetKind.IDLE:
            gen.reset(state.pos_ned_m, state.vel_ned_m_s, state.yaw_rad)
            controller.reset()
        self._last_kind = target.kind
        gen.update(target, self._dt_s, state.pos_ned_m)
        avoiding = commander.mode is FlightMode.AUTO_MISSION and target.kind is TargetKind.POSITION
        if avoiding and self.planner is not None:
            self._apply_planner(state, target)
        p, v, a = gen.pos_ned, gen.vel_ned, gen.acc_ned
        out = controller.update_single(  # update_position_single without its Python frame
            state.pos_ned_m,
            state.vel_ned_m_s,
            state.q_ned_frd,
            state.rate_frd_rad_s,
            (p[0], p[1], p[2]),
            (v[0], v[1], v[2]),
            (a[0], a[1], a[2]),
            gen.yaw_rad,
        )
        self.thrust_ratio = out[4] / self._hover_thrust_n
        self._pending_control = out
        return (out[0], out[1], out[2], out[3])

    def after_answer(self) -> None:
        """The latest step's bookkeeping that its command does not depend on (``run_loop`` calls it right after
        the answer, while the sim integrates): the truth hash, the battery model and the tracking statistics;
        and the next step's setpoint reference ahead of time (``SetpointGenerator.prepare``).

        Idempotent; :meth:`step`, :meth:`snapshot`, :meth:`record` and :meth:`summary` call it first when the
        caller did not, so the numbers are the same either way (the next step reads the battery only after it).
        """
        truth = self._pending_truth
        if truth is not None:
            self._pending_truth = None
            self._hash.update(self._pack(truth.time_us, *truth.q_ned_frd, *truth.vel_ned_m_s, truth.lat_deg,
                                         truth.lon_deg, truth.alt_amsl_m))  # fmt: skip
        out = self._pending_control
        if out is not None:
            self._pending_control = None
            self.setpoints.prepare(self._target, self._dt_s)  # the next step's reference, if the target stays
            _, _, _, _, _, ex, ey, ez, eroll, epitch = out
            self.battery.update(self.thrust_ratio, self._dt_s)
            q = self.state.q_ned_frd  # type: ignore[union-attr]  # a control step had a state
            tilt = math.acos(max(-1.0, min(1.0, 1.0 - 2.0 * (q[1] * q[1] + q[2] * q[2]))))
            self.tracking.add(math.sqrt(ex * ex + ey * ey + ez * ez), math.sqrt(eroll * eroll + epitch * epitch), tilt)

    def _apply_planner(self, state: VehicleState, target: NavTarget) -> None:
        """Let the avoidance planner override the reference (about home at its edge) in the setpoint generator.

        The planner gets the mission route from the target on (``MissionExecutor.route_ahead``, two
        CA_LOOKAHEAD_M lengths); waypoints a detour bypassed (``rejoin_route_index``) or that lie inside a
        tracked obstacle's safety volume (``_skip_covered_target``, before the target reaches the commander) are
        skipped in the executor (reported reached, DO items still run).
        """
        planner = self.planner
        assert planner is not None
        idle_output = getattr(planner, "idle_output", None)
        if idle_output is not None:  # nothing to avoid: the output update() would give, without the route
            idle = idle_output(state.time_us, self.frame_detections)
            if idle is not None:
                self._planner_output = idle
                return
        home = self.home_ned
        rel = (state.pos_ned_m[0] - home[0], state.pos_ned_m[1] - home[1], state.pos_ned_m[2] - home[2])
        goal = (target.pos_ned_m[0] - home[0], target.pos_ned_m[1] - home[1], target.pos_ned_m[2] - home[2])
        route = self._mission_route()
        nxt: Sequence[float] | np.ndarray | None = None
        if route is not None:
            nxt = route.pos_ned_m[1:] if len(route.seqs) > 1 else None
        else:
            out = self._last_output
            if out is not None and out.target is not None and out.target.next_pos_ned_m is not None:
                nxt = out.target.next_pos_ned_m
        result = planner.update(
            state.time_us, rel, state.vel_ned_m_s, state.q_ned_frd, self.frame_detections, goal, nxt
        )
        self._planner_output = result
        k = int(getattr(result, "rejoin_route_index", 0))
        if route is not None and 0 < k < len(route.seqs):  # the detour rejoins past waypoints: skip them now
            assert self.executor is not None
            self.executor.skip_to(route.seqs[k], state.time_us)
        setpoint = getattr(result, "setpoint", None)
        for decision in getattr(result, "decisions", ()):
            self._say(str(decision.text), Severity.NOTICE)
        if setpoint is not None:
            p, v, a = setpoint.pos_ned_m, setpoint.vel_ned_m_s, setpoint.acc_ned_m_s2
            self.setpoints.set_reference(
                (float(p[0]) + home[0], float(p[1]) + home[1], float(p[2]) + home[2]),
                (float(v[0]), float(v[1]), float(v[2])),
                (float(a[0]), float(a[1]), float(a[2])),
            )

    def _mission_route(self) -> MissionRoute | None:
        """The executor's route when the flown target is its current positional item (None otherwise)."""
        executor, out = self.executor, self._last_output
        if executor is None or out is None or out.target is None or executor.state is not MissionState.ACTIVE:
            return None
        if out.target.kind not in (NavKind.WAYPOINT, NavKind.LOITER) or out.target.seq != executor.current_seq:
            return None
        route = executor.route_ahead(ROUTE_AHEAD_LOOKAHEADS * self.params.get("CA_LOOKAHEAD_M"), ROUTE_MAX_POINTS)
        return route if route.seqs and route.seqs[0] == out.target.seq else None

    def _skip_covered_target(self, time_us: int) -> bool:
        """Skip the route's head while it lies inside a tracked obstacle's safety volume (CA_RSAFE_M; obstacles
        of the planner's latest output) to the first route point outside, or the item the route stops at."""
        obstacles = getattr(self._planner_output, "obstacles", ())
        route = self._mission_route() if obstacles else None
        if route is None:
            return False
        checked = self._route_checked
        if checked is not None and checked[0] is route and checked[1] is obstacles:
            return False  # both unchanged since the last check (the executor and the map cache them)
        self._route_checked = (route, obstacles)
        r_safe = self.params.get("CA_RSAFE_M")
        clear = np.full(len(route.seqs), np.inf)
        for obstacle in obstacles:
            np.minimum(clear, obstacle.signed_distance(route.pos_ned_m), out=clear)
        if clear[0] >= r_safe:
            return False
        outside = np.flatnonzero(clear >= r_safe)
        seq = route.seqs[int(outside[0])] if len(outside) else route.next_seq
        assert self.executor is not None
        if seq < 0 or not self.executor.skip_to(seq, time_us):
            return False
        self._say(f"Skipped to item {seq}: item {route.seqs[0]} lies inside an obstacle's safety volume")
        return True

    # ------------------------------------------------------------------ after the answer
    def drain_texts(self) -> list[StatusText]:
        """Events (commander + runner) since the last call."""
        texts = self.commander.drain_texts()
        if self.texts:
            texts += self.texts
            self.texts = []
        return texts

    def snapshot(self) -> TelemetrySnapshot | None:
        """The telemetry snapshot of the latest step (None before the first state)."""
        self.after_answer()
        state = self.state
        if state is None:
            return None
        commander = self.commander
        home = commander.home
        home_geo = home.geo if home is not None else self.estimator.origin
        out = self._last_output
        gps_ok = state.gps_fix_type >= 3
        reached, self._pending_reached = self._pending_reached, []
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
            battery_voltage_v=self.battery.voltage_v,
            battery_current_a=self.battery.current_a(self.thrust_ratio),
            battery_remaining_pct=100.0 * self.battery.remaining,
            throttle_pct=100.0 * min(1.0, self.thrust_ratio * self._hover_fraction()),
            sensors_present=_SENSORS_REPORTED,
            sensors_enabled=_SENSORS_REPORTED,
            sensors_health=self._sensors_health(state, gps_ok),
            mission_seq_current=out.current_seq if out is not None else 0,
            mission_count=len(self.mission),
            mission_reached=reached,
            mission_state=int(self.executor.state) if self.executor is not None else int(MissionState.NO_MISSION),
        )

    def _sensors_health(self, state: VehicleState, gps_ok: bool) -> int:
        """SYS_STATUS health bits: GPS with a 3D fix, no geofence breach, pre-arm checks passing."""
        commander = self.commander
        health = _SENSORS_PRESENT if gps_ok else _SENSORS_PRESENT & ~_SENSOR_GPS
        if FailsafeKind.GEOFENCE.value not in commander.failsafe_reasons:
            health |= _SENSOR_GEOFENCE
        if commander.armed or commander.arming_refusal(state) is None:
            health |= _SENSOR_PREARM_CHECK
        return health

    def _hover_fraction(self) -> float:
        """Hover thrust as a fraction of the maximum (to turn thrust_ratio into throttle)."""
        return self._hover_thrust_n / (4.0 * self.airframe.max_rotor_thrust_n)

    def record(self, texts: Sequence[StatusText]) -> StepRecord | None:
        """The step record for a listener (None before the first state)."""
        self.after_answer()
        state = self.state
        if state is None:
            return None
        gen, commander = self.setpoints, self.commander
        out = self._last_output
        return StepRecord(
            time_us=state.time_us,
            state=state,
            target=self._target,
            pos_sp_ned_m=(gen.pos_ned[0], gen.pos_ned[1], gen.pos_ned[2]),
            vel_sp_ned_m_s=(gen.vel_ned[0], gen.vel_ned[1], gen.vel_ned[2]),
            acc_sp_ned_m_s2=(gen.acc_ned[0], gen.acc_ned[1], gen.acc_ned[2]),
            yaw_sp_rad=gen.yaw_rad,
            motor_cmd=self._motor,
            thrust_ratio=self.thrust_ratio,
            armed=commander.armed,
            mode=commander.mode,
            landed_state=commander.landed_state,
            home_ned_m=commander.home.pos_ned_m if commander.home is not None else None,
            mission_seq=out.current_seq if out is not None else 0,
            reached=tuple(self._pending_reached),
            texts=tuple(texts),
            detections=self.frame_detections,
            planner_output=self._planner_output,
            controller=self.controller,
            battery_remaining_pct=100.0 * self.battery.remaining,
            battery_voltage_v=self.battery.voltage_v,
        )

    # ------------------------------------------------------------------ summary
    def summary(self, wall_time_s: float) -> dict[str, object]:
        """``autopilot_summary.json`` (SPEC §12): mission progress, modes, landing, tracking errors."""
        self.after_answer()
        commander = self.commander
        tr = self.tracking
        sim_time_s = (self.state.time_us * 1e-6) if self.state is not None else 0.0
        executor = self.executor
        return {
            "end_reason": (self.end_reason or AutopilotEndReason.STOPPED).value,
            "sim_time_s": round(sim_time_s, 6),
            "wall_time_s": round(wall_time_s, 3),
            "frames": self.frames,
            "vehicle": self.airframe.name,
            "items_total": len(self.mission),
            "items_reached": len(set(self.reached_seqs)),
            "reached_seqs": list(self.reached_seqs),
            "mission_state": executor.state.name if executor is not None else MissionState.NO_MISSION.name,
            "mode": commander.mode.name,
            "mode_history": [{"t_s": t / 1e6, "mode": m.name} for t, m in commander.mode_history],
            "armed": commander.armed,
            "landed": commander.landed_state is LandedState.ON_GROUND,
            "disarmed": not commander.armed,
            "payload_released": commander.gripper_release,
            "battery_remaining": round(self.battery.remaining, 4),
            "tracking_pos_err_rms_m": math.sqrt(tr.pos_sq_sum / tr.n) if tr.n else 0.0,
            "tracking_pos_err_max_m": tr.pos_max,
            "tracking_att_err_rms_deg": math.degrees(math.sqrt(tr.att_sq_sum / tr.n)) if tr.n else 0.0,
            "tracking_att_err_max_deg": math.degrees(tr.att_max),
            "max_tilt_deg": math.degrees(tr.max_tilt_rad),
            "flying_steps": tr.n,
            "truth_sha256": self._hash.hexdigest(),
        }

    def write_summary(self, wall_time_s: float) -> Path | None:
        """Write ``LOG_DIR/autopilot_summary.json`` (None without a log dir)."""
        if not self.config.log_dir:
            return None
        path = Path(self.config.log_dir) / "autopilot_summary.json"
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(json.dumps(self.summary(wall_time_s), indent=2) + "\n")
        return path


class VehicleAdapter:
    """The ``VehicleInterface`` the GCS and API servers call: commands, missions, parameters."""

    def __init__(self, autopilot: Autopilot) -> None:
        self._ap = autopilot

    def handle_command(self, request: CommandRequest) -> CommandResult:
        return self._ap.handle_command(request)

    def mission_items(self, mission_type: MissionType) -> list[MissionItem]:
        return self._ap.mission_items(mission_type)

    def replace_mission(self, mission_type: MissionType, items: list[MissionItem]) -> tuple[MissionResult, str]:
        return self._ap.replace_mission(mission_type, items)

    def set_current_mission_item(self, seq: int) -> bool:
        return self._ap.set_current_mission_item(seq)

    def set_position_target(self, target: PositionTarget) -> bool:
        return self._ap.set_position_target(target)

    def set_velocity_target(self, target: VelocityTarget) -> bool:
        return self._ap.set_velocity_target(target)

    def set_manual_input(self, sticks: ManualInput) -> bool:
        return self._ap.set_manual_input(sticks)

    def param_names(self) -> list[str]:
        return self._ap.params.names()

    def param_get(self, name: str) -> float | None:
        params = self._ap.params
        return params.get(name) if name in params else None

    def param_set(self, name: str, value: float) -> tuple[bool, float, str]:
        params = self._ap.params
        try:
            return True, params.set(name, value), ""
        except ParamError as exc:
            current = params.get(name) if name in params else math.nan
            return False, current, str(exc)


@dataclass
class Links:
    """The sockets of one autopilot process (SPEC §3); any of the GCS/API servers may be absent."""

    lockstep: object  # mavlink_bridge.lockstep.LockstepClient
    gcs: list[object] = field(default_factory=list)  # mavlink_bridge.gcs_server.GcsServer


def run_loop(
    autopilot: Autopilot,
    links: Links,
    should_stop: Callable[[], bool],
    *,
    connect_timeout_s: float = 30.0,
) -> AutopilotEndReason:
    """Serve the lockstep until stopped or the sim is gone; GCS links polled between frames."""
    client = links.lockstep
    servers = links.gcs
    if servers:
        autopilot._gcs_heartbeat_age = lambda: _gcs_age(servers)
    t0 = time.monotonic()
    next_poll = 0.0
    steps = 0
    reason = AutopilotEndReason.STOPPED
    while not should_stop():
        frame = client.next_frame(_LINK_POLL_PERIOD_S)  # type: ignore[attr-defined]
        now = time.monotonic()
        if frame is not None:
            client.answer(autopilot.step(frame))  # type: ignore[attr-defined]
            autopilot.after_answer()  # while the sim integrates the next step
            steps += 1
        elif client.sim_lost:  # type: ignore[attr-defined]
            reason = AutopilotEndReason.SIM_LOST
            break
        elif not client.connected and now - t0 > connect_timeout_s:  # type: ignore[attr-defined]
            reason = AutopilotEndReason.SIM_NEVER_CONNECTED
            break
        texts = autopilot.drain_texts()
        if servers:
            state = autopilot.state
            sim_us = state.time_us if state is not None else 0
            if frame is not None and (steps % _SNAPSHOT_EVERY == 0 or texts or autopilot._pending_reached):
                snapshot = autopilot.snapshot()
                if snapshot is not None:
                    for server in servers:
                        server.publish(snapshot)  # type: ignore[attr-defined]
            for text in texts:
                for server in servers:
                    server.statustext(text.severity, text.text)  # type: ignore[attr-defined]
            if frame is None or now >= next_poll:
                next_poll = now + _LINK_POLL_PERIOD_S
                for server in servers:
                    server.poll(sim_us, now)  # type: ignore[attr-defined]
        listener = autopilot.listener
        if listener is not None:
            record = autopilot.record(texts) if frame is not None else None
            if record is not None:
                listener.on_step(record)
            else:  # no step carries them: the texts still reach the recording, at the latest sim time
                for text in texts:
                    listener.on_event(text.text, text.severity, autopilot._now_us())
    autopilot.end_reason = reason
    return reason


def _gcs_age(servers: Sequence[object]) -> float | None:
    """Wall seconds since the youngest GCS heartbeat over all links (None if none ever)."""
    ages = [server.gcs_heartbeat_age_s for server in servers]  # type: ignore[attr-defined]
    age = min(ages) if ages else math.inf
    return None if math.isinf(age) else age
