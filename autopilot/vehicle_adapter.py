"""The autopilot's GCS-facing API: the ``VehicleInterface`` the GCS and API servers call (SPEC §8).

- Reads: commands, mission and fence uploads, offboard setpoints, joystick input and parameter requests, in
  the contract's types (``mavlink_bridge.contract.vehicle_api``).
- Hands them to: the commander (through ``Autopilot.handle_command``), the navigator (missions, fences), the
  link health (offboard and joystick freshness) and the parameter store.
- Emits: honest results (``CommandResult``, ``MissionResult`` with a reason, parameter values).
Every call returns at once; no I/O.
"""

from __future__ import annotations

import math

from autopilot.parameters.store import ParamError
from autopilot.runner import Autopilot
from mavlink_bridge.contract.vehicle_api import (
    AltitudeFrame,
    CommandRequest,
    CommandResult,
    LocalPositionTarget,
    ManualInput,
    MissionItem,
    MissionResult,
    MissionType,
    PositionTarget,
    VelocityFrame,
    VelocityTarget,
)


class VehicleAdapter:
    """The autopilot behind ``mavlink_bridge.contract.vehicle_api.VehicleInterface``."""

    def __init__(self, autopilot: Autopilot) -> None:
        self._ap = autopilot

    def handle_command(self, request: CommandRequest) -> CommandResult:
        return self._ap.handle_command(request)

    def mission_items(self, mission_type: MissionType) -> list[MissionItem]:
        return self._ap.navigator.mission_items(mission_type)

    def replace_mission(self, mission_type: MissionType, items: list[MissionItem]) -> tuple[MissionResult, str]:
        result, reason = self._ap.navigator.replace_mission(mission_type, items)
        if result is MissionResult.ACCEPTED:
            self._ap.mission_accepted(mission_type, items)
        return result, reason

    def set_current_mission_item(self, seq: int) -> bool:
        return self._ap.navigator.set_current_mission_item(seq)

    def set_position_target(self, target: PositionTarget) -> bool:
        """An offboard position setpoint (local NED about the origin, or global); False without a local frame."""
        ap = self._ap
        frame = ap.estimator.local_frame
        if isinstance(target, LocalPositionTarget):
            pos = target.pos_ned_m
        elif frame is None:
            return False
        else:
            alt_amsl = target.alt_m
            if target.alt_frame is AltitudeFrame.ABOVE_HOME:
                home = ap.home_geo
                if home is None:
                    return False
                alt_amsl += home.alt_amsl_m
            pos = frame.ned_from_geodetic(target.lat_deg, target.lon_deg, alt_amsl)
        ap.commander.set_offboard_target((float(pos[0]), float(pos[1]), float(pos[2])), target.yaw_rad)
        self._offboard_heard()
        return True

    def set_velocity_target(self, target: VelocityTarget) -> bool:
        """An offboard velocity setpoint; a body-frame one is turned with the heading of each control step
        (``Commander.set_offboard_velocity``)."""
        body = target.frame is VelocityFrame.BODY
        self._ap.commander.set_offboard_velocity(target.vel_m_s, target.yaw_rad, target.yaw_rate_rad_s, body=body)
        self._offboard_heard()
        return True

    def _offboard_heard(self) -> None:
        self._ap.wake_navigation()  # the commander takes the new setpoint at the next step
        self._ap.links.offboard_heard()
        self._ap.update_context(offboard_streaming=True)

    def set_manual_input(self, sticks: ManualInput) -> bool:
        """Joystick input (MANUAL_CONTROL); POSCTL flies it while it keeps coming (COM_RC_LOSS_T)."""
        self._ap.commander.set_manual_input(sticks)
        self._ap.wake_navigation()
        self._ap.links.manual_heard()
        self._ap.update_context(manual_fresh=True)
        return True

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
