"""Where a detour rejoins the route (issue 6, round 3): the first pass of a self-crossing route, a clear
route after the rejoin point, and the waypoints it bypassed reported to the caller."""

from __future__ import annotations

import numpy as np
import pytest

from autopilot.planner.detour import DetourLimits, plan_detour
from autopilot.planner.obstacle_map import ObstacleKind, TrackedObstacle
from autopilot.planner.param_decls import PlannerParams
from autopilot.planner.planner import AvoidancePlanner, PlannerState
from autopilot.planner.reachability import unreachable_reason
from mavlink_bridge.contract.frames import quat_from_euler
from mavlink_bridge.contract.wire import ObstacleDetection, ObstacleShape

POS = np.array([0.0, 0.0, -10.0])
VEL = np.array([5.0, 0.0, 0.0])
LIMITS = DetourLimits(
    r_safe_m=2.0,
    margin_m=0.5,
    v_max_m_s=6.0,
    a_max_m_s2=3.0,
    rejoin_m=4.0,
    min_agl_m=2.0,
    alt_floor_m=0.0,
    alt_ceiling_m=120.0,
)
Q_NORTH = quat_from_euler(0.0, 0.0, 0.0)


def _clearance(points: np.ndarray, obstacles: tuple[TrackedObstacle, ...]) -> float:
    return min(float(o.signed_distance(points).min()) for o in obstacles)


def test_self_crossing_route_rejoins_after_the_first_pass() -> None:
    """The route crosses itself on the obstacle; its second pass is even nearer the centre than the first.

    The rejoin point follows the first pass (the one the vehicle is on), not the global nearest point of
    the route, which would send the detour around the whole loop.
    """
    obs = TrackedObstacle(1, ObstacleKind.SPHERE, (20.0, 0.3, -10.0), 1.5, 0, 0, 1)
    route = np.array([[40.0, 0.0, -10.0], [40.0, 15.0, -10.0], [20.0, 15.0, -10.0], [20.0, -30.0, -10.0]])
    result = plan_detour(POS, VEL, route, obs, (obs,), LIMITS)
    plan = result.plan
    assert plan is not None
    rho = 1.5 + LIMITS.r_safe_m + LIMITS.margin_m
    assert plan.rejoin_ned == pytest.approx((20.0 + rho + LIMITS.rejoin_m, 0.0, -10.0))
    assert plan.rejoin_route_index == 0  # still on the leg toward the first waypoint
    assert plan.cost_m < 40.0
    assert _clearance(plan.samples_ned, (obs,)) >= LIMITS.r_safe_m


def test_route_after_the_rejoin_point_is_clear() -> None:
    """A second column stands on the route just past where a detour around the first would rejoin (the
    clearance dip of benchmark field 22): the detour must not hand the vehicle back to the route there."""
    threat = TrackedObstacle(1, ObstacleKind.COLUMN, (20.0, 0.5, -10.0), 2.0, 0, 0, 1)
    alone = plan_detour(POS, VEL, np.array([[80.0, 0.0, -10.0]]), threat, (threat,), LIMITS)
    assert alone.plan is not None
    s_rejoin_alone = float(alone.plan.rejoin_ned[0])
    after = TrackedObstacle(2, ObstacleKind.COLUMN, (s_rejoin_alone + 6.0, -0.8, -10.0), 1.5, 0, 0, 1)
    obstacles = (threat, after)
    result = plan_detour(POS, VEL, np.array([[80.0, 0.0, -10.0]]), threat, obstacles, LIMITS)
    plan = result.plan
    assert plan is not None
    assert plan.rejoin_ned[0] > after.center_ned[0] + after.radius_m + LIMITS.r_safe_m  # past both
    assert _clearance(plan.samples_ned, obstacles) >= LIMITS.r_safe_m
    assert len(plan.continuation_ned) > 10 and _clearance(plan.continuation_ned, obstacles) >= LIMITS.r_safe_m


def _sphere_detection(time_us: int, oid: int, pos: np.ndarray, center: np.ndarray, r: float) -> ObstacleDetection:
    rel = center - pos
    surface = rel - r * rel / np.linalg.norm(rel)
    return ObstacleDetection(
        time_us, oid, (float(surface[0]), float(surface[1]), float(surface[2])), r, ObstacleShape.SPHERE
    )


def test_planner_reports_the_waypoints_a_detour_bypassed() -> None:
    """The corner waypoint lies inside the obstacle's safety volume (0.55 m from it): it cannot be reached safely,
    so the detour rejoins the leg after it.

    ``rejoin_route_index`` says so (1: resume toward the waypoint after the current target) while the detour
    is flown and after it ends, until the caller advances its target; then it reports 0.
    """
    planner = AvoidancePlanner(PlannerParams())
    center = np.array([20.0, 0.5, -10.0])
    corner, after = (22.5, 0.0, -10.0), (22.5, 40.0, -10.0)
    assert "safety volume" in unreachable_reason(corner, [_sphere(center, 2.0)], PlannerParams().r_safe_m)
    out = planner.update(0, POS, VEL, Q_NORTH, [_sphere_detection(0, 1, POS, center, 2.0)], corner, after)
    assert out.state is PlannerState.DETOUR and out.detour is not None
    assert out.detour.rejoin_route_index == 1 and out.detour.rejoin_ned[1] > 0.0  # on the leg after the corner
    assert out.rejoin_route_index == 1
    t_end_us = round(out.detour.path.duration_s * 1e6)
    for time_us in (t_end_us // 2, t_end_us + 40_000):
        sp = out.setpoint
        assert sp is not None
        pos, vel = np.array(sp.pos_ned_m), np.array(sp.vel_ned_m_s)
        out = planner.update(time_us, pos, vel, Q_NORTH, (), corner, after)
        assert out.rejoin_route_index == 1  # the caller has not advanced yet
    assert out.state is PlannerState.CLEAR and out.setpoint is None
    out = planner.update(t_end_us + 80_000, pos, vel, Q_NORTH, (), after, None)  # the caller advanced
    assert out.rejoin_route_index == 0
    assert out.state is PlannerState.CLEAR


def _sphere(center: np.ndarray, r: float, oid: int = 1) -> TrackedObstacle:
    return TrackedObstacle(oid, ObstacleKind.SPHERE, (float(center[0]), float(center[1]), float(center[2])), r, 0, 0, 1)


def test_detour_rejoins_at_a_reachable_corner_waypoint() -> None:
    """Issue 22: the corner waypoint is 4 m from the obstacle, outside its safety volume (R_safe 2 m). A rejoin
    ρ + CA_REJOIN_M past the obstacle would lie on the next leg (the corner bypassed); the detour ends at the
    corner instead, along the leg at cruise speed, and the route resumes toward it (nothing skipped)."""
    obs = _sphere(np.array([20.0, 0.5, -10.0]), 2.0)
    corner, after = np.array([26.0, 0.0, -10.0]), np.array([26.0, 40.0, -10.0])
    result = plan_detour(POS, VEL, np.array([corner, after]), obs, (obs,), LIMITS)
    plan = result.plan
    assert plan is not None
    np.testing.assert_allclose(plan.rejoin_ned, corner, atol=1e-9)
    np.testing.assert_allclose(plan.samples_ned[-1], corner, atol=1e-6)  # the curve ends on the waypoint
    assert plan.rejoin_route_index == 0 and not plan.stops_at_rejoin
    assert _clearance(plan.samples_ned, (obs,)) >= LIMITS.r_safe_m
    # the same corner flagged as a via point around the fence (not a mission item) may be passed
    via = plan_detour(POS, VEL, np.array([corner, after]), obs, (obs,), LIMITS, route_items=(False, True)).plan
    assert via is not None and via.rejoin_route_index == 1


def test_detour_stops_at_the_waypoint_when_the_route_after_it_is_blocked() -> None:
    """The leg after the reachable waypoint runs straight back past the same obstacle: handing the vehicle back
    there at speed would leave no room, so the detour ends at the waypoint at rest (the next leg starts from a
    hover and gets its own detour)."""
    obs = _sphere(np.array([20.0, 0.5, -10.0]), 2.0)
    wp, back = np.array([26.0, 0.0, -10.0]), np.array([0.0, 1.0, -10.0])
    plan = plan_detour(POS, VEL, np.array([wp, back]), obs, (obs,), LIMITS).plan
    assert plan is not None and plan.stops_at_rejoin
    np.testing.assert_allclose(plan.rejoin_ned, wp, atol=1e-9)
    end_vel = plan.path.state_tuple(plan.path.duration_s)[1]
    assert float(np.linalg.norm(end_vel)) < 1e-6
    assert _clearance(plan.samples_ned, (obs,)) >= LIMITS.r_safe_m


def test_hand_off_ray_past_a_corner_is_clear() -> None:
    """Routing benchmark world 478: the rejoin point falls 1 m before a via-point corner (not a mission item) and a
    second obstacle stands on the straight ray past the corner, off the route after it. The vehicle cannot turn at
    the corner at cruise speed; the threat check that runs when the detour ends looks along the velocity. The
    detour must not hand the vehicle back where that ray meets a safety volume."""
    threat = _sphere(np.array([20.0, 0.3, -10.0]), 2.0)
    rho = 2.0 + LIMITS.r_safe_m + LIMITS.margin_m
    corner = np.array([20.0 + rho + LIMITS.rejoin_m + 1.0, 0.0, -10.0])
    route = np.array([corner, corner + np.array((0.0, 40.0, 0.0))])  # a 90° turn 1 m after the plain rejoin point
    ahead = _sphere(corner + np.array((5.0, 0.0, 0.0)), 1.5, oid=2)  # on the straight ray past the corner
    obstacles = (threat, ahead)
    plan = plan_detour(POS, VEL, route, threat, obstacles, LIMITS, route_items=(False, True)).plan
    assert plan is not None
    end_pos, end_vel, _ = plan.path.state_tuple(plan.path.duration_s)
    speed = float(np.linalg.norm(end_vel))
    reach_m = speed**2 / (2.0 * LIMITS.a_max_m_s2) + 2.0 * speed
    if speed > 1e-6:
        ray = np.array(end_pos) + np.linspace(0.0, 1.0, 50)[:, None] * (np.array(end_vel) / speed * reach_m)
        assert _clearance(ray, obstacles) >= LIMITS.r_safe_m
    assert _clearance(plan.samples_ned, obstacles) >= LIMITS.r_safe_m


def test_detour_flies_through_the_reachable_items_before_the_obstacle() -> None:
    """A dense route (items every 4 m) runs into a sphere: the detour follows the route through the items whose
    legs are clear, leaves it after the last of them, and rejoins at the first reachable item past the sphere;
    the planner reports nothing skipped while the caller's target is one it flies through."""
    center = np.array([30.0, 0.3, -10.0])
    items = np.array([(4.0 * k, 0.0, -10.0) for k in range(1, 16)])  # 4 .. 60 m north
    planner = AvoidancePlanner(PlannerParams())
    out = planner.update(0, POS, VEL, Q_NORTH, [_sphere_detection(0, 1, POS, center, 2.0)], items[0], items[1:])
    plan = out.detour
    assert out.state is PlannerState.DETOUR and plan is not None
    obs = _sphere(center, 2.0)
    clear = [bool(obs.signed_distance(p[None, :])[0] >= PlannerParams().r_safe_m) for p in items]
    assert plan.prefix_route_index >= 3 and all(clear[: plan.prefix_route_index + 1])
    for p in items[: plan.prefix_route_index + 1]:  # flown through: on the curve
        assert float(np.min(np.linalg.norm(plan.samples_ned - p, axis=1))) < 0.3
    rejoined = items[plan.rejoin_route_index]
    np.testing.assert_allclose(plan.rejoin_ned, rejoined, atol=1e-9)  # at an item, never between two
    assert all(not c for c in clear[plan.prefix_route_index + 1 : plan.rejoin_route_index])  # skipped: unreachable
    assert out.rejoin_route_index == 0  # the target (items[0]) is flown through: nothing skipped yet
    assert _clearance(plan.samples_ned, (obs,)) >= PlannerParams().r_safe_m
