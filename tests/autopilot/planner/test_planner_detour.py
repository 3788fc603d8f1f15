"""Detour choice (paper §3.3): clears R_safe, least Euclidean cost, ruled out by ground/ceiling/fence/columns."""

from __future__ import annotations

import math

import numpy as np
import pytest

from autopilot.planner.detour import CandidateStatus, DetourLimits, DetourSide, plan_detour
from autopilot.planner.geometry import CircleZone
from autopilot.planner.obstacle_map import ObstacleKind, TrackedObstacle

POS = np.array([0.0, 0.0, -10.0])
VEL = np.array([5.0, 0.0, 0.0])
ROUTE = np.array([[60.0, 0.0, -10.0]])
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


def sphere(oid: int, n: float, e: float, alt: float, r: float) -> TrackedObstacle:
    return TrackedObstacle(oid, ObstacleKind.SPHERE, (n, e, -alt), r, 0, 0, 1)


def column(oid: int, n: float, e: float, r: float) -> TrackedObstacle:
    return TrackedObstacle(oid, ObstacleKind.COLUMN, (n, e, -10.0), r, 0, 0, 1)


def _report(result, side: DetourSide):
    return next(c for c in result.candidates if c.side is side)


def _true_clearance(samples: np.ndarray, obstacles) -> float:
    return min(float(o.signed_distance(samples).min()) for o in obstacles)


def test_chosen_detour_clears_r_safe_and_meets_limits() -> None:
    obstacles = (sphere(1, 20, 0.3, 10, 2.0),)
    result = plan_detour(POS, VEL, ROUTE, obstacles[0], obstacles, LIMITS)
    plan = result.plan
    assert plan is not None
    # dense evaluation of the curve (not just the planner's own samples)
    ts = np.linspace(0, plan.path.duration_s, 4000)
    dense = np.array([plan.path.state_at(t)[0] for t in ts])
    assert _true_clearance(dense, obstacles) >= LIMITS.r_safe_m
    assert plan.path.limits_ok and plan.path.a_bound_m_s2 <= LIMITS.a_max_m_s2 + 1e-9
    # rejoins the route past the obstacle, along it
    assert plan.rejoin_ned[1] == pytest.approx(0.0) and plan.rejoin_ned[0] > 20 + 2 + 2
    _, v_end, _ = plan.path.state_at(plan.path.duration_s)
    assert v_end[1] == pytest.approx(0.0, abs=1e-9) and v_end[0] > 0


@pytest.mark.parametrize(
    ("east_m", "alt_m", "expected"),
    [
        (0.8, 10.0, DetourSide.LEFT),  # obstacle right of the route: left is shorter
        (-0.8, 10.0, DetourSide.RIGHT),
        (0.0, 9.2, DetourSide.OVER),  # obstacle below the route: over is shorter
        (0.0, 10.8, DetourSide.UNDER),
    ],
)
def test_side_follows_euclidean_cost(east_m: float, alt_m: float, expected: DetourSide) -> None:
    obs = sphere(1, 20, east_m, alt_m, 2.0)
    result = plan_detour(POS, VEL, ROUTE, obs, (obs,), LIMITS)
    assert result.plan is not None and result.plan.side is expected
    costs = {c.side: c.cost_m for c in result.candidates}
    assert costs[expected] == min(costs.values())
    assert result.plan.cost_m == pytest.approx(costs[expected])


def test_ground_rules_under_out() -> None:
    obs = sphere(1, 20, 0.0, 4.5, 2.0)  # vehicle at 4.5 m: under would need 4.5 - 4.5 = 0 m altitude
    pos = np.array([0.0, 0.0, -4.5])
    result = plan_detour(pos, VEL, np.array([[60.0, 0.0, -4.5]]), obs, (obs,), LIMITS)
    under = _report(result, DetourSide.UNDER)
    assert under.status is CandidateStatus.RULED_OUT and under.reason == "ground"
    assert result.plan is not None and result.plan.side is not DetourSide.UNDER
    assert -result.plan.samples_ned[:, 2].min() >= LIMITS.min_agl_m - 1e-9


def test_ceiling_rules_over_out() -> None:
    obs = sphere(1, 20, 0.0, 9.5, 2.0)  # over is cheapest without a ceiling
    free = plan_detour(POS, VEL, ROUTE, obs, (obs,), LIMITS)
    assert free.plan is not None and free.plan.side is DetourSide.OVER
    capped = LIMITS.__class__(**{**{f: getattr(LIMITS, f) for f in LIMITS.__slots__}, "alt_ceiling_m": 12.0})
    result = plan_detour(POS, VEL, ROUTE, obs, (obs,), capped)
    assert _report(result, DetourSide.OVER).status is CandidateStatus.RULED_OUT
    assert _report(result, DetourSide.OVER).reason == "ceiling"
    assert result.plan is not None and result.plan.side is not DetourSide.OVER
    assert -result.plan.samples_ned[:, 2].max() <= 12.0


def test_fence_rules_a_side_out() -> None:
    obs = column(1, 20, 0.8, 2.0)  # left is cheapest ...
    free = plan_detour(POS, VEL, ROUTE, obs, (obs,), LIMITS)
    assert free.plan is not None and free.plan.side is DetourSide.LEFT
    fence = CircleZone((20.0, -6.5), 3.0)  # ... until a no-fly zone sits on the left
    fenced = LIMITS.__class__(**{**{f: getattr(LIMITS, f) for f in LIMITS.__slots__}, "fences": (fence,)})
    result = plan_detour(POS, VEL, ROUTE, obs, (obs,), fenced)
    left = _report(result, DetourSide.LEFT)
    assert left.status is CandidateStatus.BLOCKED and left.reason == "fence"
    assert result.plan is not None and result.plan.side is DetourSide.RIGHT
    for a, b in zip(result.plan.samples_ned[:-1], result.plan.samples_ned[1:], strict=True):
        assert fence.segment_clear(a, b, 0.0)


def test_column_is_never_passed_over_or_under() -> None:
    obs = column(1, 20, 0.0, 3.0)
    result = plan_detour(POS, VEL, ROUTE, obs, (obs,), LIMITS)
    assert _report(result, DetourSide.OVER).reason == "top unknown"
    assert _report(result, DetourSide.UNDER).reason == "stands on the ground"
    assert result.plan is not None and result.plan.side in (DetourSide.LEFT, DetourSide.RIGHT)
    assert _true_clearance(result.plan.samples_ned, (obs,)) >= LIMITS.r_safe_m


def test_detour_avoids_other_obstacles_or_reports_none() -> None:
    threat = column(1, 20, 0.5, 2.0)
    blocker_left = column(2, 20, -7.0, 2.0)  # closes the left gap: left is blocked by obstacle 2
    obstacles = (threat, blocker_left)
    result = plan_detour(POS, VEL, ROUTE, threat, obstacles, LIMITS)
    assert result.plan is not None and result.plan.side is DetourSide.RIGHT
    assert _true_clearance(result.plan.samples_ned, obstacles) >= LIMITS.r_safe_m
    walled = (threat, blocker_left, column(3, 20, 7.5, 2.0))
    narrow = LIMITS.__class__(**{**{f: getattr(LIMITS, f) for f in LIMITS.__slots__}, "alt_ceiling_m": 30.0})
    boxed = plan_detour(POS, VEL, ROUTE, threat, walled, narrow)
    if boxed.plan is not None:  # only a wide detour around the whole row may pass
        assert _true_clearance(boxed.plan.samples_ned, walled) >= LIMITS.r_safe_m
    else:
        assert all(c.status is not CandidateStatus.CHOSEN for c in boxed.candidates)
    assert math.isfinite(min(c.cost_m for c in result.candidates))
