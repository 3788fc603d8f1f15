"""Vehicle side of the MAVLink parameter protocol (SPEC §8), float-only (MAV_PARAM_TYPE_REAL32).

PARAM_REQUEST_LIST queues every parameter and sends ``per_tick`` of them per ``tick`` so a
long list never floods the link; PARAM_REQUEST_READ answers by name or index;
PARAM_SET goes to ``vehicle.param_set`` and is *always* answered with PARAM_VALUE carrying
the value in force (the old one when refused, plus a STATUSTEXT with the reason).
An unknown name gets a STATUSTEXT ``unknown parameter NAME`` (there is no value to send).
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable
from dataclasses import dataclass

from pymavlink.dialects.v20 import common as mavlink2

from mavlink_bridge.contract.vehicle_api import Severity, VehicleInterface
from mavlink_bridge.wire.param_ids import PARAM_TYPE_REAL32, decode_param_id


@dataclass(slots=True)
class ParamProtocolStats:
    values_sent: int = 0
    sets_accepted: int = 0
    sets_refused: int = 0
    unknown_requests: int = 0


class ParamProtocol:
    """Parameter requests from GCS peers; feed it messages and call ``tick`` to stream lists."""

    HANDLED = frozenset({"PARAM_REQUEST_LIST", "PARAM_REQUEST_READ", "PARAM_SET"})

    def __init__(
        self,
        mav: mavlink2.MAVLink,
        vehicle: VehicleInterface,
        statustext: Callable[[Severity, str], None],
        *,
        per_tick: int = 40,
    ) -> None:
        self._mav = mav
        self._vehicle = vehicle
        self._statustext = statustext
        self.per_tick = per_tick
        self.stats = ParamProtocolStats()
        self._queue: deque[int] = deque()

    def handle(self, msg: mavlink2.MAVLink_message) -> None:
        kind = msg.get_type()
        if kind == "PARAM_REQUEST_LIST":
            self._queue.clear()
            self._queue.extend(range(len(self._vehicle.param_names())))
        elif kind == "PARAM_REQUEST_READ":
            self._on_read(msg)
        elif kind == "PARAM_SET":
            self._on_set(msg)

    def tick(self) -> None:
        """Send up to ``per_tick`` queued PARAM_VALUEs of a list request."""
        if not self._queue:
            return
        names = self._vehicle.param_names()
        for _ in range(min(self.per_tick, len(self._queue))):
            index = self._queue.popleft()
            if index < len(names):
                self._send_value(names, index)

    def _on_read(self, msg: mavlink2.MAVLink_message) -> None:
        names = self._vehicle.param_names()
        index = int(msg.param_index)
        if index >= 0:
            if index < len(names):
                self._send_value(names, index)
            else:
                self.stats.unknown_requests += 1
                self._statustext(Severity.WARNING, f"unknown parameter index {index}")
            return
        name = decode_param_id(msg.param_id)
        try:
            self._send_value(names, names.index(name))
        except ValueError:
            self.stats.unknown_requests += 1
            self._statustext(Severity.WARNING, f"unknown parameter {name}")

    def _on_set(self, msg: mavlink2.MAVLink_message) -> None:
        name = decode_param_id(msg.param_id)
        names = self._vehicle.param_names()
        if name not in names:
            self.stats.unknown_requests += 1
            self._statustext(Severity.WARNING, f"unknown parameter {name}")
            return
        accepted, _value_now, reason = self._vehicle.param_set(name, float(msg.param_value))
        if accepted:
            self.stats.sets_accepted += 1
        else:
            self.stats.sets_refused += 1
            self._statustext(Severity.WARNING, f"{name} refused: {reason}")
        self._send_value(names, names.index(name))

    def _send_value(self, names: list[str], index: int) -> None:
        name = names[index]
        value = self._vehicle.param_get(name)
        if value is None:
            return
        self._mav.param_value_send(name.encode("ascii"), float(value), PARAM_TYPE_REAL32, len(names), index)
        self.stats.values_sent += 1
