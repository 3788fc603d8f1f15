"""Bézier hodograph bounds really bound velocity and acceleration; the fitted detour meets its limits."""

from __future__ import annotations

import numpy as np
import pytest

from autopilot.planner.bezier import LIMIT_RTOL, bezier_eval, derivative_bounds, fit_detour, hodograph


def _numeric_derivatives(ctrl: np.ndarray, duration_s: float) -> tuple[np.ndarray, np.ndarray]:
    t = np.linspace(0.0, 1.0, 4001)
    p = bezier_eval(ctrl, t)
    dt = duration_s * (t[1] - t[0])
    v = np.gradient(p, dt, axis=0)
    a = np.gradient(v, dt, axis=0)
    return np.linalg.norm(v, axis=1)[2:-2], np.linalg.norm(a, axis=1)[2:-2]


@pytest.mark.parametrize("degree", [3, 5, 7])
def test_hodograph_hull_bounds_velocity_and_acceleration(degree: int) -> None:
    rng = np.random.default_rng(degree)
    for _ in range(20):
        ctrl = rng.uniform(-10, 10, (degree + 1, 3))
        duration = float(rng.uniform(0.5, 5.0))
        v_bound, a_bound = derivative_bounds(ctrl, duration)
        v, a = _numeric_derivatives(ctrl, duration)
        assert v.max() <= v_bound * (1 + 1e-6)
        assert a.max() <= a_bound * (1 + 1e-3)
        # the bound is attained at the ends (the curve starts/ends with the first/last hodograph point)
        assert np.linalg.norm(hodograph(ctrl, duration)[0]) == pytest.approx(v[0], rel=2e-2)


def test_hodograph_of_a_line_is_constant_velocity() -> None:
    ctrl = np.array([[0.0, 0, 0], [1.0, 0, 0], [2.0, 0, 0], [3.0, 0, 0]])
    v_bound, a_bound = derivative_bounds(ctrl, 1.5)
    assert v_bound == pytest.approx(2.0) and a_bound == pytest.approx(0.0)


def test_fit_detour_meets_limits_and_continuity() -> None:
    pts = np.array([[0, 0, -10], [19, -4, -10], [20.7, -4, -10], [22.2, -3.5, -10], [28.5, 0, -10.0]])
    v0, v1 = np.array([5.0, 0, 0]), np.array([5.0, 0, 0])
    path = fit_detour(pts, v0, v1, v_max_m_s=6.0, a_max_m_s2=3.0)
    assert path.limits_ok and path.v_bound_m_s <= 6.0 * (1 + LIMIT_RTOL) and path.a_bound_m_s2 <= 3.0 * (1 + LIMIT_RTOL)
    ts = np.linspace(0.0, path.duration_s, 3000)
    states = [path.state_at(t) for t in ts]
    pos = np.array([s[0] for s in states])
    vel = np.array([s[1] for s in states])
    acc = np.array([s[2] for s in states[:-1]])
    assert np.linalg.norm(vel, axis=1).max() <= 6.0 * (1 + LIMIT_RTOL)
    assert np.linalg.norm(acc, axis=1).max() <= 3.0 * (1 + LIMIT_RTOL)
    assert pos[0] == pytest.approx(pts[0]) and pos[-1] == pytest.approx(pts[-1])
    assert vel[0] == pytest.approx(v0)  # continuous with the vehicle
    assert np.cross(vel[-1], v1) == pytest.approx(np.zeros(3), abs=1e-9)  # leaves along the route
    for p in pts:  # passes through every via point
        assert np.linalg.norm(pos - p, axis=1).min() < 0.02
    # C1: no velocity jump anywhere (finite differences stay consistent with the analytic velocity)
    fd = np.diff(pos, axis=0) / (ts[1] - ts[0])
    assert np.abs(fd - 0.5 * (vel[1:] + vel[:-1])).max() < 0.05


def test_fit_detour_tight_limits_slow_down_instead_of_violating() -> None:
    pts = np.array([[0, 0, 0], [5, 5, 0], [10, 0, 0], [15, 5, 0.0]])
    path = fit_detour(pts, np.array([2.0, 0, 0]), np.array([2.0, 0, 0]), v_max_m_s=3.0, a_max_m_s2=1.0)
    assert path.limits_ok and path.a_bound_m_s2 <= 1.0 * (1 + LIMIT_RTOL)


def test_sample_spacing_bound() -> None:
    pts = np.array([[0, 0, 0], [10, 3, 0], [20, 0, 0.0]])
    path = fit_detour(pts, np.array([4.0, 0, 0]), np.array([4.0, 0, 0]), 5.0, 2.0)
    s = path.sample(0.3)
    assert np.linalg.norm(np.diff(s, axis=0), axis=1).max() <= 0.3


def test_sample_times_locate_each_sample_on_the_path() -> None:
    """Per-segment sampling: each sample is the path's position at its time (the planner re-checks the rest of
    a detour from the sample at the reference time on), spacing stays bounded, and long segments get more."""
    pts = np.array([[0, 0, 0], [1.5, 1.0, 0], [3, 1.5, 0], [30, 0, 0.0]])
    path = fit_detour(pts, np.array([3.0, 0, 0]), np.array([5.0, 0, 0]), 6.0, 3.0)
    samples, times = path.sample_with_times(0.4)
    assert len(samples) == len(times) and np.all(np.diff(times) > 0.0) and times[-1] == pytest.approx(path.duration_s)
    for p, t in zip(samples, times, strict=True):
        assert p == pytest.approx(path.state_at(float(t))[0], abs=1e-9)
    assert np.linalg.norm(np.diff(samples, axis=0), axis=1).max() <= 0.4
    per_segment = np.histogram(times[1:], bins=np.concatenate(([0.0], np.cumsum(path.durations_s))))[0]
    assert per_segment[-1] > 4 * per_segment[0]  # the 27 m leg is sampled densely, the 1.8 m one sparsely
