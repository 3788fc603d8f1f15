"""The commander: arming, flight modes and landed state; each step, the target of the mode's flight task (SPEC §3,
§8).

An explicit state machine with no I/O and no clock: the runner feeds it the vehicle state (sim time inside),
decoded GCS commands (:mod:`autopilot.commander.commands`, its base class) and failsafe events; it answers each
command with an honest :class:`CommandResult` (and :attr:`Commander.last_reason` when refused) and produces one
:class:`NavTarget` per step for the setpoint generator.

State: ``armed``; ``mode`` (PX4-encoded :class:`FlightMode`); ``landed_state`` (:class:`LandedState`); ``home``
(set at the first 3D GPS fix and again at arming, as PX4 does); ``gripper_release``. Each mode flies one flight
task of :mod:`autopilot.flight_tasks` (PX4's FlightTasks): HOLD (``hold``), POSCTL (``sticks``, holding when
centred or without a joystick), AUTO_TAKEOFF (``takeoff``, then HOLD), AUTO_LAND (``land``; blind after a
position-loss failsafe), AUTO_RTL (``rtl``), OFFBOARD (``offboard``; entered only while setpoints stream, PX4's
rule: the runner sets ``offboard_streaming``; leaving it on a setpoint loss is the failsafe's job) and
AUTO_MISSION (the mission executor's target, through the navigator). On the ground, a target above the vehicle
or a climbing velocity takes off; the land detector (:mod:`autopilot.safety.land_detector`) sees touchdown,
then auto-disarm after ``COM_DISARM_LAND``.
"""

from __future__ import annotations

import math

from autopilot.commander.commands import CommandHandling
from autopilot.commander.inputs import CommandContext, CommanderInputs, CommandHandler, Home
from autopilot.estimation import VehicleState
from autopilot.flight_tasks.hold import HoldTask
from autopilot.flight_tasks.land import LandTask, land_speed_m_s
from autopilot.flight_tasks.offboard import OffboardTask
from autopilot.flight_tasks.position_control import StickTask
from autopilot.flight_tasks.rtl import RtlTask
from autopilot.flight_tasks.setpoints import NavTarget, TargetKind
from autopilot.flight_tasks.takeoff import TakeoffTask
from autopilot.flight_tasks.targets import face_yaw
from autopilot.parameters.store import ParamStore
from autopilot.safety.failsafe import FailsafeAction, FailsafeEvent, FailsafeKind
from autopilot.safety.land_detector import LandDetector
from mavlink_bridge.contract.frames import GeoPoint, LocalNedFrame
from mavlink_bridge.contract.vehicle_api import (
    CommandResult,
    FlightMode,
    LandedState,
    ManualInput,
    Severity,
    StatusText,
)
from mavlink_bridge.contract.wire import Vec3

#: An armed vehicle on the ground takes off when its target is this far above it (m).
_TAKEOFF_TRIGGER_M = 0.5
#: On the ground in OFFBOARD, a velocity setpoint climbing at least this fast takes off (m/s).
_TAKEOFF_TRIGGER_M_S = 0.3
#: Outside AUTO_TAKEOFF, a climbing vehicle counts as in the air above this height over home (m).
_AIRBORNE_ALT_M = 1.0

_ARMABLE_MODES = frozenset(
    {FlightMode.POSCTL, FlightMode.AUTO_LOITER, FlightMode.AUTO_TAKEOFF, FlightMode.AUTO_MISSION, FlightMode.OFFBOARD}
)
_SUPPORTED_MODES = _ARMABLE_MODES | {FlightMode.AUTO_LAND, FlightMode.AUTO_RTL}


class Commander(CommandHandling):
    """Arming, modes, landed state, land detector; one :class:`NavTarget` per :meth:`update`."""

    def __init__(self, params: ParamStore) -> None:
        self.params = params
        self.armed = False
        self.mode = FlightMode.AUTO_LOITER
        self.landed_state = LandedState.ON_GROUND
        self.home: Home | None = None
        self.gripper_release = False
        self.local_frame: LocalNedFrame | None = None  # the estimator's, from the latest inputs
        self.context = CommandContext()  # the latest one given with inputs or a command
        self.last_reason = ""
        self.command_handlers: dict[int, CommandHandler] = {}  # MAV_CMD number -> handler (e.g. INJECT_FAILURE)
        self.mode_history: list[tuple[int, FlightMode]] = []
        self._texts: list[StatusText] = []
        self._state: VehicleState | None = None
        self.hold = HoldTask()
        self.takeoff = TakeoffTask()
        self.land = LandTask()
        self.rtl = RtlTask()
        self.offboard = OffboardTask()
        self.sticks = StickTask()
        self._speed_xy_m_s: float | None = None  # DO_CHANGE_SPEED override
        self._speeds_key: tuple[int, float | None] = (-1, None)  # _speeds() cache
        self._speeds_m_s = (0.0, 0.0, 0.0)
        self.land_detector = LandDetector(params)
        self._mission_target: NavTarget | None = None
        self._touchdown_us: int | None = None
        self._armed_at_us = 0

    # ------------------------------------------------------------------ helpers
    @property
    def state(self) -> VehicleState | None:
        """The vehicle state of the latest :meth:`update`."""
        return self._state

    @property
    def in_air(self) -> bool:
        return self.landed_state in (LandedState.IN_AIR, LandedState.TAKEOFF, LandedState.LANDING)

    @property
    def speed_xy_m_s(self) -> float:
        """Horizontal cruise speed in force (DO_CHANGE_SPEED override or MIS_CRUISE_SPD), capped."""
        p = self.params.get
        speed = self._speed_xy_m_s if self._speed_xy_m_s is not None else p("MIS_CRUISE_SPD")
        return min(speed, p("MPC_XY_VEL_MAX"))

    def home_down_m(self) -> float:
        """Down of home; before arming, of the vehicle (where home will be)."""
        if self.home is not None:
            return self.home.pos_ned_m[2]
        return self._state.pos_ned_m[2] if self._state is not None else 0.0

    def alt_rel_home_m(self, state: VehicleState) -> float:
        return self.home_down_m() - state.pos_ned_m[2]

    def _set_mode(self, mode: FlightMode) -> None:
        if mode is self.mode:
            return
        self.mode = mode
        self.land.blind = self.land.blind and mode is FlightMode.AUTO_LAND
        t_us = self._state.time_us if self._state is not None else 0
        self.mode_history.append((t_us, mode))
        self._say(f"Mode {mode.name}")

    # ------------------------------------------------------------------ mode entry
    def enter_takeoff(self, state: VehicleState, alt_rel_m: float) -> None:
        self.takeoff.start(state, self.home_down_m(), alt_rel_m, self.hold)
        self._set_mode(FlightMode.AUTO_TAKEOFF)

    def enter_land(self, state: VehicleState, ne: tuple[float, float] | None = None) -> None:
        self.land.start(state, ne)
        self._set_mode(FlightMode.AUTO_LAND)

    def _enter_rtl(self, state: VehicleState) -> None:
        self.rtl.start(state, self.home_down_m(), self.params)
        self._set_mode(FlightMode.AUTO_RTL)

    def _enter_hold(self, state: VehicleState, mode: FlightMode = FlightMode.AUTO_LOITER) -> None:
        self.hold.hold_here(state, self.params.get("MPC_ACC_HOR"))
        self._set_mode(mode)

    def request_mode(self, mode: FlightMode) -> CommandResult:
        """Switch mode (DO_SET_MODE, failsafes, mission RTL/LAND items); refusal reason in last_reason."""
        state = self._state
        if mode not in _SUPPORTED_MODES:
            return self._refuse(CommandResult.DENIED, f"mode {mode.name} is not supported (no RC input)")
        if state is None:
            return self._refuse(CommandResult.TEMPORARILY_REJECTED, "no vehicle state yet")
        if mode is self.mode:
            return CommandResult.ACCEPTED
        if mode is FlightMode.AUTO_RTL:
            if self.home is None:
                return self._refuse(CommandResult.DENIED, "RTL: no home position (arm first)")
            if not (self.armed and self.in_air):
                return self._refuse(CommandResult.DENIED, "RTL: not flying")
            self._enter_rtl(state)
        elif mode is FlightMode.AUTO_LAND:
            if not (self.armed and self.in_air):
                return self._refuse(CommandResult.DENIED, "LAND: not flying")
            self.enter_land(state)
        elif mode is FlightMode.AUTO_TAKEOFF:
            self.enter_takeoff(state, self.params.get("MIS_TAKEOFF_ALT"))
        elif mode is FlightMode.AUTO_MISSION:
            if not self.context.mission_ready:
                return self._refuse(CommandResult.DENIED, "MISSION: no valid mission uploaded")
            self._mission_target = None
            self._set_mode(mode)
        elif mode is FlightMode.OFFBOARD:
            if self.offboard.setpoint is None or not self.context.offboard_streaming:
                return self._refuse(CommandResult.DENIED, "OFFBOARD: stream setpoints first")
            self._set_mode(mode)
        else:
            self._enter_hold(state, mode)
        return CommandResult.ACCEPTED

    # ------------------------------------------------------------------ arming
    def arming_refusal(self, state: VehicleState | None) -> str | None:
        """Why arming is refused now, or None (checks: estimate, GPS 3D fix, on ground, failsafe, mode)."""
        status = self.context.estimator_status
        if state is None or not state.valid:
            return (
                f"estimator not ready ({status.reason})"
                if status is not None and status.reason
                else "estimator not ready"
            )
        need_gps = self.params.get("COM_ARM_WO_GPS") < 0.5
        if state.gps_fix_type < 3 and need_gps:
            return "no 3D GPS fix"
        if status is not None and not self.armed and (not status.aligned or (need_gps and not status.healthy)):
            return f"estimator: {status.reason}"
        if self.in_air:
            return "not on the ground"
        if self.context.failsafe_reasons:
            return f"failsafe active ({', '.join(sorted(self.context.failsafe_reasons))})"
        if self.mode not in _ARMABLE_MODES:
            return f"cannot arm in mode {self.mode.name}"
        if self.mode is FlightMode.AUTO_MISSION and not self.context.mission_ready:
            return "mission mode without a valid mission"
        return None

    def arm(self, force: bool = False) -> CommandResult:
        state = self._state
        if self.armed:
            return CommandResult.ACCEPTED
        if state is None:
            return self._refuse(CommandResult.TEMPORARILY_REJECTED, "Arming denied: no vehicle state yet")
        reason = None if force else self.arming_refusal(state)
        if reason is not None:
            return self._refuse(CommandResult.DENIED, f"Arming denied: {reason}")
        self.armed = True
        self._armed_at_us = state.time_us
        self._touchdown_us = None
        self._set_home(state)
        if self.mode is FlightMode.AUTO_TAKEOFF:  # takeoff requested before arming: climb above the new home
            self.enter_takeoff(state, self.takeoff.alt_rel_m)
        elif self.mode in (FlightMode.AUTO_LOITER, FlightMode.POSCTL):
            self.hold.pos_ned_m = state.pos_ned_m
        self._say("Armed" + (" (forced)" if force else ""))
        return CommandResult.ACCEPTED

    def _set_home(self, state: VehicleState) -> None:
        self.home = Home(state.pos_ned_m, GeoPoint(state.lat_deg, state.lon_deg, state.alt_amsl_m), state.yaw_rad)

    def disarm(self, force: bool = False, reason: str = "") -> CommandResult:
        if not self.armed:
            return CommandResult.ACCEPTED
        if self.in_air and not force:
            return self._refuse(CommandResult.DENIED, "Disarming denied: in air (force with 21196)")
        self.armed = False
        self._say("Disarmed" + (f" ({reason})" if reason else ""))
        if self.in_air:  # forced in the air: motors stop, the vehicle falls
            self.landed_state = LandedState.IN_AIR
        if self.mode in (FlightMode.AUTO_LAND, FlightMode.AUTO_RTL, FlightMode.AUTO_TAKEOFF):
            self._set_mode(FlightMode.AUTO_LOITER)
        return CommandResult.ACCEPTED

    # ------------------------------------------------------------------ inputs from the runner
    def goto(self, state: VehicleState, pos_ned_m: Vec3, yaw_rad: float = math.nan) -> None:
        """Fly to a point and hold it there (DO_REPOSITION): HOLD mode with a new hold point."""
        self.hold.pos_ned_m = pos_ned_m
        self.hold.yaw_rad = yaw_rad if not math.isnan(yaw_rad) else face_yaw(self.params, state, pos_ned_m)
        self._set_mode(FlightMode.AUTO_LOITER)

    def set_speed_xy(self, speed_m_s: float | None) -> None:
        """Cruise speed override (DO_CHANGE_SPEED, mission speed items); None = MIS_CRUISE_SPD."""
        self._speed_xy_m_s = speed_m_s

    def set_gripper(self, release: bool) -> None:
        if release != self.gripper_release:
            self._say("Payload released" if release else "Gripper closed")
        self.gripper_release = release

    def set_offboard_target(self, pos_ned_m: Vec3, yaw_rad: float = math.nan) -> None:
        """An external position setpoint (SET_POSITION_TARGET_LOCAL_NED); used in OFFBOARD."""
        self.offboard.set_position(pos_ned_m, yaw_rad, self._speeds())

    def set_offboard_velocity(
        self, vel_m_s: Vec3, yaw_rad: float = math.nan, yaw_rate_rad_s: float = math.nan, *, body: bool = False
    ) -> None:
        """An external velocity setpoint (m/s, NED; with ``body`` forward/right/down about the heading; a yaw,
        else a yaw rate, NaN = keep the heading); used in OFFBOARD, within the speed limits in force."""
        self.offboard.set_velocity(vel_m_s, yaw_rad, yaw_rate_rad_s, body, self._speeds())

    def set_manual_input(self, sticks: ManualInput) -> None:
        """The latest joystick input (MANUAL_CONTROL); flown in POSCTL while ``manual_fresh``."""
        self.sticks.sticks = sticks

    def apply_failsafe(self, event: FailsafeEvent) -> None:
        """React to a failsafe that just triggered (action from its parameter) or cleared. A position loss lands
        without horizontal position control until a cleared POSITION_LOSS gives it back (land where it is)."""
        if event.cleared:
            self._say(event.message, Severity.NOTICE)
            if event.kind is FailsafeKind.POSITION_LOSS and self.land.blind and self._state is not None:
                self.land.blind = False
                self.land.ne = (self._state.pos_ned_m[0], self._state.pos_ned_m[1])
            return
        self._say(event.message, Severity.CRITICAL if event.action >= FailsafeAction.HOLD else Severity.WARNING)
        if not (self.armed and self.in_air) or event.action <= FailsafeAction.WARN or self._state is None:
            return
        if event.kind is FailsafeKind.POSITION_LOSS:
            self.enter_land(self._state)
            self.land.blind = True
            return
        no_way_home = event.kind is FailsafeKind.NO_ROUTE and self.mode is FlightMode.AUTO_RTL  # land, not RTL again
        if event.action is FailsafeAction.RTL and self.home is not None and not no_way_home:
            self.request_mode(FlightMode.AUTO_RTL)
        elif event.action in (FailsafeAction.RTL, FailsafeAction.LAND):
            self.request_mode(FlightMode.AUTO_LAND)
        elif self.mode is not FlightMode.AUTO_LAND:
            self._enter_hold(self._state)

    # ------------------------------------------------------------------ per step
    def _speeds(self) -> tuple[float, float, float]:
        """(xy cruise, climb, descent) speeds in force; cached while the parameters and the override are unchanged."""
        key = (self.params.version, self._speed_xy_m_s)
        if key != self._speeds_key:
            p = self.params.get
            self._speeds_key = key
            self._speeds_m_s = (self.speed_xy_m_s, p("MPC_Z_VEL_MAX_UP"), p("MPC_Z_VEL_MAX_DN"))
        return self._speeds_m_s

    def mission_land_speed_m_s(self) -> float:
        """The descent speed of a mission LAND at the latest state (MPC_LAND_SPEED before any: the vehicle is
        then taken to be at home's height, below MPC_LAND_ALT2)."""
        state = self._state
        return self.land_speed_m_s(state) if state is not None else self.params.get("MPC_LAND_SPEED")

    def land_speed_m_s(self, state: VehicleState) -> float:
        """Descent speed of a landing: MPC_LAND_SPEED below MPC_LAND_ALT2 above home, else MPC_Z_VEL_MAX_DN."""
        return land_speed_m_s(self.params, self.alt_rel_home_m(state))

    def _land_target(self, state: VehicleState) -> NavTarget:
        return self.land.target(state, self.params, self.land_speed_m_s(state), self.speed_xy_m_s)

    def _mode_target(self, state: VehicleState) -> NavTarget:
        """The target of the current mode's flight task, as if airborne."""
        mode = self.mode
        if mode is FlightMode.AUTO_TAKEOFF:
            if self.takeoff.reached(state, self.params) and self.in_air:
                self._say("Takeoff complete")
                self._set_mode(FlightMode.AUTO_LOITER)
            else:
                return self.takeoff.target(self.hold, self.params, self.speed_xy_m_s)
        if mode is FlightMode.AUTO_LAND:
            if self.land.blind:  # no horizontal position: brake and descend level (a DESCEND target)
                return self.land.descend_target(self.params, self.land_speed_m_s(state), self.speed_xy_m_s)
            return self._land_target(state)
        if mode is FlightMode.AUTO_RTL:
            home = self.home
            assert home is not None  # RTL is entered only with a home
            routed = self._mission_target.pos_ned_m if self._mission_target is not None else None  # the navigator's
            target = self.rtl.target(state, home.pos_ned_m, self.params, self._speeds(), self.hold, self.land, routed)
            return target if target is not None else self._land_target(state)
        if mode is FlightMode.AUTO_MISSION and self._mission_target is not None:
            return self._mission_target
        if mode is FlightMode.OFFBOARD:
            offboard_target = self.offboard.target(state)
            if offboard_target is not None:
                return offboard_target
        if mode is FlightMode.POSCTL:
            stick_target = self.sticks.target(state, self.context.manual_fresh, self.params, self._speeds, self.hold)
            if stick_target is not None:
                return stick_target
        return self.hold.target(self._speeds())

    def _auto_disarm_on_ground(self, state: VehicleState) -> None:
        """COM_DISARM_LAND after a touchdown, COM_DISARM_PRFLT after arming without takeoff."""
        p = self.params.get
        if self._touchdown_us is not None:
            delay_s, since_us, why = p("COM_DISARM_LAND"), self._touchdown_us, "landed"
        else:
            delay_s, since_us, why = p("COM_DISARM_PRFLT"), self._armed_at_us, "no takeoff"
        if delay_s >= 0.0 and state.time_us - since_us >= delay_s * 1e6:
            self.disarm(reason=why)

    def observe(self, state: VehicleState) -> None:
        """The latest estimate between updates: commands are judged and stamped on it (the runner calls this every
        step; :meth:`update` runs at the navigation rate)."""
        self._state = state

    def update(self, inputs: CommanderInputs) -> NavTarget:
        """Advance the state machine one step on ``inputs`` (see :class:`CommanderInputs`)."""
        state, thrust_ratio = inputs.state, inputs.thrust_ratio
        self._state = state
        self.local_frame = inputs.local_frame
        self.context = inputs.context
        self._mission_target = inputs.mission_target
        if self.local_frame is None:
            return NavTarget(TargetKind.IDLE)
        if self.home is None and state.valid and state.gps_fix_type >= 3:
            self._set_home(state)  # PX4: home at the first 3D fix, moved to where the vehicle arms
        p = self.params.get
        if not self.armed:  # motors off: on the ground unless still falling after a forced disarm
            falling = abs(state.vel_ned_m_s[2]) >= p("LNDMC_Z_VEL_MAX")
            self.landed_state = LandedState.IN_AIR if falling else LandedState.ON_GROUND
            return NavTarget(TargetKind.IDLE)
        if self.landed_state is LandedState.ON_GROUND:
            target = self._mode_target(state)
            if target.kind is TargetKind.VELOCITY:
                takeoff = -target.vel_ned_m_s[2] >= _TAKEOFF_TRIGGER_M_S
            else:
                climb_m = state.pos_ned_m[2] - target.pos_ned_m[2]
                takeoff = target.kind is TargetKind.POSITION and climb_m >= _TAKEOFF_TRIGGER_M
            if not takeoff:
                self._auto_disarm_on_ground(state)
                return NavTarget(TargetKind.IDLE)
            self.landed_state = LandedState.TAKEOFF
            self._touchdown_us = None
            self.land_detector.reset()
            self._say("Takeoff")
            return target
        target = self._mode_target(state)
        if target.kind is TargetKind.LAND or target.kind is TargetKind.DESCEND:
            self.landed_state = LandedState.LANDING
        elif self.landed_state is LandedState.TAKEOFF:
            if self.mode is not FlightMode.AUTO_TAKEOFF and self.alt_rel_home_m(state) > _AIRBORNE_ALT_M:
                self.landed_state = LandedState.IN_AIR
            return target  # no land detection before leaving the ground
        elif self.landed_state is LandedState.LANDING:
            self.landed_state = LandedState.IN_AIR
        if self.land_detector.landed(state, thrust_ratio, blind=self.land.blind):
            self.landed_state = LandedState.ON_GROUND
            self._touchdown_us = state.time_us
            self._say("Landing detected")
            self.hold.pos_ned_m = state.pos_ned_m
            return NavTarget(TargetKind.IDLE)
        return target
