"""MissionRouter (issue 13): legs routed around the fence on events, via points passed, detour rejoins mapped
back to mission items, replans after a HOLD include the tracked obstacles, no route: hold, then the action."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from autopilot.geofence.fence import CircleZone, Geofence, PolygonZone
from autopilot.planner.mission_router import MissionRouter, RouteStatus
from autopilot.planner.obstacle_map import ObstacleKind, TrackedObstacle
from autopilot.planner.param_decls import PlannerParams
from autopilot.planner.planner import PlannerState

ALT = -10.0
ROUTE = np.array([(100.0, 0.0, ALT), (100.0, 60.0, ALT)])
CIRCLE = Geofence((CircleZone((50.0, 0.0), 10.0, False),))


def test_a_clear_leg_is_direct_and_a_blocked_one_gets_via_points_planned_once() -> None:
    direct = MissionRouter(PlannerParams())
    step = direct.update(0, (0.0, 0.0, ALT), ROUTE, 1)
    assert step.status is RouteStatus.DIRECT and step.goal_ned_m == tuple(ROUTE[0]) and step.planned
    router = MissionRouter(PlannerParams(), CIRCLE)
    step = router.update(0, (0.0, 0.0, ALT), ROUTE, 1)
    assert step.status is RouteStatus.ROUTED and step.vias_left >= 1 and step.planned
    assert step.texts and step.texts[0].startswith("Route: ")
    assert np.allclose(step.route_ahead_ned_m[-2:], ROUTE)  # then the target and the next leg
    again = router.update(40_000, (0.5, 0.0, ALT), ROUTE, 1)
    assert not again.planned and not again.texts and router.searches == 1  # planned on events only
    assert router.update(80_000, (0.6, 0.0, ALT), ROUTE, 1) is again  # the same object while nothing changes


def test_via_points_are_passed_in_order_and_the_path_keeps_the_margin() -> None:
    router = MissionRouter(PlannerParams(fence_margin_m=3.0), CIRCLE)
    step = router.update(0, (0.0, 0.0, ALT), ROUTE, 1)
    path = step.path_ned_m
    assert path is not None and all(CIRCLE.segment_clear(path[i], path[i + 1], 2.99) for i in range(len(path) - 1))
    goals = []
    for k in range(step.vias_left):
        step = router.update(k + 1, step.goal_ned_m, ROUTE, 1)  # at the via point
        goals.append(step.goal_ned_m)
    assert goals[-1] == tuple(ROUTE[0]) and step.vias_left == 0


def test_rejoin_past_the_vias_and_the_target_maps_to_the_mission_item() -> None:
    router = MissionRouter(PlannerParams(), CIRCLE)
    step = router.update(0, (0.0, 0.0, ALT), ROUTE, 1)
    vias = step.vias_left
    assert router.consume(vias) == 0  # rejoined at the target: only via points bypassed
    assert router.update(1, (0.0, 0.0, ALT), ROUTE, 1).goal_ned_m == tuple(ROUTE[0])
    assert router.consume(1) == 1  # past the target: one mission point bypassed (the caller skips to the next)


def test_hold_replans_around_tracked_obstacles_and_no_route_holds_then_acts() -> None:
    params = PlannerParams(noroute_t_s=5.0, noroute_action=3)
    router = MissionRouter(params)
    router.update(0, (0.0, 0.0, ALT), ROUTE, 1)
    column = TrackedObstacle(4, ObstacleKind.COLUMN, (50.0, 0.0, ALT), 3.0, 0, 0, 5)
    step = router.update(1_500_000, (20.0, 0.0, ALT), ROUTE, 1, (column,), PlannerState.HOLD)
    assert step.status is RouteStatus.ROUTED and step.known_world and step.planned
    wall = PolygonZone(((60.0, -500.0), (60.0, 500.0), (70.0, 500.0), (70.0, -500.0)), False)
    boxed = MissionRouter(params, Geofence((wall, CircleZone((0.0, 0.0), 300.0, True))))
    step = boxed.update(0, (0.0, 0.0, ALT), ROUTE, 1)
    assert step.status is RouteStatus.NO_ROUTE and step.goal_ned_m == (0.0, 0.0, ALT)  # hold where it is
    assert step.texts[0].startswith("No route to 1: no path") and "CA_NOROUTE_ACT" in step.texts[0]
    actions = [boxed.update(t, (0.0, 0.0, ALT), ROUTE, 1).action for t in range(100_000, 7_000_000, 100_000)]
    assert actions.count(3) == 1 and actions.index(3) == 49  # once, after CA_NOROUTE_T (5 s)
    boxed.set_fence(Geofence())  # the obstacle to the route gone: the next retry finds it
    step = boxed.update(8_000_000, (0.0, 0.0, ALT), ROUTE, 1)
    assert step.status is RouteStatus.DIRECT


def test_a_new_fence_or_margin_replans_the_leg() -> None:
    router = MissionRouter(PlannerParams(), Geofence())
    assert router.update(0, (0.0, 0.0, ALT), ROUTE, 1).status is RouteStatus.DIRECT
    router.set_fence(CIRCLE)
    assert router.update(1, (0.0, 0.0, ALT), ROUTE, 1).status is RouteStatus.ROUTED
    router.set_params(replace(PlannerParams(), fence_margin_m=40.0))  # wider than the gap: the goal too
    assert router.update(2, (0.0, 0.0, ALT), ROUTE, 1).planned
