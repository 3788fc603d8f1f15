"""The commander: arming, flight modes, landed state and what the vehicle is asked to do (SPEC §3, §8).

An explicit state machine with no I/O and no clock: the runner feeds it the vehicle state
(sim time inside), decoded GCS commands and failsafe events; it answers each command with
an honest :class:`CommandResult` (and :attr:`Commander.last_reason` when refused) and
produces one :class:`NavTarget` per step for the setpoint generator.

State: ``armed``; ``mode`` (PX4-encoded :class:`FlightMode`); ``landed_state``
(:class:`LandedState`); ``home`` (set at the first 3D GPS fix and again at arming, as PX4
does); ``gripper_release``. Modes:

- AUTO_LOITER (HOLD): hold a point. POSCTL: fly the joystick (MANUAL_CONTROL, :meth:`set_manual_input`) as
  velocities about the heading while it keeps coming (``manual_fresh``, set by the runner); centred sticks or
  no joystick: hold (see :mod:`autopilot.flight_tasks.position_control`).
- AUTO_TAKEOFF: climb to the takeoff altitude above home at ``MPC_TKO_SPEED``, then HOLD.
- AUTO_LAND: descend (``MPC_Z_VEL_MAX_DN``, then ``MPC_LAND_SPEED`` below ``MPC_LAND_ALT2``)
  until the land detector sees touchdown, then auto-disarm after ``COM_DISARM_LAND``. After a position-loss
  failsafe (``FailsafeKind.POSITION_LOSS``) it descends without horizontal position control (a DESCEND
  target: it brakes on its dead-reckoned velocity and descends level; the land detector ignores that
  velocity's horizontal part) until the position comes back.
- AUTO_RTL: climb to ``MIS_RTL_ALT`` (if lower), fly home, wait ``RTL_LAND_DELAY``, land.
- AUTO_MISSION: the target comes from the mission executor (:meth:`set_mission_target`).
- OFFBOARD: the target is the latest external position or velocity setpoint (:meth:`set_offboard_target`,
  :meth:`set_offboard_velocity`); entered only while setpoints stream (PX4's rule: the runner sets
  ``offboard_streaming``); leaving it on a setpoint loss is the failsafe's job (``COM_OBL_ACT``). On the
  ground, a position setpoint above the vehicle or a climbing velocity setpoint takes off.

Land detector (PX4 ``MulticopterLandDetector`` in spirit): vertical speed below
``LNDMC_Z_VEL_MAX``, horizontal speed below ``LNDMC_XY_VEL_MAX`` and collective thrust
below ``LNDMC_LOW_T_THR`` of hover, all for ``LNDMC_TRIG_TIME`` seconds.

Altitudes in commands follow PX4: COMMAND_LONG positional altitudes are AMSL; COMMAND_INT
altitudes are in its ``frame`` (3/6 = relative to home, 0/5 = AMSL); NaN means "default"
(takeoff: ``MIS_TAKEOFF_ALT``; reposition: keep the current altitude).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, replace
from enum import Enum

from autopilot.estimation import EstimatorStatus, VehicleState
from autopilot.flight_tasks.position_control import stick_demand
from autopilot.flight_tasks.setpoints import NavTarget, TargetKind
from autopilot.parameters.store import ParamStore
from autopilot.safety.failsafe import FailsafeAction, FailsafeEvent, FailsafeKind
from autopilot.safety.land_detector import LandDetector
from mavlink_bridge.contract.frames import GeoPoint, LocalNedFrame, ne_from_heading_frame
from mavlink_bridge.contract.mav_enums import MavCmd
from mavlink_bridge.contract.vehicle_api import (
    CommandRequest,
    CommandResult,
    FlightMode,
    LandedState,
    ManualInput,
    Severity,
    StatusText,
)
from mavlink_bridge.contract.wire import Vec3, fast_frozen_init

#: COMPONENT_ARM_DISARM param2 magic that forces arming/disarming (PX4/ArduPilot).
FORCE_MAGIC = 21196.0
#: MAV_MODE_FLAG_CUSTOM_MODE_ENABLED (DO_SET_MODE param1).
_CUSTOM_MODE_ENABLED = 1
#: An armed vehicle on the ground takes off when its target is this far above it (m).
_TAKEOFF_TRIGGER_M = 0.5
#: On the ground in OFFBOARD, a velocity setpoint climbing at least this fast takes off (m/s).
_TAKEOFF_TRIGGER_M_S = 0.3
#: POSCTL: after the sticks let go, the vehicle holds where it is once slower than this on each axis (m/s) ...
_STICK_STOPPED_M_S = 0.2
#: ... or after braking this long (sim µs), whichever comes first.
_STICK_BRAKE_MAX_US = 5_000_000
#: The position of a target that has none (VELOCITY).
_NO_POSITION = (math.nan, math.nan, math.nan)
#: Face the target only when it is at least this far away horizontally (m).
_FACE_TARGET_MIN_M = 2.0
#: Outside AUTO_TAKEOFF, a climbing vehicle counts as in the air above this height over home (m).
_AIRBORNE_ALT_M = 1.0
_RELATIVE_ALT_FRAMES = frozenset({3, 6, 11})
#: A command handled outside the commander (e.g. MAV_CMD_INJECT_FAILURE): (result, reason when refused).
CommandHandler = Callable[[CommandRequest], tuple[CommandResult, str]]


_ARMABLE_MODES = frozenset(
    {FlightMode.POSCTL, FlightMode.AUTO_LOITER, FlightMode.AUTO_TAKEOFF, FlightMode.AUTO_MISSION, FlightMode.OFFBOARD}
)
_SUPPORTED_MODES = _ARMABLE_MODES | {FlightMode.AUTO_LAND, FlightMode.AUTO_RTL}


class RtlPhase(Enum):
    """Where an RTL is."""

    CLIMB = "climb"
    RETURN = "return"
    LOITER = "loiter"
    LAND = "land"


@fast_frozen_init
@dataclass(frozen=True, slots=True)
class Home:
    """The home position: where the vehicle was armed (local NED about the origin, and geodetic)."""

    pos_ned_m: Vec3
    geo: GeoPoint
    yaw_rad: float


def _velocity_target(
    vel_ned_m_s: Vec3,
    speeds: tuple[float, float, float],
    yaw_rad: float = math.nan,
    yaw_rate_rad_s: float = math.nan,
) -> NavTarget:
    """A VELOCITY target (it has no position) within ``speeds`` (xy, up, down)."""
    return NavTarget(TargetKind.VELOCITY, _NO_POSITION, yaw_rad, *speeds, vel_ned_m_s, yaw_rate_rad_s)


@dataclass(frozen=True, slots=True)
class CommandContext:
    """What the commander needs from outside to judge commands and modes (the runner builds it on change)."""

    mission_ready: bool = False  # a valid mission is loaded
    offboard_streaming: bool = False  # offboard setpoints arrived within COM_OF_LOSS_T
    manual_fresh: bool = False  # joystick input arrived within COM_RC_LOSS_T
    failsafe_reasons: frozenset[str] = frozenset()  # the failsafes in force (arming is refused meanwhile)
    estimator_status: EstimatorStatus | None = None  # arming waits until it is aligned and healthy (None: unchecked)


@fast_frozen_init
@dataclass(frozen=True, slots=True)
class CommanderInputs:
    """Everything the commander reads at one step: the estimate, the last thrust, the estimator's local frame,
    the :class:`CommandContext` and, in AUTO_MISSION, the navigator's target (about the origin)."""

    state: VehicleState
    thrust_ratio: float  # last collective thrust / hover thrust (land detector)
    local_frame: LocalNedFrame | None
    context: CommandContext
    mission_target: NavTarget | None = None


class Commander:
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
        self._hold_ned: Vec3 = (0.0, 0.0, 0.0)
        self._hold_yaw = math.nan
        self._hold_key: tuple[object, ...] = ()
        self._hold_target = NavTarget(TargetKind.IDLE)
        self._goto_ned: Vec3 = (0.0, 0.0, 0.0)
        self._goto_yaw = math.nan
        self._takeoff_down_m = 0.0
        self._takeoff_alt_rel_m = 0.0
        self._land_ne: tuple[float, float] = (0.0, 0.0)
        self._land_key: tuple[object, ...] = ()
        self._land_nav: NavTarget | None = None
        self._land_blind = False  # AUTO_LAND without a horizontal position (position-loss failsafe)
        self._descend_nav: NavTarget | None = None
        self._descend_version = -1
        self._rtl_phase = RtlPhase.CLIMB
        self._rtl_down_m = 0.0
        self._rtl_loiter_until_us = 0
        self._speed_xy_m_s: float | None = None  # DO_CHANGE_SPEED override
        self._speeds_key: tuple[int, float | None] = (-1, None)  # _speeds() cache
        self._speeds_m_s = (0.0, 0.0, 0.0)
        self.land_detector = LandDetector(params)
        self._mission_target: NavTarget | None = None
        self._offboard_target: NavTarget | None = None
        self._offboard_body_vel: Vec3 | None = None  # a body-frame velocity setpoint, turned every step
        self._sticks: ManualInput | None = None
        self._sticks_flying = False  # POSCTL flies the sticks, or brakes after them (not yet holding)
        self._stick_brake_since_us: int | None = None
        self._touchdown_us: int | None = None
        self._armed_at_us = 0

    # ------------------------------------------------------------------ helpers
    def drain_texts(self) -> list[StatusText]:
        """STATUSTEXT events since the last call."""
        out, self._texts = self._texts, []
        return out

    def _say(self, text: str, severity: Severity = Severity.INFO) -> None:
        self._texts.append(StatusText(severity, text))

    def _refuse(self, result: CommandResult, reason: str) -> CommandResult:
        self.last_reason = reason
        self._say(reason, Severity.WARNING)
        return result

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

    def _home_down_m(self) -> float:
        """Down of home; before arming, of the vehicle (where home will be)."""
        if self.home is not None:
            return self.home.pos_ned_m[2]
        return self._state.pos_ned_m[2] if self._state is not None else 0.0

    def alt_rel_home_m(self, state: VehicleState) -> float:
        return self._home_down_m() - state.pos_ned_m[2]

    def _set_mode(self, mode: FlightMode) -> None:
        if mode is self.mode:
            return
        self.mode = mode
        self._land_blind = self._land_blind and mode is FlightMode.AUTO_LAND
        t_us = self._state.time_us if self._state is not None else 0
        self.mode_history.append((t_us, mode))
        self._say(f"Mode {mode.name}")

    def _hold_here(self, state: VehicleState) -> None:
        """Hold where the vehicle can stop: its position plus the braking distance at MPC_ACC_HOR."""
        acc = self.params.get("MPC_ACC_HOR")
        vn, ve, _ = state.vel_ned_m_s
        speed = math.hypot(vn, ve)
        k = speed / (2.0 * acc)
        n, e, d = state.pos_ned_m
        self._hold_ned = (n + vn * k, e + ve * k, d)
        self._hold_yaw = math.nan

    def _face(self, state: VehicleState, target_ned: Vec3) -> float:
        if self.params.get("MPC_YAW_MODE") >= 0.5:
            return math.nan
        dn, de = target_ned[0] - state.pos_ned_m[0], target_ned[1] - state.pos_ned_m[1]
        return math.atan2(de, dn) if math.hypot(dn, de) >= _FACE_TARGET_MIN_M else math.nan

    def _down_from_alt(self, alt_m: float, request: CommandRequest) -> float:
        """Local down (m) of a command altitude (see the module docstring for frames)."""
        if request.is_int and request.frame in _RELATIVE_ALT_FRAMES:
            return self._home_down_m() - alt_m
        origin_alt = self.local_frame.home.alt_amsl_m if self.local_frame is not None else 0.0
        return origin_alt - alt_m

    def _ne_from_latlon(self, lat_deg: float, lon_deg: float, state: VehicleState) -> tuple[float, float] | None:
        """Local NE (m) of lat/lon in degrees; NaN (or 0/0 for COMMAND_LONG) = the current position."""
        if math.isnan(lat_deg) or math.isnan(lon_deg) or (lat_deg == 0.0 and lon_deg == 0.0):
            return state.pos_ned_m[0], state.pos_ned_m[1]
        if self.local_frame is None or not (-90.0 <= lat_deg <= 90.0 and -180.0 <= lon_deg <= 180.0):
            return None
        n, e, _ = self.local_frame.ned_from_geodetic(lat_deg, lon_deg, self.local_frame.home.alt_amsl_m)
        return n, e

    # ------------------------------------------------------------------ mode entry
    def _enter_takeoff(self, state: VehicleState, alt_rel_m: float) -> None:
        self._takeoff_alt_rel_m = alt_rel_m
        self._takeoff_down_m = self._home_down_m() - alt_rel_m
        self._hold_ned = (state.pos_ned_m[0], state.pos_ned_m[1], self._takeoff_down_m)
        self._hold_yaw = math.nan
        self._set_mode(FlightMode.AUTO_TAKEOFF)

    def _enter_land(self, state: VehicleState, ne: tuple[float, float] | None = None) -> None:
        self._land_ne = ne if ne is not None else (state.pos_ned_m[0], state.pos_ned_m[1])
        self._set_mode(FlightMode.AUTO_LAND)

    def _enter_rtl(self, state: VehicleState) -> None:
        self._rtl_phase = RtlPhase.CLIMB
        self._rtl_down_m = min(state.pos_ned_m[2], self._home_down_m() - self.params.get("MIS_RTL_ALT"))
        self._set_mode(FlightMode.AUTO_RTL)

    def _enter_hold(self, state: VehicleState, mode: FlightMode = FlightMode.AUTO_LOITER) -> None:
        self._hold_here(state)
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
            self._enter_land(state)
        elif mode is FlightMode.AUTO_TAKEOFF:
            self._enter_takeoff(state, self.params.get("MIS_TAKEOFF_ALT"))
        elif mode is FlightMode.AUTO_MISSION:
            if not self.context.mission_ready:
                return self._refuse(CommandResult.DENIED, "MISSION: no valid mission uploaded")
            self._mission_target = None
            self._set_mode(mode)
        elif mode is FlightMode.OFFBOARD:
            if self._offboard_target is None or not self.context.offboard_streaming:
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
            self._enter_takeoff(state, self._takeoff_alt_rel_m)
        elif self.mode in (FlightMode.AUTO_LOITER, FlightMode.POSCTL):
            self._hold_ned = state.pos_ned_m
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

    # ------------------------------------------------------------------ commands
    def handle_command(self, request: CommandRequest, context: CommandContext | None = None) -> CommandResult:
        """Execute one COMMAND_LONG/COMMAND_INT (judged with ``context`` when given: it is fresher than the last
        step's); ``last_reason`` says why when not ACCEPTED."""
        if context is not None:
            self.context = context
        self.last_reason = ""
        p = request.params
        if any(math.isinf(v) for v in p):
            return self._refuse(CommandResult.DENIED, "command parameter is infinite")
        cmd = request.command
        state = self._state
        if cmd == MavCmd.COMPONENT_ARM_DISARM:
            force = p[1] == FORCE_MAGIC
            if p[0] == 1.0:
                return self.arm(force)
            if p[0] == 0.0:
                return self.disarm(force)
            return self._refuse(CommandResult.DENIED, f"ARM_DISARM param1 must be 0 or 1, got {p[0]:g}")
        handler = self.command_handlers.get(cmd)
        if handler is not None:
            result, reason = handler(request)
            return result if result is CommandResult.ACCEPTED else self._refuse(result, reason)
        if state is None:
            return self._refuse(CommandResult.TEMPORARILY_REJECTED, "no vehicle state yet")
        if cmd == MavCmd.NAV_TAKEOFF:
            return self._cmd_takeoff(request, state)
        if cmd == MavCmd.NAV_LAND:
            if not (self.armed and self.in_air):
                return self._refuse(CommandResult.DENIED, "LAND: not flying")
            ne = self._ne_from_latlon(p[4], p[5], state)
            if ne is None:
                return self._refuse(CommandResult.DENIED, "LAND: latitude/longitude out of range")
            self._enter_land(state, ne)
            return CommandResult.ACCEPTED
        if cmd == MavCmd.NAV_RETURN_TO_LAUNCH:
            return self.request_mode(FlightMode.AUTO_RTL)
        if cmd == MavCmd.MISSION_START:
            return self.request_mode(FlightMode.AUTO_MISSION)
        if cmd == MavCmd.DO_SET_MODE:
            return self._cmd_set_mode(p)
        if cmd == MavCmd.DO_CHANGE_SPEED:
            return self._cmd_change_speed(p)
        if cmd == MavCmd.DO_GRIPPER:
            if p[1] not in (0.0, 1.0):
                return self._refuse(CommandResult.DENIED, f"GRIPPER: action must be 0 release or 1 grab, not {p[1]:g}")
            self.set_gripper(release=p[1] == 0.0)
            return CommandResult.ACCEPTED
        if cmd == MavCmd.DO_REPOSITION:
            return self._cmd_reposition(request, state)
        return self._refuse(CommandResult.UNSUPPORTED, f"command {cmd} is not supported")

    def _cmd_takeoff(self, request: CommandRequest, state: VehicleState) -> CommandResult:
        alt = request.params[6]
        if self.in_air and not self.armed:
            return self._refuse(CommandResult.DENIED, "TAKEOFF: disarmed in the air")
        if math.isnan(alt):
            alt_rel = self.params.get("MIS_TAKEOFF_ALT")
        else:
            alt_rel = self._home_down_m() - self._down_from_alt(alt, request)
        spec = self.params.specs["MIS_TAKEOFF_ALT"]
        if not (spec.min <= alt_rel <= spec.max):
            return self._refuse(
                CommandResult.DENIED,
                f"TAKEOFF: {alt_rel:.1f} m above home is outside [{spec.min:g}, {spec.max:g}] m "
                "(COMMAND_LONG param7 is AMSL; send NaN for MIS_TAKEOFF_ALT)",
            )
        self._enter_takeoff(state, alt_rel)
        return CommandResult.ACCEPTED

    def _cmd_set_mode(self, p: tuple[float, ...]) -> CommandResult:
        if not int(p[0]) & _CUSTOM_MODE_ENABLED:
            return self._refuse(CommandResult.DENIED, "DO_SET_MODE: only PX4 custom modes are supported")
        try:
            mode = FlightMode.from_px4(int(p[1]), int(p[2]))
        except ValueError:
            return self._refuse(CommandResult.DENIED, f"DO_SET_MODE: unknown PX4 mode {int(p[1])}/{int(p[2])}")
        return self.request_mode(mode)

    def _cmd_change_speed(self, p: tuple[float, ...]) -> CommandResult:
        speed_type, speed = int(p[0]), p[1]
        if speed == -1.0:
            return CommandResult.ACCEPTED
        if speed == -2.0:
            self._speed_xy_m_s = None
            return CommandResult.ACCEPTED
        if speed_type not in (0, 1):
            return self._refuse(CommandResult.UNSUPPORTED, f"DO_CHANGE_SPEED: speed type {speed_type} not supported")
        vmax = self.params.get("MPC_XY_VEL_MAX")
        if not (0.0 < speed <= vmax):
            return self._refuse(CommandResult.DENIED, f"DO_CHANGE_SPEED: {speed:g} m/s outside (0, {vmax:g}]")
        self.set_speed_xy(speed)
        return CommandResult.ACCEPTED

    def _cmd_reposition(self, request: CommandRequest, state: VehicleState) -> CommandResult:
        p = request.params
        if not (self.armed and self.in_air):
            return self._refuse(CommandResult.TEMPORARILY_REJECTED, "REPOSITION: take off first")
        ne = self._ne_from_latlon(p[4], p[5], state)
        if ne is None:
            return self._refuse(CommandResult.DENIED, "REPOSITION: latitude/longitude out of range")
        down = state.pos_ned_m[2] if math.isnan(p[6]) else self._down_from_alt(p[6], request)
        if self._home_down_m() - down < 0.0:
            return self._refuse(CommandResult.DENIED, "REPOSITION: altitude below home")
        if p[0] > 0.0:
            vmax = self.params.get("MPC_XY_VEL_MAX")
            if p[0] > vmax:
                return self._refuse(CommandResult.DENIED, f"REPOSITION: speed {p[0]:g} m/s above {vmax:g}")
            self._speed_xy_m_s = p[0]
        self.goto(state, (ne[0], ne[1], down), math.nan if math.isnan(p[3]) else math.radians(p[3]))
        return CommandResult.ACCEPTED

    # ------------------------------------------------------------------ inputs from the runner
    def goto(self, state: VehicleState, pos_ned_m: Vec3, yaw_rad: float = math.nan) -> None:
        """Fly to a point and hold it there (DO_REPOSITION): HOLD mode with a new hold point."""
        self._hold_ned = pos_ned_m
        self._hold_yaw = yaw_rad if not math.isnan(yaw_rad) else self._face(state, pos_ned_m)
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
        self._offboard_target = NavTarget(TargetKind.POSITION, pos_ned_m, yaw_rad, *self._speeds())
        self._offboard_body_vel = None

    def set_offboard_velocity(
        self, vel_m_s: Vec3, yaw_rad: float = math.nan, yaw_rate_rad_s: float = math.nan, *, body: bool = False
    ) -> None:
        """An external velocity setpoint (m/s, NED; with ``body`` forward/right/down about the heading; a yaw,
        else a yaw rate, NaN = keep the heading); used in OFFBOARD, within the speed limits in force.

        A body-frame velocity is turned with the heading of every control step: at ``--speed max`` a client's
        20 Hz (wall clock) stream can be several tenths of a second of sim time apart, and turned once on
        receipt (as PX4 does in real time) the course would lag a turning heading by that much.
        """
        ned = (0.0, 0.0, vel_m_s[2]) if body else vel_m_s
        self._offboard_target = _velocity_target(ned, self._speeds(), yaw_rad, yaw_rate_rad_s)
        self._offboard_body_vel = vel_m_s if body else None

    @staticmethod
    def _body_velocity_target(state: VehicleState, target: NavTarget, vel_frd_m_s: Vec3) -> NavTarget:
        """``target`` with its velocity ``vel_frd_m_s`` (forward, right, down about the heading) in NED now."""
        forward, right, down = vel_frd_m_s
        north, east = ne_from_heading_frame(forward, right, state.yaw_rad) if state.valid else (0.0, 0.0)
        return replace(target, vel_ned_m_s=(north, east, down))  # no heading (invalid state): stop horizontally

    def set_manual_input(self, sticks: ManualInput) -> None:
        """The latest joystick input (MANUAL_CONTROL); flown in POSCTL while ``manual_fresh``."""
        self._sticks = sticks

    def _stick_target(self, state: VehicleState) -> NavTarget | None:
        """POSCTL: the sticks' velocity target, or None to hold. When the sticks let go (centred, or stale) the
        vehicle brakes to a stop (a zero velocity target) and then holds where it stopped, as PX4 does: no
        overshoot and return to a precomputed point."""
        sticks = self._sticks
        demand = None
        if sticks is not None and self.context.manual_fresh and state.valid:
            demand = stick_demand(sticks, state.yaw_rad, self.params)
        if demand is not None:
            self._sticks_flying = True
            self._stick_brake_since_us = None
            speeds = (demand.speed_xy_m_s, demand.speed_up_m_s, demand.speed_down_m_s)
            return _velocity_target(demand.vel_ned_m_s, speeds, yaw_rate_rad_s=demand.yaw_rate_rad_s)
        if not self._sticks_flying:
            return None
        if self._stick_brake_since_us is None:
            self._stick_brake_since_us = state.time_us
        vn, ve, vd = state.vel_ned_m_s
        slow = math.hypot(vn, ve) < _STICK_STOPPED_M_S and abs(vd) < _STICK_STOPPED_M_S
        if slow or state.time_us - self._stick_brake_since_us >= _STICK_BRAKE_MAX_US:
            self._sticks_flying = False
            self._hold_ned, self._hold_yaw = state.pos_ned_m, math.nan
            return None
        return _velocity_target((0.0, 0.0, 0.0), self._speeds())

    def apply_failsafe(self, event: FailsafeEvent) -> None:
        """React to a failsafe that just triggered (action from its parameter) or cleared. A position loss lands
        without horizontal position control until a cleared POSITION_LOSS gives it back (land where it is)."""
        if event.cleared:
            self._say(event.message, Severity.NOTICE)
            if event.kind is FailsafeKind.POSITION_LOSS and self._land_blind and self._state is not None:
                self._land_blind = False
                self._land_ne = (self._state.pos_ned_m[0], self._state.pos_ned_m[1])
            return
        self._say(event.message, Severity.CRITICAL if event.action >= FailsafeAction.HOLD else Severity.WARNING)
        if not (self.armed and self.in_air) or event.action <= FailsafeAction.WARN or self._state is None:
            return
        if event.kind is FailsafeKind.POSITION_LOSS:
            self._enter_land(self._state)
            self._land_blind = True
            return
        if event.action is FailsafeAction.RTL and self.home is not None:
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
        p = self.params.get
        return p("MPC_LAND_SPEED") if self.alt_rel_home_m(state) < p("MPC_LAND_ALT2") else p("MPC_Z_VEL_MAX_DN")

    def _land_target(self, state: VehicleState) -> NavTarget:
        """LAND over ``_land_ne``; one object while the spot, the speeds and the parameters stay (so the setpoint
        generator's prepared step applies). Its down is the vehicle's when it was made: LAND holds only the xy."""
        speed_dn, speed_xy = self.land_speed_m_s(state), self.speed_xy_m_s
        key = (self._land_ne, speed_dn, speed_xy, self.params.version)
        nav = self._land_nav
        if nav is None or key != self._land_key:
            self._land_key = key
            pos = (self._land_ne[0], self._land_ne[1], state.pos_ned_m[2])
            nav = self._land_nav = NavTarget(
                TargetKind.LAND, pos, math.nan, speed_xy, self.params.get("MPC_Z_VEL_MAX_UP"), speed_dn
            )
        return nav

    def _descend_target(self, state: VehicleState) -> NavTarget:
        """DESCEND (position lost): stop and descend at the land speeds; one object while they and the parameters
        stay (no allocation per step)."""
        speed_dn = self.land_speed_m_s(state)
        nav = self._descend_nav
        if nav is None or nav.speed_down_m_s != speed_dn or self._descend_version != self.params.version:
            self._descend_version = self.params.version
            speeds = (self.speed_xy_m_s, self.params.get("MPC_Z_VEL_MAX_UP"), speed_dn)
            nav = self._descend_nav = NavTarget(TargetKind.DESCEND, _NO_POSITION, math.nan, *speeds)
        return nav

    def _mode_target(self, state: VehicleState) -> NavTarget:
        """The target of the current mode, as if airborne."""
        p = self.params.get
        mode = self.mode
        if mode is FlightMode.AUTO_TAKEOFF:
            if abs(state.pos_ned_m[2] - self._takeoff_down_m) < p("MIS_ALT_ACC_RAD") and self.in_air:
                self._say("Takeoff complete")
                self._set_mode(FlightMode.AUTO_LOITER)
            else:
                vxy = self.speed_xy_m_s
                return NavTarget(TargetKind.POSITION, self._hold_ned, math.nan, vxy, p("MPC_TKO_SPEED"), vxy)
        if mode is FlightMode.AUTO_LAND:
            if (
                self._land_blind
            ):  # no horizontal position: brake and descend level (autopilot.flight_tasks.setpoints DESCEND)
                return self._descend_target(state)
            return self._land_target(state)
        if mode is FlightMode.AUTO_RTL:
            return self._rtl_target(state)
        if mode is FlightMode.AUTO_MISSION and self._mission_target is not None:
            return self._mission_target
        if mode is FlightMode.OFFBOARD and self._offboard_target is not None:
            if self._offboard_body_vel is not None:
                return self._body_velocity_target(state, self._offboard_target, self._offboard_body_vel)
            return self._offboard_target
        if mode is FlightMode.POSCTL:
            stick_target = self._stick_target(state)
            if stick_target is not None:
                return stick_target
        key = (self._hold_ned, self._hold_yaw, *self._speeds())
        if key != self._hold_key:  # the same hold target every step while nothing changes: build it once
            self._hold_key = key
            self._hold_target = NavTarget(TargetKind.POSITION, *key)
        return self._hold_target

    def _rtl_target(self, state: VehicleState) -> NavTarget:
        p = self.params.get
        home = self.home
        assert home is not None  # RTL is entered only with a home
        n, e, d = state.pos_ned_m
        if self._rtl_phase is RtlPhase.CLIMB:
            if d - self._rtl_down_m < p("MIS_ALT_ACC_RAD"):
                self._rtl_phase = RtlPhase.RETURN
                self._goto_ned = (home.pos_ned_m[0], home.pos_ned_m[1], self._rtl_down_m)
                self._goto_yaw = self._face(state, self._goto_ned)
            else:
                self._hold_ned = (n, e, self._rtl_down_m)
                return NavTarget(TargetKind.POSITION, self._hold_ned, math.nan, *self._speeds())
        if self._rtl_phase is RtlPhase.RETURN:
            if math.hypot(n - home.pos_ned_m[0], e - home.pos_ned_m[1]) < p("MIS_ACC_RAD"):
                self._rtl_phase = RtlPhase.LOITER
                self._rtl_loiter_until_us = state.time_us + int(p("RTL_LAND_DELAY") * 1e6)
            else:
                return NavTarget(TargetKind.POSITION, self._goto_ned, self._goto_yaw, *self._speeds())
        if self._rtl_phase is RtlPhase.LOITER:
            if state.time_us >= self._rtl_loiter_until_us:
                self._rtl_phase = RtlPhase.LAND
                self._land_ne = (home.pos_ned_m[0], home.pos_ned_m[1])
            else:
                return NavTarget(TargetKind.POSITION, self._goto_ned, math.nan, *self._speeds())
        return self._land_target(state)

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
        if self.land_detector.landed(state, thrust_ratio, blind=self._land_blind):
            self.landed_state = LandedState.ON_GROUND
            self._touchdown_us = state.time_us
            self._say("Landing detected")
            self._hold_ned = state.pos_ned_m
            return NavTarget(TargetKind.IDLE)
        return target
