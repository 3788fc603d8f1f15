"""The ground station's commands: COMMAND_LONG with retries, the ack, and the vehicle's reason for a refusal."""

from __future__ import annotations

import contextlib
import math
import time

from pymavlink.dialects.v20 import common as mavlink2

from mavlink_bridge.contract.vehicle_api import CommandResult, FlightMode
from mavlink_bridge.gcs_client.errors import CommandFailedError, GcsError, GcsTimeoutError
from mavlink_bridge.gcs_client.session import GcsSession, Msg

M = mavlink2
_FORCE_ARM_MAGIC = 21196.0  # PX4/ArduPilot: param2 of COMPONENT_ARM_DISARM that bypasses pre-arm checks

#: What a COMMAND_ACK result means, for a refusal the vehicle sent no STATUSTEXT about.
RESULT_MEANING = {
    CommandResult.TEMPORARILY_REJECTED: "not now: the vehicle is not ready for it yet (try again in a moment)",
    CommandResult.DENIED: "the vehicle refused it in its present state and gave no reason",
    CommandResult.UNSUPPORTED: "the vehicle does not support this command",
    CommandResult.FAILED: "the vehicle accepted it but could not carry it out",
    CommandResult.CANCELLED: "cancelled by the vehicle",
}
#: Wall seconds to wait after a refusal for the STATUSTEXT that says why (the vehicle sends it after the ack).
REASON_WAIT_S = 0.5


class GcsCommands(GcsSession):
    """Commands and their acks: arm, disarm, mode, takeoff, land, RTL, mission start, message rates."""

    def command(self, command: int, *params: float, timeout_s: float | None = None) -> CommandResult:
        """COMMAND_LONG (up to 7 params, rest 0); retried with rising ``confirmation``; returns the final result."""
        if len(params) > 7:
            raise ValueError("COMMAND_LONG has 7 parameters")
        p = [float(v) for v in params] + [0.0] * (7 - len(params))
        ts, tc = self.target_system, self.target_component
        confirmation = 0
        deadline = time.monotonic() + (self.timeout_s if timeout_s is None else timeout_s)

        def is_ack(msg: Msg) -> Msg | None:
            if msg.get_type() == "COMMAND_ACK" and int(msg.command) == command:
                target = int(getattr(msg, "target_system", 0))
                if target in (0, self.mav.srcSystem):
                    return msg
            return None

        in_progress = False
        while time.monotonic() < deadline:
            if not in_progress:
                self.mav.command_long_send(ts, tc, command, confirmation, *p)
            ack = self._wait(is_ack, min(self.retry_s, max(0.0, deadline - time.monotonic())))
            if ack is None:
                confirmation = min(255, confirmation + 1)
                continue
            result = CommandResult(int(ack.result))
            if result is not CommandResult.IN_PROGRESS:
                return result
            in_progress = True
        raise GcsTimeoutError(f"no COMMAND_ACK for command {command}")

    def _command_ok(self, command: int, *params: float) -> None:
        serial = self.statustext_serial
        result = self.command(command, *params)
        if result is not CommandResult.ACCEPTED:
            raise CommandFailedError(command, result, self.refusal_reason(serial, result))

    def refusal_reason(self, serial: int, result: CommandResult) -> str:
        """Why the vehicle refused: its warning STATUSTEXT since ``serial`` (waited for up to
        :data:`REASON_WAIT_S`, as it may follow the ack), else what ``result`` means."""
        deadline = time.monotonic() + REASON_WAIT_S
        reason = self._reason(serial, "")
        while not reason and time.monotonic() < deadline:
            self.pump(0.05)
            reason = self._reason(serial, "")
        return reason or RESULT_MEANING.get(result, result.name)

    def arm(self, force: bool = False) -> None:
        self._command_ok(M.MAV_CMD_COMPONENT_ARM_DISARM, 1.0, _FORCE_ARM_MAGIC if force else 0.0)

    def disarm(self, force: bool = False) -> None:
        self._command_ok(M.MAV_CMD_COMPONENT_ARM_DISARM, 0.0, _FORCE_ARM_MAGIC if force else 0.0)

    def set_mode(self, mode: FlightMode) -> None:
        """MAV_CMD_DO_SET_MODE with the PX4 custom main/sub mode."""
        self._command_ok(
            M.MAV_CMD_DO_SET_MODE,
            float(M.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED),
            float(mode.px4_main_mode),
            float(mode.px4_sub_mode),
        )

    def takeoff(self, alt_m: float) -> None:
        """MAV_CMD_NAV_TAKEOFF to ``alt_m`` above home; param7 is AMSL as PX4 expects (needs HOME_POSITION: asked
        for when not known yet, then waited for while the vehicle has none)."""
        if self._telemetry.home is None:
            with contextlib.suppress(GcsError):  # refused (no home yet: it comes with the fix) or not answered
                self.request_home(wait_s=0.0)
            self.wait_until(lambda s: s.home is not None, self.timeout_s)
        assert self._telemetry.home is not None
        nan = math.nan
        self._command_ok(M.MAV_CMD_NAV_TAKEOFF, -1.0, 0.0, 0.0, nan, nan, nan, self._telemetry.home.alt_amsl_m + alt_m)

    def land(self) -> None:
        nan = math.nan
        self._command_ok(M.MAV_CMD_NAV_LAND, 0.0, 0.0, 0.0, nan, nan, nan, nan)

    def rtl(self) -> None:
        self._command_ok(M.MAV_CMD_NAV_RETURN_TO_LAUNCH)

    def start_mission(self, first_item: int = 0, last_item: int = 0) -> None:
        """MAV_CMD_MISSION_START (PX4 switches to AUTO.MISSION)."""
        self._command_ok(M.MAV_CMD_MISSION_START, float(first_item), float(last_item))

    def request_message(self, message_id: int) -> None:
        """MAV_CMD_REQUEST_MESSAGE: the vehicle sends ``message_id`` once, now (as QGroundControl asks for
        HOME_POSITION rather than wait for its slow stream)."""
        self._command_ok(M.MAV_CMD_REQUEST_MESSAGE, float(message_id))

    def request_home(self, wait_s: float = 0.3) -> None:
        """Ask for HOME_POSITION now and take what comes within ``wait_s``."""
        self.request_message(M.MAVLINK_MSG_ID_HOME_POSITION)
        self.pump(wait_s)

    def set_message_interval(self, message_id: int, interval_s: float) -> None:
        """SET_MESSAGE_INTERVAL: ``interval_s`` > 0, 0 = default rate, < 0 = off."""
        interval_us = -1.0 if interval_s < 0 else interval_s * 1e6
        self._command_ok(M.MAV_CMD_SET_MESSAGE_INTERVAL, float(message_id), interval_us)
