"""Obstacle map: detections -> volumes (frames), track by id, merge overlapping, forget stale; threat choice."""

from __future__ import annotations

import math

import numpy as np
import pytest

from autopilot.planner.obstacle_map import ObstacleKind, ObstacleMap, TrackedObstacle
from autopilot.planner.threat import assess_threat
from mavlink_bridge.contract.frames import quat_from_euler
from mavlink_bridge.contract.wire import ObstacleDetection, ObstacleShape

POS = np.array([0.0, 0.0, -10.0])


def test_detection_in_body_frame_becomes_world_sphere() -> None:
    m = ObstacleMap()
    q_east = quat_from_euler(0.0, 0.0, math.pi / 2)  # nose east: body forward = NED east
    det = ObstacleDetection(0, 7, (8.0, 0.0, 0.0), 2.0, ObstacleShape.SPHERE)
    assert m.update(0, POS, q_east, [det]) == {7}
    (obs,) = m.obstacles
    assert obs.kind is ObstacleKind.SPHERE
    assert obs.center_ned == pytest.approx((0.0, 10.0, -10.0), abs=1e-9)  # surface 8 m east + radius 2
    assert obs.radius_m == pytest.approx(2.0)


def test_cylinder_and_box_detections_are_columns() -> None:
    m = ObstacleMap()
    q = quat_from_euler(0.0, 0.0, 0.0)
    m.update(0, POS, q, [ObstacleDetection(0, 1, (10.0, 0.0, 3.0), 3.0, ObstacleShape.CYLINDER)])
    (obs,) = m.obstacles
    assert obs.kind is ObstacleKind.COLUMN and obs.center_ned[:2] == pytest.approx((13.0, 0.0))
    # a column blocks every altitude: points far above/below at the axis are inside
    assert obs.signed_distance(np.array([[13.0, 0.0, -80.0], [13.0, 0.0, -0.5]])) == pytest.approx([-3.0, -3.0])


def test_same_id_is_tracked_with_range_weighting() -> None:
    m = ObstacleMap()
    q = quat_from_euler(0.0, 0.0, 0.0)
    far = ObstacleDetection(0, 1, (20.0, 1.0, 0.0), 2.0, ObstacleShape.SPHERE)  # noisy far reading
    near = ObstacleDetection(100_000, 1, (5.0, 0.0, 0.0), 2.0, ObstacleShape.SPHERE)
    m.update(0, POS + np.array([-15.0, 0, 0]), q, [far])
    m.update(100_000, POS, q, [near])
    (obs,) = m.obstacles
    assert obs.detections == 2 and obs.last_seen_us == 100_000
    # the near reading (true centre (7, 0)) dominates the far one (centre ~ (7, 1.1))
    assert abs(obs.center_ned[1]) < 0.3


def test_overlapping_detections_merge_and_distinct_ones_do_not() -> None:
    m = ObstacleMap(merge_m=0.5)
    q = quat_from_euler(0.0, 0.0, 0.0)
    m.update(0, POS, q, [ObstacleDetection(0, 1, (10.0, 0.0, 0.0), 2.0, ObstacleShape.SPHERE)])
    # a second id seen 0.5 m from the first: the same obstacle -> merged into track 1
    changed = m.update(0, POS, q, [ObstacleDetection(0, 2, (10.0, 0.5, 0.0), 2.0, ObstacleShape.SPHERE)])
    assert [o.obstacle_id for o in m.obstacles] == [1]
    assert changed == {1} and m.obstacles[0].radius_m > 2.0  # grown to enclose both
    m.update(0, POS, q, [ObstacleDetection(0, 3, (10.0, 8.0, 0.0), 1.0, ObstacleShape.SPHERE)])
    assert sorted(o.obstacle_id for o in m.obstacles) == [1, 3]


def test_forget_after_timeout() -> None:
    m = ObstacleMap(forget_s=2.0)
    q = quat_from_euler(0.0, 0.0, 0.0)
    m.update(0, POS, q, [ObstacleDetection(0, 1, (10.0, 0.0, 0.0), 2.0, ObstacleShape.SPHERE)])
    m.update(1_500_000, POS, q, [ObstacleDetection(0, 2, (10.0, 9.0, 0.0), 1.0, ObstacleShape.SPHERE)])
    assert len(m.obstacles) == 2
    m.update(2_100_000, POS, q, [])
    assert [o.obstacle_id for o in m.obstacles] == [2]
    m.update(3_600_000, POS, q, [])
    assert m.obstacles == ()


def _sphere(oid: int, n: float, e: float, r: float) -> TrackedObstacle:
    return TrackedObstacle(oid, ObstacleKind.SPHERE, (n, e, -10.0), r, 0, 0, 1)


def test_threat_is_the_first_conflict_on_the_route_or_velocity() -> None:
    obstacles = (_sphere(1, 30.0, 0.0, 2.0), _sphere(2, 15.0, 3.0, 1.0), _sphere(3, 0.0, 10.0, 1.0))
    route = np.array([[60.0, 0.0, -10.0]])
    vel = np.array([5.0, 0.0, 0.0])
    t = assess_threat(POS, vel, route, obstacles, r_safe_m=2.5, lookahead_m=40.0)
    assert t is not None and t.obstacle.obstacle_id == 2  # 3 m off the route < 1 + 2.5: nearer than #1
    assert t.entry_distance_m == pytest.approx(15.0 - math.sqrt(3.5**2 - 9.0))
    assert t.time_to_contact_s == pytest.approx(t.entry_distance_m / 5.0)
    assert assess_threat(POS, vel, route, obstacles, r_safe_m=1.5, lookahead_m=40.0).obstacle.obstacle_id == 1
    assert assess_threat(POS, vel, route, obstacles, r_safe_m=1.5, lookahead_m=20.0) is None
    # flying sideways toward #3 (velocity ray) while the route is clear of it
    t3 = assess_threat(POS, np.array([0.0, 5.0, 0.0]), route, obstacles[2:], 1.5, 40.0)
    assert t3 is not None and not t3.on_route


def test_forget_drops_the_tracks_of_sensor_ids_and_their_aliases() -> None:
    """A detection known to be a tracked vehicle leaves the map (navigator.sense); other obstacles stay."""
    m = ObstacleMap()
    q = quat_from_euler(0.0, 0.0, 0.0)
    m.update(0, POS, q, [ObstacleDetection(0, 3, (8.0, 0.0, 0.0), 1.0, ObstacleShape.SPHERE),
                         ObstacleDetection(0, 9, (8.0, 6.0, 0.0), 1.0, ObstacleShape.SPHERE)])  # fmt: skip
    assert {o.obstacle_id for o in m.obstacles} == {3, 9}
    assert m.forget({9, 42}) is True
    assert [o.obstacle_id for o in m.obstacles] == [3] and len(m.arrays) == 1
    assert m.forget({9}) is False  # nothing left of it: the snapshot stays
    m.update(100_000, POS, q, [ObstacleDetection(100_000, 9, (8.0, 6.0, 0.0), 1.0, ObstacleShape.SPHERE)])
    assert {o.obstacle_id for o in m.obstacles} == {3, 9}  # seen again (not associated): an obstacle again
