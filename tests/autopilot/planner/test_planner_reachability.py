"""The one rule for whether a waypoint can be reached safely (issue 22, SPEC §7): outside every tracked obstacle's
safety volume and outside the fence margin; otherwise the reason a bypass reports."""

from __future__ import annotations

import numpy as np

from autopilot.geofence.fence import CircleZone, Geofence
from autopilot.geofence.planner_zones import planner_fence_zones
from autopilot.planner.obstacle_map import ObstacleKind, TrackedObstacle
from autopilot.planner.reachability import unreachable_reason

COLUMN = TrackedObstacle(3, ObstacleKind.COLUMN, (10.0, 0.0, 0.0), 2.0, 0, 0, 1)
FENCE = planner_fence_zones(Geofence((CircleZone((0.0, 30.0), 5.0, False), CircleZone((0.0, 0.0), 100.0, True))))


def test_clear_waypoint_is_reachable() -> None:
    assert unreachable_reason(np.array((10.0, 4.5, -8.0)), [COLUMN], 2.0, FENCE, 3.0) == ""


def test_waypoint_in_a_safety_volume_names_the_obstacle_and_the_distance() -> None:
    why = unreachable_reason(np.array((10.0, 3.5, -8.0)), [COLUMN], 2.0, FENCE, 3.0)
    assert why == "it lies inside obstacle 3's safety volume (1.5 m from it, CA_RSAFE_M 2 m)"
    inside = unreachable_reason(np.array((10.0, 1.0, -8.0)), [COLUMN], 2.0)
    assert inside == "it lies inside obstacle 3's safety volume (1.0 m inside it, CA_RSAFE_M 2 m)"


def test_waypoint_in_the_fence_margin_is_unreachable() -> None:
    """2 m outside an exclusion circle (margin 3 m), and 2 m inside the inclusion circle's edge."""
    near_zone = unreachable_reason(np.array((0.0, 23.0, -8.0)), [], 2.0, FENCE, 3.0)
    assert near_zone == "it lies within CA_FENCE_MARG_M (3 m) of the fence"
    near_edge = unreachable_reason(np.array((98.0, 0.0, -8.0)), [], 2.0, FENCE, 3.0)
    assert near_edge == near_zone
    assert unreachable_reason(np.array((0.0, 23.0, -8.0)), [], 2.0, FENCE, 1.0) == ""  # a 1 m margin
