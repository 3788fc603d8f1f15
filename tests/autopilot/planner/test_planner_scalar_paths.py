"""The planner's scalar (plain-Python) hot paths agree with the vectorised reference geometry.

The planner evaluates a few points against a few obstacles every control step in plain Python (numpy's
per-call overhead dominates there); these tests pin each fast path to the numpy function it replaces.
"""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest

from autopilot.planner.bezier import bezier_eval, fit_detour, hodograph
from autopilot.planner.detour_checks import polyline_blocker
from autopilot.planner.detour_geometry import RoutePolyline
from autopilot.planner.obstacle_map import ObstacleArrays, ObstacleKind, TrackedObstacle, row_signed_distance
from autopilot.planner.threat import _entry_fraction, inflated_segment_hit


def _random_obstacles(rng: np.random.Generator, n: int, capped: bool = False) -> tuple[TrackedObstacle, ...]:
    out = []
    for i in range(n):
        kind = ObstacleKind.SPHERE if rng.random() < 0.5 else ObstacleKind.COLUMN
        top = float(rng.uniform(-20.0, -5.0)) if capped and kind is ObstacleKind.COLUMN else -math.inf
        center = tuple(float(x) for x in rng.uniform((-10, -10, -15), (10, 10, -5)))
        out.append(TrackedObstacle(i, kind, center, float(rng.uniform(0.5, 3.0)), 0, 0, 1, top))
    return tuple(out)


@pytest.mark.parametrize("capped", [False, True])
def test_row_distance_matches_arrays(capped: bool) -> None:
    rng = np.random.default_rng(1)
    arrays = ObstacleArrays(_random_obstacles(rng, 12, capped))
    points = rng.uniform((-15, -15, -25), (15, 15, 0), size=(200, 3))
    reference = arrays.signed_distance(points)
    scalar = np.array([[row_signed_distance(row, tuple(p)) for row in arrays.rows] for p in points.tolist()])
    assert scalar == pytest.approx(reference, abs=1e-9)
    assert arrays.signed_distance(points, [3, 7]) == pytest.approx(reference[:, [3, 7]], abs=1e-12)
    assert arrays.nearest_distance(tuple(points[0])) == pytest.approx(reference[0].min())


def test_entry_fraction_matches_segment_intersections() -> None:
    rng = np.random.default_rng(2)
    obstacles = _random_obstacles(rng, 10, capped=True)
    rows = ObstacleArrays(obstacles).rows
    hits = 0
    for _ in range(300):
        a, b = rng.uniform((-15, -15, -25), (15, 15, 0), size=(2, 3))
        for obs, row in zip(obstacles, rows, strict=True):
            ref = inflated_segment_hit(obs, a, b, 1.5)
            got = _entry_fraction(row, tuple(a), tuple(b), 1.5)
            assert (ref is None) == (got is None)
            if ref is not None:
                hits += 1
                assert got == pytest.approx(ref[0], abs=1e-9)
    assert hits > 50  # the sample exercises hits, not only misses


def test_polyline_blocker_matches_dense_sampling() -> None:
    """The exact per-segment check names the obstacle a 1 cm sampling of the polyline finds furthest inside."""
    rng = np.random.default_rng(3)
    for _ in range(40):
        arrays = ObstacleArrays(_random_obstacles(rng, 6))
        poly = rng.uniform((-15, -15, -15), (15, 15, -5), size=(4, 3))
        need = [2.0] * len(arrays)
        dense = np.concatenate([a + (b - a) * np.linspace(0, 1, 2000)[:, None] for a, b in itertools.pairwise(poly)])
        short = (2.0 - arrays.signed_distance(dense)).max(axis=0)
        expected = int(arrays.ids[int(short.argmax())]) if short.max() > 1e-3 else -1
        got = polyline_blocker([tuple(p) for p in poly.tolist()], arrays.rows, need)
        if abs(short.max()) > 1e-3:
            assert got == expected


def test_route_arc_length_lookups() -> None:
    route = RoutePolyline([(0.0, 0.0, 0.0), (10.0, 0.0, 0.0), (10.0, 0.0, 0.0), (10.0, 5.0, 0.0)])
    assert route.at(4.0) == ((4.0, 0.0, 0.0), (1.0, 0.0, 0.0), 0)
    assert route.at(12.0) == ((10.0, 2.0, 0.0), (0.0, 1.0, 0.0), 2)  # the zero-length leg is skipped
    assert route.at(99.0) == ((10.0, 5.0, 0.0), (0.0, 1.0, 0.0), 2)  # clamped to the end
    assert route.stretch(8.0, 4.0) == [(8.0, 0.0, 0.0), (10.0, 0.0, 0.0), (10.0, 0.0, 0.0), (10.0, 2.0, 0.0)]


def test_bezier_state_tuple_matches_bernstein_and_hodographs() -> None:
    pts = np.array([[0.0, 0.0, -10.0], [8.0, 3.0, -10.5], [16.0, 4.0, -11.0], [24.0, 0.0, -10.0]])
    path = fit_detour(pts, np.array([5.0, 0.0, 0.0]), np.array([5.0, -1.0, 0.0]), 6.0, 3.0)
    start = 0.0
    for ctrl, duration in zip(path.ctrl_ned, path.durations_s, strict=True):
        for u in (0.0, 0.3, 0.77, 1.0):
            t = start + u * float(duration)
            if t >= path.duration_s:
                continue
            pos, vel, acc = path.state_tuple(t)
            assert pos == pytest.approx(bezier_eval(ctrl, np.array([u]))[0])
            vel_ctrl = hodograph(ctrl, float(duration))
            assert vel == pytest.approx(bezier_eval(vel_ctrl, np.array([u]))[0])
            if 0.0 < u < 1.0:  # the chain is C1: acceleration jumps at the joints
                assert acc == pytest.approx(bezier_eval(hodograph(vel_ctrl, float(duration)), np.array([u]))[0])
        start += float(duration)
    end_pos, _, end_acc = path.state_tuple(path.duration_s + 1.0)
    assert end_pos == pytest.approx(tuple(pts[-1])) and end_acc == (0.0, 0.0, 0.0)
