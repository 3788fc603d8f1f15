"""The ground station's parameter protocol: read, set (with the vehicle's refusal) and list."""

from __future__ import annotations

import math
import struct
import time
from collections.abc import Callable

from mavlink_bridge.gcs_client.errors import GcsTimeoutError, ParamNotFoundError, ParamRefusedError
from mavlink_bridge.gcs_client.session import GcsSession, Msg
from mavlink_bridge.wire.param_ids import PARAM_TYPE_REAL32, decode_param_id


def _float32(value: float) -> float:
    """``value`` as it survives a float32 MAVLink field."""
    return struct.unpack("<f", struct.pack("<f", value))[0]


class GcsParams(GcsSession):
    """PARAM_REQUEST_READ / PARAM_SET / PARAM_REQUEST_LIST, GCS side."""

    def get_param(self, name: str) -> float:
        """The value in force; ParamNotFoundError if the vehicle does not know ``name``."""
        ts, tc = self.target_system, self.target_component
        msg = self._exchange(
            lambda: self.mav.param_request_read_send(ts, tc, name.encode("ascii"), -1),
            self._param_matcher(name),
            f"parameter {name}",
        )
        return float(msg.param_value)

    def set_param(self, name: str, value: float) -> float:
        """Set ``name``; returns the value in force, ParamRefusedError if the vehicle kept another one."""
        ts, tc = self.target_system, self.target_component
        serial = self.statustext_serial
        msg = self._exchange(
            lambda: self.mav.param_set_send(ts, tc, name.encode("ascii"), float(value), PARAM_TYPE_REAL32),
            self._param_matcher(name),
            f"parameter {name}",
        )
        in_force = float(msg.param_value)
        if in_force != _float32(float(value)) and not (math.isnan(in_force) and math.isnan(value)):
            raise ParamRefusedError(name, float(value), in_force, self._reason(serial, "refused by the vehicle"))
        return in_force

    def list_params(self) -> dict[str, float]:
        """Every parameter (PARAM_REQUEST_LIST; missing indices re-read one by one)."""
        ts, tc = self.target_system, self.target_component
        values: dict[int, tuple[str, float]] = {}
        total: int | None = None

        def collect(msg: Msg) -> None:
            nonlocal total
            if msg.get_type() == "PARAM_VALUE" and msg.get_srcSystem() == ts:
                total = int(msg.param_count)
                if 0 <= int(msg.param_index) < total:
                    values[int(msg.param_index)] = (decode_param_id(msg.param_id), float(msg.param_value))

        def complete(msg: Msg) -> bool | None:
            collect(msg)
            return True if total is not None and len(values) >= total else None

        self.mav.param_request_list_send(ts, tc)
        deadline = time.monotonic() + self.timeout_s
        while time.monotonic() < deadline:
            before = len(values)
            if self._wait(complete, self.retry_s) is not None:
                break
            if len(values) > before:
                deadline = time.monotonic() + self.timeout_s  # still streaming: the limit is on silence
                continue
            if total is None:
                self.mav.param_request_list_send(ts, tc)
            else:
                for index in [i for i in range(total) if i not in values][:20]:
                    self.mav.param_request_read_send(ts, tc, b"", index)
        if total is None or len(values) < total:
            raise GcsTimeoutError(f"parameter list incomplete: {len(values)}/{total if total is not None else '?'}")
        return {name: value for _, (name, value) in sorted(values.items())}

    def _param_matcher(self, name: str) -> Callable[[Msg], Msg | None]:
        def match(msg: Msg) -> Msg | None:
            kind = msg.get_type()
            if kind == "PARAM_VALUE" and decode_param_id(msg.param_id) == name:
                return msg
            if kind == "STATUSTEXT" and self._telemetry.latest_text() == f"unknown parameter {name}":
                raise ParamNotFoundError(f"the vehicle has no parameter {name}")
            return None

        return match
