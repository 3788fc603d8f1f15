"""Route planning on the known world (issue 13): around fences and known obstacles, with the margin kept."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest

from autopilot.geofence.fence import CircleZone, Geofence, PolygonZone
from autopilot.planner.obstacle_map import ObstacleKind, TrackedObstacle
from autopilot.planner.route_graph import KnownWorld, ObstacleDisc, obstacle_discs

ALT = -10.0
U_INCLUSION = (
    (0.0, 0.0),
    (0.0, 30.0),
    (30.0, 30.0),
    (30.0, 20.0),
    (10.0, 20.0),
    (10.0, 10.0),
    (30.0, 10.0),
    (30.0, 0.0),
)


def _clear(fence: Geofence, path: np.ndarray, margin_m: float) -> bool:
    return all(fence.segment_clear(path[i], path[i + 1], margin_m) for i in range(len(path) - 1))


def test_straight_leg_when_nothing_is_in_the_way() -> None:
    world = KnownWorld(Geofence((CircleZone((50.0, 40.0), 10.0, False),)), 3.0)
    r = world.route((0.0, 0.0, ALT), (100.0, 0.0, ALT))
    assert r.ok and len(r.path_ned_m) == 2 and r.length_m == pytest.approx(100.0)
    assert r.vias_ned_m.shape == (0, 3)


def test_goes_around_an_exclusion_circle_keeping_the_margin() -> None:
    fence = Geofence((CircleZone((50.0, 0.0), 10.0, False),))
    r = KnownWorld(fence, 3.0).route((0.0, 0.0, ALT), (100.0, 0.0, -20.0))
    assert r.ok and len(r.path_ned_m) > 2
    assert _clear(fence, r.path_ned_m, 2.99)  # the whole path keeps the 3 m margin
    assert 100.0 < r.length_m < 100.0 + 2 * 13.0  # goes round, not far round
    assert r.path_ned_m[0, 2] == ALT and r.path_ned_m[-1, 2] == -20.0  # altitude interpolated


def test_polygon_wall_across_the_route_and_a_tall_obstacle_past_it() -> None:
    wall = PolygonZone(((40.0, -30.0), (40.0, 30.0), (45.0, 30.0), (45.0, -30.0)), False)
    fence = Geofence((wall,))
    world = KnownWorld(fence, 2.0, (ObstacleDisc((50.0, -34.0), 8.0, label="tower"),))
    r = world.route((0.0, 0.0, ALT), (100.0, 0.0, ALT))
    assert r.ok and _clear(fence, r.path_ned_m, 1.99)
    assert np.all(r.path_ned_m[:, 1] >= 0.0)  # the tower closes the west end: around the east end
    xy = r.path_ned_m[:, :2]
    for a, b in itertools.pairwise(xy):  # the tower's disc is never crossed
        t = np.clip(np.dot((50.0, -34.0) - a, b - a) / np.dot(b - a, b - a), 0.0, 1.0)
        assert np.hypot(*(a + t * (b - a) - (50.0, -34.0))) >= 8.0 - 1e-6


def test_an_obstacle_below_the_leg_does_not_block_it() -> None:
    low = ObstacleDisc((50.0, 0.0), 5.0, -math.inf, 4.0)
    world = KnownWorld(Geofence(), 2.0, (low,))
    assert len(world.route((0.0, 0.0, ALT), (100.0, 0.0, ALT), r_safe_m=2.0).path_ned_m) == 2
    assert len(world.route((0.0, 0.0, -5.0), (100.0, 0.0, -5.0), r_safe_m=2.0).path_ned_m) > 2


def test_concave_inclusion_is_never_left() -> None:
    fence = Geofence((PolygonZone(U_INCLUSION, True),))
    r = KnownWorld(fence, 1.0).route((25.0, 25.0, ALT), (25.0, 5.0, ALT))
    assert r.ok and _clear(fence, r.path_ned_m, 0.99)
    assert r.length_m > 40.0  # down the U, not across its notch


def test_no_route_reasons() -> None:
    fence = Geofence((CircleZone((50.0, 0.0), 10.0, False), CircleZone((0.0, 0.0), 300.0, True)))
    world = KnownWorld(fence, 3.0)
    assert "goal inside exclusion circle 1" in world.route((0.0, 0.0, ALT), (50.0, 0.0, ALT)).reason
    assert "outside the inclusion fence" in world.route((0.0, 0.0, ALT), (900.0, 0.0, ALT)).reason
    ring = PolygonZone(((40.0, -60.0), (40.0, 60.0), (45.0, 60.0), (45.0, -60.0)), False)
    walled = KnownWorld(Geofence((ring, CircleZone((0.0, 0.0), 50.0, True))), 3.0)
    r = walled.route((0.0, 0.0, ALT), (47.0, 0.0, ALT))
    assert not r.ok and r.reason.startswith("no path")
    assert not world.route((0.0, math.nan, ALT), (10.0, 0.0, ALT)).ok


def test_start_within_the_margin_leaves_without_crossing_the_zone() -> None:
    fence = Geofence((CircleZone((50.0, 0.0), 10.0, False),))
    r = KnownWorld(fence, 3.0).route((50.0, -11.5, ALT), (50.0, 11.5, ALT))  # both ends inside the margin
    assert r.ok and _clear(fence, r.path_ned_m, 0.0) and r.length_m > 23.0


def test_bad_margin_is_refused_with_a_reason() -> None:
    with pytest.raises(ValueError, match="margin"):
        KnownWorld(Geofence(), math.nan)


def test_tracked_obstacles_become_inflated_columns() -> None:
    column = TrackedObstacle(3, ObstacleKind.COLUMN, (20.0, 5.0, -5.0), 2.0, 0, 0, 1, top_down=-25.0)
    ball = TrackedObstacle(4, ObstacleKind.SPHERE, (30.0, 0.0, -10.0), 1.5, 0, 0, 1)
    c, s = obstacle_discs((column, ball), r_safe_m=2.0, margin_m=0.5)
    assert c.radius_m == pytest.approx(4.5) and c.top_alt_m == pytest.approx(25.0) and c.label == "obstacle 3"
    assert (s.bottom_alt_m, s.top_alt_m) == pytest.approx((8.5, 11.5))
