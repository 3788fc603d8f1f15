"""Freshness of the real-time peers: offboard setpoints, the joystick and GCS heartbeats (SPEC §3).

The simulator owns time, but an offboard script, a joystick and a ground station live in wall-clock time, so
their ages are wall seconds (stretched by 1/speed when the sim runs slower than real time, like the GCS link
timeouts). Reads the wall clock and the GCS servers' heartbeat ages; emits ages and freshness flags.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from typing import Protocol


class HeartbeatSource(Protocol):
    """A GCS link that knows when it last heard a ground station (``GcsServer``)."""

    @property
    def gcs_heartbeat_age_s(self) -> float: ...


class LinkHealth:
    """When the offboard stream and the joystick were last heard; the youngest GCS heartbeat."""

    def __init__(self, speed_factor: float = 1.0, wall_clock: Callable[[], float] = time.monotonic) -> None:
        self.speed_factor = speed_factor
        self.wall_clock = wall_clock
        self._offboard_wall_s: float | None = None
        self._manual_wall_s: float | None = None
        self._gcs: Sequence[HeartbeatSource] = ()

    def watch_gcs(self, servers: Sequence[HeartbeatSource]) -> None:
        """The GCS/API links whose heartbeats count for the GCS-loss failsafe."""
        self._gcs = tuple(servers)

    def offboard_heard(self) -> None:
        self._offboard_wall_s = self.wall_clock()

    def manual_heard(self) -> None:
        self._manual_wall_s = self.wall_clock()

    def _age_s(self, heard_wall_s: float | None) -> float | None:
        if heard_wall_s is None:
            return None
        age = self.wall_clock() - heard_wall_s
        speed = self.speed_factor
        return age * speed if 0.0 < speed < 1.0 else age

    def offboard_age_s(self) -> float | None:
        """Seconds since the last offboard setpoint; None if none ever came."""
        return self._age_s(self._offboard_wall_s)

    def manual_age_s(self) -> float | None:
        """Seconds since the last joystick input; None if none ever came."""
        return self._age_s(self._manual_wall_s)

    def gcs_heartbeat_age_s(self) -> float | None:
        """Wall seconds since the youngest GCS heartbeat over all links (None if none ever)."""
        age = min((server.gcs_heartbeat_age_s for server in self._gcs), default=math.inf)
        return None if math.isinf(age) else age

    def offboard_streaming(self, loss_timeout_s: float) -> bool:
        age = self.offboard_age_s()
        return age is not None and age <= loss_timeout_s

    def manual_fresh(self, loss_timeout_s: float) -> bool:
        age = self.manual_age_s()
        return age is not None and age <= loss_timeout_s
