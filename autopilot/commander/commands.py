"""The commands a GCS sends the commander (SPEC §8): COMMAND_LONG / COMMAND_INT judged and executed.

Altitudes follow PX4: COMMAND_LONG positional altitudes are AMSL; COMMAND_INT altitudes are in its ``frame``
(3/6 = relative to home, 0/5 = AMSL); NaN means "default" (takeoff: ``MIS_TAKEOFF_ALT``; reposition: keep the
current altitude).
"""

from __future__ import annotations

import math

from autopilot.commander.inputs import CommandContext, CommandHandler
from autopilot.estimation import VehicleState
from autopilot.parameters.store import ParamStore
from mavlink_bridge.contract.frames import LocalNedFrame
from mavlink_bridge.contract.mav_enums import MavCmd
from mavlink_bridge.contract.vehicle_api import CommandRequest, CommandResult, FlightMode, Severity, StatusText

#: COMPONENT_ARM_DISARM param2 magic that forces arming/disarming (PX4/ArduPilot).
FORCE_MAGIC = 21196.0
#: MAV_MODE_FLAG_CUSTOM_MODE_ENABLED (DO_SET_MODE param1).
_CUSTOM_MODE_ENABLED = 1
_RELATIVE_ALT_FRAMES = frozenset({3, 6, 11})


class CommandHandling:
    """The command half of :class:`autopilot.commander.state_machine.Commander` (its base class): decodes each
    command and calls the state machine's transitions (``arm``, ``disarm``, ``request_mode``, ``enter_takeoff``,
    ``enter_land``, ``goto``, ``set_speed_xy``, ``set_gripper``), which the Commander defines; status texts and
    refusals are kept here."""

    params: ParamStore
    armed: bool
    local_frame: LocalNedFrame | None
    context: CommandContext
    last_reason: str
    command_handlers: dict[int, CommandHandler]
    _state: VehicleState | None
    _texts: list[StatusText]

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
            self.enter_land(state, ne)
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
            alt_rel = self.home_down_m() - self._down_from_alt(alt, request)
        spec = self.params.specs["MIS_TAKEOFF_ALT"]
        if not (spec.min <= alt_rel <= spec.max):
            return self._refuse(
                CommandResult.DENIED,
                f"TAKEOFF: {alt_rel:.1f} m above home is outside [{spec.min:g}, {spec.max:g}] m "
                "(COMMAND_LONG param7 is AMSL; send NaN for MIS_TAKEOFF_ALT)",
            )
        self.enter_takeoff(state, alt_rel)
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
            self.set_speed_xy(None)
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
        if self.home_down_m() - down < 0.0:
            return self._refuse(CommandResult.DENIED, "REPOSITION: altitude below home")
        if p[0] > 0.0:
            vmax = self.params.get("MPC_XY_VEL_MAX")
            if p[0] > vmax:
                return self._refuse(CommandResult.DENIED, f"REPOSITION: speed {p[0]:g} m/s above {vmax:g}")
            self.set_speed_xy(p[0])
        self.goto(state, (ne[0], ne[1], down), math.nan if math.isnan(p[3]) else math.radians(p[3]))
        return CommandResult.ACCEPTED

    def _down_from_alt(self, alt_m: float, request: CommandRequest) -> float:
        """Local down (m) of a command altitude (see the module docstring for frames)."""
        if request.is_int and request.frame in _RELATIVE_ALT_FRAMES:
            return self.home_down_m() - alt_m
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
