"""The autopilot: composes its modules and steps them once per lockstep frame (SPEC §3-§4). No sockets.
Every frame (250 Hz): [failures] -> [stale-data check] -> estimator -> setpoints -> [avoidance] -> [traffic's
reactive layer] -> cascade -> [motor failures] -> ActuatorCommand (+ its UTM report). At 50 Hz and after any
command: failsafes (10 Hz), navigator, commander. The answer goes out *before* the bookkeeping
(:meth:`Autopilot.after_answer`), while the simulator integrates; ``docs/architecture.md`` says what each owns."""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from pathlib import Path

from autopilot.commander.inputs import CommandContext, CommanderInputs
from autopilot.commander.script import CommandScript
from autopilot.commander.state_machine import Commander
from autopilot.control.airframe import Airframe, load_airframe
from autopilot.control.cascade import SingleStep
from autopilot.estimation import Estimator, FrameLike, VehicleState, make_estimator
from autopilot.flight_control.controller import FlightControl
from autopilot.flight_tasks.setpoints import NavTarget, TargetKind
from autopilot.navigation import HomeFrame, Navigator
from autopilot.navigation.own_report import OwnReporter
from autopilot.param_binding import autopilot_bindings
from autopilot.param_schema import make_param_store
from autopilot.parameters.store import ParamStore
from autopilot.planner.param_decls import PlannerParams
from autopilot.planner.planner import AvoidancePlanner
from autopilot.reporting import report
from autopilot.reporting.report import AutopilotEndReason, MissionProgress, StepListener, StepRecord
from autopilot.safety.failsafe import BatteryModel, FailsafeInputs, FailsafeMonitor, SensorFailsafe
from autopilot.safety.failure_injection import FailureInjector
from autopilot.safety.link_health import LinkHealth
from autopilot.safety.sensor_validation import StaleSensorCheck
from mavlink_bridge.contract.frames import GeoPoint, Vec3
from mavlink_bridge.contract.mav_enums import MavCmd
from mavlink_bridge.contract.vehicle_api import (
    CommandRequest,
    CommandResult,
    FlightMode,
    LandedState,
    MissionItem,
    MissionType,
    Severity,
    StatusText,
    TelemetrySnapshot,
)
from mavlink_bridge.contract.wire import ActuatorCommand, ObstacleDetection

#: Failsafe conditions are evaluated every this much sim time (µs); PX4's commander runs them at 10 Hz too.
FAILSAFE_PERIOD_US = 100_000
#: Navigator and commander period (µs, 50 Hz as PX4's navigator and land detector; at once after a command).
NAV_PERIOD_US = 20_000
_IDLE = NavTarget(TargetKind.IDLE)


@dataclass(frozen=True)
class AutopilotConfig:
    """Settings of one autopilot instance (the CLI fills it, SPEC §12)."""

    vehicle: str = "x500"
    estimator: str = "truth"
    params_file: str | None = None
    log_dir: str | None = None
    speed_factor: float = 1.0  # only stretches GCS timeouts when < 1 (the sim owns time)
    avoidance: bool = True  # run the obstacle-avoidance planner in AUTO_MISSION (CA_ENABLE switches detours)
    system_id: int = 1  # MAV_SYS_ID: traffic avoidance's right of way between vehicles depends on it (SPEC §13)


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
        planner: object | None = None,
        script: CommandScript | None = None,
        wall_clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self.config = config or AutopilotConfig()
        self.airframe = airframe or load_airframe(self.config.vehicle)
        self.params = params or make_param_store(
            self.config.params_file, payload_nominal_kg=self.airframe.payload_nominal_kg, airframe=self.airframe.name
        )
        self.estimator = estimator or make_estimator(self.config.estimator)
        self.listener = listener
        if planner is None and self.config.avoidance:
            planner = AvoidancePlanner(PlannerParams.from_store(self.params))
        self.commander = Commander(self.params)
        self.commander.rtl.await_route = True  # the navigator routes every return (navigation.return_routing)
        self.navigator = Navigator(self.params, planner, self.commander.mission_land_speed_m_s, self.config.system_id)  # type: ignore[arg-type]
        self.script = script
        self.links = LinkHealth(self.config.speed_factor, wall_clock)
        self.failures = FailureInjector(self.params)  # what the estimator sees and the motors get (SYS_FAILURE_EN)
        self.commander.command_handlers[MavCmd.INJECT_FAILURE] = self.failures.handle_command
        self.sensor_check = StaleSensorCheck()  # a stuck mag/baro is dropped before the estimator
        self.control = FlightControl(self.params, self.airframe)
        self.failsafe = FailsafeMonitor(self.params)
        self.sensor_failsafe = SensorFailsafe(self.params)
        self.battery = BatteryModel(self.params.get("BAT_HOVER_ENDUR"))
        self.state: VehicleState | None = None
        self.tracking = report.Tracking()
        self.truth_hash = report.TruthHash()
        self.progress = MissionProgress()
        self.frames = 0
        self.end_reason: AutopilotEndReason | None = None
        self.frame_detections: tuple[ObstacleDetection, ...] = ()
        self._map_detections: Sequence[ObstacleDetection] = ()  # the frame's, less those of tracked vehicles
        self._texts: list[StatusText] = []
        self._context = CommandContext()
        self._prev_time_us: int | None = None
        self._last_mode = self.commander.mode
        self._last_home: object | None = None
        self._target = _IDLE
        self._pending_truth: object | None = None  # this step's truth, hashed by after_answer
        self._truth: object | None = None  # the latest truth, for the step record (estimate vs truth)
        self._pending_control: SingleStep | None = None  # this step's cascade output, booked by after_answer
        self._motor, self._dt_s = (0.0, 0.0, 0.0, 0.0), 0.004
        self._next_failsafe_us = self._next_nav_us = 0
        self.own_reporter = OwnReporter(self.config.system_id)  # its UTM report at 1 Hz: report_for(t_us) (SPEC §13)
        autopilot_bindings(
            self.navigator, self.control, self.battery, self._apply_controller_params, self._listener_safety_radius
        ).attach(self.params)

    def _apply_controller_params(self, _name: str, _value: float) -> None:
        problem = self.control.apply_controller_params()
        if problem is not None:
            self._say(problem, Severity.WARNING)

    def _listener_safety_radius(self, _name: str, value: float) -> None:  # drawn safety spheres follow R_safe
        if hasattr(self.listener, "safety_radius_m"):
            self.listener.safety_radius_m = value  # type: ignore[union-attr]

    # ------------------------------------------------------------------ geography
    @property
    def home_geo(self) -> GeoPoint | None:
        """Home if armed once, else the estimator's origin (where home will be), else None."""
        return self.commander.home.geo if self.commander.home is not None else self.estimator.origin

    @property
    def home_ned(self) -> Vec3:
        """Home about the estimator origin."""
        return self.commander.home.pos_ned_m if self.commander.home is not None else (0.0, 0.0, 0.0)

    def _say(self, text: str, severity: Severity = Severity.INFO) -> None:
        self._texts.append(StatusText(severity, text))

    def update_context(self, **changes: object) -> CommandContext:
        """The commander's context with ``changes`` (a new object only on a change, which wakes the slow loop)."""
        context = self._context
        if any(getattr(context, name) != value for name, value in changes.items()):
            context = self._context = replace(context, **changes)  # type: ignore[arg-type]
            self.wake_navigation()
        return context

    # ------------------------------------------------------------------ commands (GCS, API, script)
    def mission_accepted(self, mission_type: MissionType, items: Sequence[MissionItem]) -> None:
        """An upload the navigator accepted: the commander's context and the listener's drawing follow."""
        self.update_context(mission_ready=self.navigator.mission_ready)
        home = self.home_geo
        if self.listener is not None and home is not None and mission_type is MissionType.FENCE:
            self.listener.on_fence(self.navigator.geofence.zones)
        elif self.listener is not None and home is not None:
            self.listener.on_mission(items, home)

    def handle_command(self, request: CommandRequest) -> CommandResult:
        self.wake_navigation()
        streaming = self.links.offboard_streaming(self.params.get("COM_OF_LOSS_T"))
        result = self.commander.handle_command(request, self.update_context(offboard_streaming=streaming))
        if request.command == MavCmd.MISSION_START and result is CommandResult.ACCEPTED:
            first = request.params[0]
            seq = int(first) if math.isfinite(first) and first >= 1.0 else None
            if not self.navigator.start_mission(self._now_us(), seq):
                return CommandResult.DENIED
        return result

    def _now_us(self) -> int:
        return self.state.time_us if self.state is not None else 0

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
        self.navigator.traffic.receive(getattr(frame, "traffic", ()))  # TrafficReports received with this frame
        seen = self.sensor_check.apply(self.failures.apply_to_frame(frame), self.commander.in_air)
        self.estimator.set_landed(self.commander.landed_state is LandedState.ON_GROUND)
        state = self.estimator.update(seen)
        self._pending_truth = self._truth = frame.truth
        commander = self.commander
        if state is None:
            return ActuatorCommand(t_us, (0.0, 0.0, 0.0, 0.0), False, commander.gripper_release)
        self.state = state
        self._map_detections = self.navigator.sense(state, self.frame_detections)  # tracked vehicles: traffic's
        commander.observe(state)
        status = self.estimator.status  # the same object while nothing changes
        if status is not self._context.estimator_status:  # arming checks and SYS_STATUS read it
            self.update_context(estimator_status=status)
        if state.time_us >= self._next_nav_us:  # 50 Hz, and at once after a command
            self._next_nav_us = state.time_us + NAV_PERIOD_US
            self._navigate(state)
        motor = self.failures.apply_to_motors(self._control(state, self._target))
        self._motor = motor
        self.own_reporter.step(state, self.estimator, self._target, commander, self.home_ned, self._context)
        return ActuatorCommand(t_us, motor, commander.armed, commander.gripper_release)

    def _navigate(self, state: VehicleState) -> None:
        """The slow loop: home, scripted commands, failsafes (10 Hz), the navigator and the commander, which
        set the target flight control flies until the next call (PX4: navigator and land detector at 50 Hz)."""
        commander = self.commander
        if commander.home is not self._last_home or self.navigator.frame is None:
            self._track_home(state)
        script = self.script
        if script is not None and script.next_at_us <= state.time_us:
            self._run_script(state)
        if state.time_us >= self._next_failsafe_us:
            self._run_failsafes(state)
        on_ground, rtl_goal = commander.landed_state is LandedState.ON_GROUND, commander.rtl.return_goal_ned_m
        nav = self.navigator.update(state, commander.mode, on_ground, self._map_detections, rtl_goal)
        self.progress.add(nav.reached)  # () most steps
        if nav.gripper_release is not None:
            commander.set_gripper(release=nav.gripper_release)
        if nav.failsafe is not None:  # no route to the mission target for CA_NOROUTE_T
            commander.apply_failsafe(nav.failsafe)
        fc = self.control
        inputs = CommanderInputs(state, fc.thrust_ratio, self.estimator.local_frame, self._context, nav.mission_target)
        self._target = commander.update(inputs)
        if commander.gripper_release is not fc.payload_released:
            fc.set_payload_released(commander.gripper_release)
        if commander.mode is not self._last_mode:
            self.navigator.mode_changed(commander.mode, self._last_mode, state.time_us)
            self._last_mode = commander.mode

    def wake_navigation(self) -> None:
        """Run the slow loop at the next step (a command, an upload or a setpoint arrived)."""
        self._next_nav_us = 0

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

    def _track_home(self, state: VehicleState) -> None:
        """Home moved (first fix, arming): the navigator's frame follows, with the fix's GPS accuracy; views redraw."""
        home = self.commander.home
        self._last_home = home
        if home is not None:
            frame = HomeFrame(home.geo, home.pos_ned_m, state.gps_eph_m, state.gps_epv_m)
        elif self.estimator.origin is not None:  # before arming: home will be about here
            frame = HomeFrame(self.estimator.origin, (0.0, 0.0, 0.0), state.gps_eph_m, state.gps_epv_m)
        else:
            return
        nav = self.navigator
        nav.set_home(frame)
        self.update_context(mission_ready=nav.mission_ready)  # the stored mission was checked against home
        if self.listener is not None and home is not None:
            for mission_type, items in ((MissionType.MISSION, nav.mission), (MissionType.FENCE, nav.fence)):
                if items:
                    self.mission_accepted(mission_type, items)

    def _run_failsafes(self, state: VehicleState) -> None:
        """Failsafe checks at FAILSAFE_PERIOD_US of sim time; link freshness refreshed for the commander too."""
        self._next_failsafe_us = state.time_us + FAILSAFE_PERIOD_US
        commander, p = self.commander, self.params.get
        offboard_age = self.links.offboard_age_s()
        self.update_context(
            offboard_streaming=offboard_age is not None and offboard_age <= p("COM_OF_LOSS_T"),
            manual_fresh=self.links.manual_fresh(p("COM_RC_LOSS_T")),
        )
        events = self.failsafe.update(
            FailsafeInputs(
                armed=commander.armed,
                in_air=commander.in_air,
                gcs_heartbeat_age_s=self.links.gcs_heartbeat_age_s(),
                offboard_setpoint_age_s=offboard_age if commander.mode is FlightMode.OFFBOARD else None,
                battery_remaining=self.battery.remaining,
                pos_ned_m=state.pos_ned_m,
                home_ned_m=self.home_ned,
                geofence=self.navigator.geofence,
            )
        )
        for event in events:
            commander.apply_failsafe(event)
        status = self.estimator.status
        for event in self.sensor_failsafe.update(state.time_us, status, commander.armed, commander.in_air):
            commander.apply_failsafe(event)
        self.update_context(failsafe_reasons=frozenset(kind.value for kind in self.failsafe.active))

    def _control(self, state: VehicleState, target: NavTarget) -> tuple[float, float, float, float]:
        fc, commander, nav = self.control, self.commander, self.navigator
        if target.kind is TargetKind.IDLE:
            return fc.idle(state, target, commander.armed, self._dt_s)
        fc.reference_for(state, target, self._dt_s)
        if target.kind is TargetKind.POSITION and (commander.mode is FlightMode.AUTO_MISSION or nav.returns.active):
            override = nav.avoid(state, target, self._map_detections)  # each frame's: the sensor runs at 10 Hz
            if override is not None:
                fc.override(override)
        if nav.traffic.bound(state, fc, commander.mode, target, self._dt_s, commander.landed_state):
            return fc.idle(state, _IDLE, commander.armed, self._dt_s)  # held on the pad: PX4's ready-for-takeoff
        out = self._pending_control = fc.control(state)
        return (out[0], out[1], out[2], out[3])

    def after_answer(self) -> None:
        """The latest step's bookkeeping that its command does not depend on (``run_loop`` calls it right after
        the answer, while the sim integrates): the truth hash, the battery model and the tracking statistics;
        and the next step's setpoint reference ahead of time (``SetpointGenerator.prepare``).

        Idempotent; :meth:`step`, :meth:`snapshot`, :meth:`record` and :meth:`summary` call it first when the
        caller did not, so the numbers are the same either way (the next step reads the battery only after it)."""
        truth = self._pending_truth
        if truth is not None:
            self._pending_truth = None
            self.truth_hash.add(truth)  # type: ignore[arg-type]
        out = self._pending_control
        if out is not None:
            self._pending_control = None
            self.control.setpoints.prepare(self._target, self._dt_s)  # the next step's reference, if it stays
            _, _, _, _, _, ex, ey, ez, eroll, epitch = out
            self.battery.update(self.control.thrust_ratio, self._dt_s)
            q = self.state.q_ned_frd  # type: ignore[union-attr]  # a control step had a state
            tilt = math.acos(max(-1.0, min(1.0, 1.0 - 2.0 * (q[1] * q[1] + q[2] * q[2]))))
            self.tracking.add(math.sqrt(ex * ex + ey * ey + ez * ez), math.sqrt(eroll * eroll + epitch * epitch), tilt)

    # ------------------------------------------------------------------ after the answer
    def drain_texts(self) -> list[StatusText]:
        """Events (commander, navigator, runner) since the last call."""
        texts = self.commander.drain_texts() + self.navigator.drain_texts()
        texts += [*self.failures.drain_texts(), *self.sensor_check.drain_texts()]
        if self._texts:
            texts += self._texts
            self._texts = []
        return texts

    def record(self, texts: Sequence[StatusText]) -> StepRecord | None:
        """The step record for a listener (None before the first state)."""
        self.after_answer()
        state = self.state
        if state is None:
            return None
        commander, fc, traffic = self.commander, self.control, self.navigator.traffic
        flying = self._target.kind is not TargetKind.IDLE
        return StepRecord(
            time_us=state.time_us,
            state=state,
            target=self._target,
            reference=fc.reference,
            motor_cmd=self._motor,
            thrust_ratio=fc.thrust_ratio,
            armed=commander.armed,
            mode=commander.mode,
            landed_state=commander.landed_state,
            home_ned_m=commander.home.pos_ned_m if commander.home is not None else None,
            mission_seq=self.navigator.current_seq,
            reached=tuple(self.progress.pending),
            texts=tuple(texts),
            detections=self.frame_detections,
            planner_output=self.navigator.planner_output,
            control=fc.controller.sample() if flying else None,
            battery_remaining_pct=100.0 * self.battery.remaining, battery_voltage_v=self.battery.voltage_v,
            truth=self._truth,  # type: ignore[arg-type]
            estimator_status=self.estimator.status,
            planned_route_home_ned_m=self.navigator.route_path_home_ned_m,
            traffic_decision=traffic.decision, uav_separation=traffic.avoidance.params.uav,
        )  # fmt: skip

    def snapshot(self) -> TelemetrySnapshot | None:
        """The telemetry snapshot of the latest step (None before the first state)."""
        self.after_answer()
        if self.state is None:
            return None
        snap = report.snapshot(
            self.state, self.commander, self.navigator, self.control, self.battery, self.progress, self.estimator.origin
        )
        failed = self.failures.unhealthy_bits  # a failed motor clears the motor-outputs bit
        return replace(snap, sensors_health=snap.sensors_health & ~failed) if failed else snap

    def summary(self, wall_time_s: float, lockstep: dict[str, int] | None = None) -> dict[str, object]:
        """``autopilot_summary.json`` (SPEC §12): mission progress, modes, landing, tracking errors; ``lockstep``:
        the link's counters (frames, strangers and invalid frames dropped), from the I/O edge."""
        self.after_answer()
        flight = {
            "end_reason": (self.end_reason or AutopilotEndReason.STOPPED).value,
            "sim_time_s": round(self._now_us() * 1e-6, 6),
            "wall_time_s": round(wall_time_s, 3),
            "frames": self.frames,
            "vehicle": self.airframe.name,
            **({} if lockstep is None else {"lockstep": lockstep}),
        }
        return report.summary(
            self.commander, self.navigator, self.battery, self.progress, self.tracking, self.truth_hash, flight
        )

    def write_summary(self, wall_time_s: float, lockstep: dict[str, int] | None = None) -> Path | None:
        """Write ``LOG_DIR/autopilot_summary.json`` (None without a log dir)."""
        if not self.config.log_dir:
            return None
        summary = self.summary(wall_time_s, lockstep)
        return report.write_json(Path(self.config.log_dir) / "autopilot_summary.json", summary)
