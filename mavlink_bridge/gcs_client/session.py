"""The ground station's link to one vehicle: receive, fold telemetry, match replies, retry, send the GCS HEARTBEAT.

Single-threaded: every blocking call pumps the link, keeps :meth:`GcsSession.telemetry` current and
sends the GCS HEARTBEAT at 1 Hz. The protocol parts (missions, commands, parameters) build on it.
"""

from __future__ import annotations

import math
import time
from collections import deque
from collections.abc import Callable
from typing import Self, TypeVar

from pymavlink.dialects.v20 import common as mavlink2

from mavlink_bridge.contract.vehicle_api import Severity, StatusText
from mavlink_bridge.gcs_client.errors import GcsTimeoutError
from mavlink_bridge.gcs_client.telemetry import TelemetryState, VehicleStatus
from mavlink_bridge.wire.gcs_link import MavlinkEndpoint

Msg = mavlink2.MAVLink_message
T = TypeVar("T")
M = mavlink2
MAV_COMP_ID_MISSIONPLANNER = 190


class GcsSession:
    """A ground station on one link (``udpin:`` waits for the vehicle to talk, ``udpout:`` talks first)."""

    def __init__(
        self,
        url: str = "udpin:127.0.0.1:14550",
        *,
        target_system: int = 1,
        target_component: int = 1,
        system_id: int = 255,
        component_id: int = MAV_COMP_ID_MISSIONPLANNER,
        signing_key: bytes | None = None,
        timeout_s: float = 5.0,
        retry_s: float = 0.3,
        endpoint: MavlinkEndpoint | None = None,
    ) -> None:
        # ``endpoint``: a link shared with other vehicles' sessions (gcs_client.fleet_link), else its own on ``url``
        self._endpoint = endpoint or MavlinkEndpoint(
            url, system_id=system_id, component_id=component_id, signing_key=signing_key, require_signing=False
        )
        self.mav = self._endpoint.mav
        self.target_system = target_system
        self.target_component = target_component
        self.timeout_s = timeout_s
        self.retry_s = retry_s
        self._pending: deque[Msg] = deque()
        self._last_heartbeat_sent_s = -math.inf
        self._telemetry = TelemetryState(target_component)
        if self._endpoint.link.peer is not None:
            self._send_heartbeat()

    # ---- lifecycle ---------------------------------------------------------------------------------------
    def close(self) -> None:
        self._endpoint.close()

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # ---- telemetry ---------------------------------------------------------------------------------------
    def telemetry(self) -> VehicleStatus:
        """The latest decoded state (call :meth:`pump` or any blocking call to refresh it)."""
        return self._telemetry.status()

    def pump(self, duration_s: float = 0.0) -> None:
        """Process incoming messages for ``duration_s`` (0: only what is waiting)."""
        self._wait(lambda _m: None, duration_s)

    def wait_heartbeat(self, timeout_s: float | None = None) -> VehicleStatus:
        """Block until a HEARTBEAT from the vehicle; GcsTimeoutError otherwise."""
        return self.wait_until(lambda s: s.heartbeat_received, self.timeout_s if timeout_s is None else timeout_s)

    def wait_until(
        self, predicate: Callable[[VehicleStatus], bool], timeout_s: float, poll_s: float = 0.05
    ) -> VehicleStatus:
        """Pump until ``predicate(telemetry())`` holds; GcsTimeoutError after ``timeout_s`` of wall time."""
        deadline = time.monotonic() + timeout_s
        while True:
            status = self.telemetry()
            if predicate(status):
                return status
            remaining = deadline - time.monotonic()
            if remaining <= 0.0:
                raise GcsTimeoutError(f"condition not met within {timeout_s:g} s")
            self.pump(min(poll_s, remaining))

    def statustexts_since(self, serial: int) -> list[StatusText]:
        """STATUSTEXTs received after :attr:`statustext_serial` was ``serial``."""
        return self._telemetry.statustexts_since(serial)

    @property
    def statustext_serial(self) -> int:
        return self._telemetry.text_serial

    def forget_reached_items(self) -> None:
        """Start counting MISSION_ITEM_REACHED afresh (e.g. before flying a new mission)."""
        self._telemetry.forget_reached_items()

    # ---- internals ---------------------------------------------------------------------------------------
    def _exchange(self, send: Callable[[], None], match: Callable[[Msg], T | None], what: str) -> T:
        """Send, wait ``retry_s`` for a match, resend; GcsTimeoutError after ``timeout_s``."""
        deadline = time.monotonic() + self.timeout_s
        while True:
            send()
            found = self._wait(match, min(self.retry_s, max(0.0, deadline - time.monotonic())))
            if found is not None:
                return found
            if time.monotonic() >= deadline:
                raise GcsTimeoutError(f"no answer for {what} within {self.timeout_s:g} s")

    def _wait(self, match: Callable[[Msg], T | None], timeout_s: float) -> T | None:
        deadline = time.monotonic() + timeout_s
        while True:
            while self._pending:
                msg = self._pending.popleft()
                found = match(msg)
                if found is not None:
                    return found
            self._maybe_heartbeat()
            remaining = deadline - time.monotonic()
            if remaining < 0.0:
                return None
            msgs = self._endpoint.receive_datagram(min(remaining, 0.1))
            for msg in msgs or ():
                if msg.get_srcSystem() == self.target_system:
                    self._telemetry.update(msg)
                    self._pending.append(msg)

    def _maybe_heartbeat(self) -> None:
        now = time.monotonic()
        if now - self._last_heartbeat_sent_s >= 1.0 and self._endpoint.link.peer is not None:
            self._send_heartbeat()

    def _send_heartbeat(self) -> None:
        self._last_heartbeat_sent_s = time.monotonic()
        self.mav.heartbeat_send(M.MAV_TYPE_GCS, M.MAV_AUTOPILOT_INVALID, 0, 0, M.MAV_STATE_ACTIVE)

    def _reason(self, serial: int, default: str) -> str:
        """The latest warning/error STATUSTEXT since ``serial`` (the vehicle's reason), else ``default``."""
        for text in reversed(self.statustexts_since(serial)):
            if text.severity <= Severity.WARNING:
                return text.text
        return default
