"""A mission waypoint that traffic keeps the vehicle off is bypassed (SPEC §13, liveness): the vehicle goes on to
the next one, and says why (``Bypassed item N: traffic kept the vehicle ...``), as it does for a waypoint inside an
obstacle.

Reactive avoidance keeps separation, not progress: vehicles whose waypoints lie inside one separation volume can
keep each other off them for as long as they try (encounter case 682: three of eight vehicles crossing over one
centre, their waypoints 3 m apart, circled it for 300 s and ended STUCK). When the vehicle has come no closer to
its waypoint (by ``PROGRESS_M``) for ``BLOCKED_US`` while within ``NEAR_VOLUMES`` grown UAV volumes of it, with a
track there, the waypoint is bypassed. Only a waypoint followed at once by another positional item (no action
item such as a delivery between, never the last one before a landing): the route goes on, the mission's meaning
does not change. A bypassed item counts as bypassed, never as reached.
"""

from __future__ import annotations

import math

from autopilot.mission.executor_types import MissionRoute
from autopilot.traffic.param_decls import TrafficParams
from autopilot.traffic.tracks import TrafficTrack
from mavlink_bridge.contract.frames import Vec3

#: How long (µs) the vehicle may come no closer to its waypoint before it is bypassed.
BLOCKED_US = 60_000_000
#: Closer by this much (m, 3D) is progress: the wait starts again.
PROGRESS_M = 1.0
#: Only within this many grown UAV volumes (horizontally) of the waypoint, with a track as near it.
NEAR_VOLUMES = 3.0


class BlockedWaypoint:
    """Watches the route's head for progress; see the module docstring."""

    def __init__(self) -> None:
        self._seq = -1
        self._best_m = math.inf
        self._since_us = 0

    def check(self, t_us: int, pos_home_ned_m: Vec3, route: MissionRoute | None, tracks: tuple[TrafficTrack, ...],
              params: TrafficParams) -> tuple[int, int, str] | None:  # fmt: skip
        """(the item to bypass, the item to go on to, why) when traffic has kept the vehicle off the route's head
        (about home, as the position and the tracks); None otherwise."""
        if route is None or len(route.seqs) < 2 or route.seqs[1] != route.seqs[0] + 1:
            self._seq = -1
            return None
        head, goal = route.seqs[0], route.pos_ned_m[0]
        off_m = math.dist(pos_home_ned_m, (float(goal[0]), float(goal[1]), float(goal[2])))
        if head != self._seq or off_m < self._best_m - PROGRESS_M:
            self._seq, self._best_m, self._since_us = head, off_m, t_us
            return None
        if t_us - self._since_us < BLOCKED_US:
            return None
        near_m = NEAR_VOLUMES * params.uav.grown(params.margin).hor_m
        if math.hypot(pos_home_ned_m[0] - goal[0], pos_home_ned_m[1] - goal[1]) >= near_m:
            return None
        there = [t for t in tracks if math.hypot(t.pos_home_ned_m[0] - goal[0], t.pos_home_ned_m[1] - goal[1]) < near_m]
        if not there:
            return None
        self._seq = -1
        why = f"traffic kept the vehicle {off_m:.0f} m off it for {(t_us - self._since_us) * 1e-6:.0f} s"
        return head, route.seqs[1], f"{why} ({there[0].name} near it)"
