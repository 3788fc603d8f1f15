"""Vehicle side of the MAVLink command protocol (SPEC §8): COMMAND_LONG / COMMAND_INT -> COMMAND_ACK.

Link-level commands (SET_MESSAGE_INTERVAL 511, REQUEST_MESSAGE 512, REQUEST_AUTOPILOT_CAPABILITIES
520) are answered here; every other command goes to ``vehicle.handle_command`` and its
honest CommandResult is acked. A retry (COMMAND_LONG with confirmation > 0) or a duplicated
datagram of a command answered within ``dedupe_window_s`` gets the same result again and
is not executed twice.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

from pymavlink.dialects.v20 import common as mavlink2

from mavlink_bridge.contract.vehicle_api import CommandRequest, CommandResult, VehicleInterface
from mavlink_bridge.wire.mission_items import xy_from_int

MAV_CMD_SET_MESSAGE_INTERVAL = mavlink2.MAV_CMD_SET_MESSAGE_INTERVAL
MAV_CMD_REQUEST_MESSAGE = mavlink2.MAV_CMD_REQUEST_MESSAGE
MAV_CMD_REQUEST_AUTOPILOT_CAPABILITIES = mavlink2.MAV_CMD_REQUEST_AUTOPILOT_CAPABILITIES

#: A link-level handler returns the result to ack and an action to run right after the ack.
LocalHandler = Callable[[CommandRequest], tuple[CommandResult, Callable[[], object] | None]]


@dataclass(slots=True)
class CommandProtocolStats:
    received: int = 0
    duplicates: int = 0
    accepted: int = 0
    refused: int = 0


@dataclass(frozen=True, slots=True)
class _Answered:
    key: tuple
    result: CommandResult
    wall_time_s: float


def request_from_msg(msg: mavlink2.MAVLink_message) -> CommandRequest:
    """COMMAND_LONG or COMMAND_INT as a CommandRequest (COMMAND_INT x/y: degrees in global frames, metres in local)."""
    if msg.get_type() == "COMMAND_INT":
        frame = int(msg.frame)
        x, y = xy_from_int(msg.x, frame), xy_from_int(msg.y, frame)
        params = (float(msg.param1), float(msg.param2), float(msg.param3), float(msg.param4), x, y, float(msg.z))
        return CommandRequest(int(msg.command), params, msg.get_srcSystem(), msg.get_srcComponent(), True, frame)
    params = tuple(float(getattr(msg, f"param{i}")) for i in range(1, 8))
    return CommandRequest(int(msg.command), params, msg.get_srcSystem(), msg.get_srcComponent())  # type: ignore[arg-type]


def _key(request: CommandRequest) -> tuple:
    # NaN != NaN: compare parameters by their text so a retried NaN parameter still matches.
    return (request.command, request.source_system, request.source_component, request.is_int, repr(request.params))


class CommandProtocol:
    """Answers every command addressed to the vehicle with exactly one COMMAND_ACK per datagram."""

    HANDLED = frozenset({"COMMAND_LONG", "COMMAND_INT"})

    def __init__(
        self,
        mav: mavlink2.MAVLink,
        vehicle: VehicleInterface,
        local_handlers: dict[int, LocalHandler],
        *,
        dedupe_window_s: float = 3.0,
    ) -> None:
        self._mav = mav
        self._vehicle = vehicle
        self._local = local_handlers
        self.dedupe_window_s = dedupe_window_s
        self.stats = CommandProtocolStats()
        self._last: _Answered | None = None
        self._last_packet: tuple[int, int, int, tuple] | None = None

    def handle(self, msg: mavlink2.MAVLink_message, wall_time_s: float) -> None:
        request = request_from_msg(msg)
        self.stats.received += 1
        key = _key(request)
        confirmation = int(getattr(msg, "confirmation", 0))
        packet = (request.source_system, request.source_component, msg.get_seq(), key)
        last = self._last
        recent = last is not None and last.key == key and wall_time_s - last.wall_time_s <= self.dedupe_window_s
        if recent and last is not None and (confirmation > 0 or packet == self._last_packet):
            self.stats.duplicates += 1
            self._ack(request, last.result)
            return
        self._last_packet = packet
        result, after = self._execute(request)
        self._last = _Answered(key, result, wall_time_s)
        if result is CommandResult.ACCEPTED:
            self.stats.accepted += 1
        else:
            self.stats.refused += 1
        self._ack(request, result)
        if after is not None:
            after()

    def _execute(self, request: CommandRequest) -> tuple[CommandResult, Callable[[], object] | None]:
        if any(math.isinf(p) for p in request.params):
            return CommandResult.DENIED, None
        handler = self._local.get(request.command)
        if handler is not None:
            return handler(request)
        try:
            return CommandResult(self._vehicle.handle_command(request)), None
        except ValueError:
            return CommandResult.FAILED, None

    def _ack(self, request: CommandRequest, result: CommandResult) -> None:
        self._mav.command_ack_send(request.command, int(result), 0, 0, request.source_system, request.source_component)
