"""A mission waypoint that traffic keeps the vehicle off is bypassed after BLOCKED_US without progress (SPEC §13:
liveness; encounter case 682), and only one the route goes on from at once."""

from __future__ import annotations

import numpy as np

from autopilot.mission.executor_types import MissionRoute
from autopilot.navigation.traffic_bypass import BLOCKED_US, BlockedWaypoint
from autopilot.traffic.param_decls import TrafficParams
from autopilot.traffic.tracks import TrafficTrack
from mavlink_bridge.contract.traffic import TrafficSource

PARAMS = TrafficParams()
WAYPOINT = (0.0, 15.0, -30.0)
ROUTE = MissionRoute((2, 3), np.array([WAYPOINT, (-35.0, 88.0, -30.0)]), 4)
OTHER = TrafficTrack(TrafficSource.UAV, 6, "", (1.0, 15.0, -32.0), (0.5, 0.0, 0.0), 0, (1.0, 15.0, -32.0))


def _circle(blocked: BlockedWaypoint, route: MissionRoute, tracks: tuple[TrafficTrack, ...], seconds: float,
            off_m: float = 12.0, t0_s: float = 0.0) -> list[tuple[float, tuple[int, int, str]]]:  # fmt: skip
    """Circle the waypoint ``off_m`` away for ``seconds`` (10 Hz); the bypasses given, with their times."""
    out = []
    for k in range(int(seconds * 10)):
        t_s = t0_s + k * 0.1
        a = 0.2 * t_s
        pos = (WAYPOINT[0] + off_m * np.cos(a), WAYPOINT[1] + off_m * np.sin(a), WAYPOINT[2])
        got = blocked.check(int(t_s * 1e6), pos, route, tracks, PARAMS)
        if got is not None:
            out.append((t_s, got))
    return out


def test_a_waypoint_traffic_keeps_the_vehicle_off_is_bypassed_after_a_while() -> None:
    got = _circle(BlockedWaypoint(), ROUTE, (OTHER,), 70.0)
    assert len(got) == 1
    t_s, (head, then, why) = got[0]
    assert abs(t_s - BLOCKED_US * 1e-6) < 0.15 and (head, then) == (2, 3)
    assert why == "traffic kept the vehicle 12 m off it for 60 s (UAV 6 near it)"


def test_progress_no_traffic_or_far_off_keep_the_waypoint() -> None:
    blocked = BlockedWaypoint()
    assert _circle(blocked, ROUTE, (), 70.0) == []  # no track near it: not traffic's doing
    assert _circle(BlockedWaypoint(), ROUTE, (OTHER,), 70.0, off_m=60.0) == []  # far from it
    closing = BlockedWaypoint()
    for k in range(700):  # closing in by 0.5 m every 3 s: progress (1 m) every 6 s
        t_us = k * 100_000
        pos = (WAYPOINT[0], WAYPOINT[1] - 30.0 + (t_us // 3_000_000) * 0.5, WAYPOINT[2])
        assert closing.check(t_us, pos, ROUTE, (OTHER,), PARAMS) is None


def test_only_a_waypoint_the_route_goes_on_from_at_once() -> None:
    """An action item (a delivery) after it, or a landing next: never bypassed."""
    action_next = MissionRoute((2, 4), ROUTE.pos_ned_m, 5)
    last = MissionRoute((2,), ROUTE.pos_ned_m[:1], 3)
    assert _circle(BlockedWaypoint(), action_next, (OTHER,), 70.0) == []
    assert _circle(BlockedWaypoint(), last, (OTHER,), 70.0) == []
