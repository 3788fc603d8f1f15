"""Segment/sphere, segment/box (rotated) and segment/cylinder intersections; signed distances; fence zones."""

from __future__ import annotations

import math

import numpy as np
import pytest

from autopilot.planner.geometry import (
    CircleZone,
    PolygonZone,
    box_signed_distance,
    cylinder_signed_distance,
    path_clear_of_fences,
    segment_box_intersection,
    segment_cylinder_intersection,
    segment_sphere_intersection,
    sphere_signed_distance,
)

A = np.array([0.0, 0.0, -10.0])
B = np.array([20.0, 0.0, -10.0])


def test_segment_sphere_hit_miss_and_tangent_fractions() -> None:
    hit = segment_sphere_intersection(A, B, np.array([10.0, 0.0, -10.0]), 2.0)
    assert hit == pytest.approx((0.4, 0.6))
    assert segment_sphere_intersection(A, B, np.array([10.0, 2.01, -10.0]), 2.0) is None
    assert segment_sphere_intersection(A, B, np.array([10.0, 0.0, -12.0]), 2.0) == pytest.approx((0.5, 0.5))
    # sphere beyond the segment end, and a segment starting inside
    assert segment_sphere_intersection(A, B, np.array([23.0, 0.0, -10.0]), 2.0) is None
    assert segment_sphere_intersection(A, B, np.array([1.0, 0.0, -10.0]), 2.0) == pytest.approx((0.0, 0.15))


def test_segment_box_axis_aligned_and_rotated() -> None:
    half = np.array([1.0, 3.0, 2.0])
    center = np.array([10.0, 2.5, -10.0])
    assert segment_box_intersection(A, B, center, half, 0.0) == pytest.approx((0.45, 0.55))
    # rotated 90°: the long side (3 m) now lies along north, the short (1 m) along east -> misses y=0
    assert segment_box_intersection(A, B, center, half, math.pi / 2) is None
    # rotated 45°: half-diagonal reach across east is (1+3)/sqrt(2) = 2.83 > 2.5 -> hits
    assert segment_box_intersection(A, B, center, half, math.pi / 4) is not None
    # above the box top (down -12): no hit
    assert segment_box_intersection(A + np.array([0, 0, -2.5]), B + np.array([0, 0, -2.5]), center, half, 0.0) is None


def test_segment_box_matches_signed_distance_sampling() -> None:
    rng = np.random.default_rng(3)
    center, half, yaw = np.array([5.0, -1.0, -4.0]), np.array([2.0, 1.0, 3.0]), 0.7
    for _ in range(200):
        a, b = rng.uniform(-5, 15, 3), rng.uniform(-5, 15, 3)
        a[2], b[2] = -abs(a[2]), -abs(b[2])
        t = np.linspace(0, 1, 2001)
        inside = box_signed_distance(a + t[:, None] * (b - a), center, half, yaw) <= 0
        hit = segment_box_intersection(a, b, center, half, yaw)
        assert (hit is not None) == bool(inside.any()) or abs(inside.mean()) < 2e-3
        if hit is not None and inside.any():
            assert t[inside].min() == pytest.approx(hit[0], abs=2e-3)


def test_segment_cylinder_vertical_extent() -> None:
    c = np.array([10.0, 0.0])
    assert segment_cylinder_intersection(A, B, c, 3.0, top_down=-20.0, bottom_down=0.0) == pytest.approx((0.35, 0.65))
    # the cylinder is only 8 m tall (top at down = -8): flying at 10 m clears it
    assert segment_cylinder_intersection(A, B, c, 3.0, top_down=-8.0, bottom_down=0.0) is None
    # a descending segment enters through the top cap
    hit = segment_cylinder_intersection(np.array([10.0, 0, -20]), np.array([10.0, 0, -4]), c, 3.0, -8.0, 0.0)
    assert hit == pytest.approx((0.75, 1.0))


def test_signed_distances() -> None:
    p = np.array([[13.0, 4.0, -10.0], [10.0, 0.0, -10.0]])
    assert sphere_signed_distance(p, np.array([10.0, 0.0, -10.0]), 2.0) == pytest.approx([3.0, -2.0])
    d = cylinder_signed_distance(np.array([[10.0, 0.0, -11.0], [14.0, 0.0, -5.0]]), np.array([10.0, 0.0]), 1.0, -8.0)
    assert d == pytest.approx([3.0, 3.0])  # above the top cap by 3 m; beside the wall by 3 m
    d = box_signed_distance(np.array([[0.0, 0.0, 0.0], [3.0, 0.0, 0.0]]), np.zeros(3), np.ones(3), 0.0)
    assert d == pytest.approx([-1.0, 2.0])


def test_fence_zones() -> None:
    excl = CircleZone((10.0, 0.0), 3.0)
    incl = CircleZone((0.0, 0.0), 50.0, inclusion=True)
    poly = PolygonZone(((8.0, -2.0), (8.0, 2.0), (12.0, 2.0), (12.0, -2.0)))
    assert excl.violates(np.array([10.0, 1.0, -5.0])) and not excl.violates(np.array([0.0, 0.0, -5.0]))
    assert not excl.segment_clear(A, B, 0.0)
    assert excl.segment_clear(A + np.array([0, 5, 0]), B + np.array([0, 5, 0]), 1.0)
    assert not excl.segment_clear(A + np.array([0, 5, 0]), B + np.array([0, 5, 0]), 2.5)
    assert incl.violates(np.array([60.0, 0.0, 0.0])) and incl.segment_clear(A, B, 1.0)
    assert not incl.segment_clear(A, np.array([70.0, 0.0, -10.0]), 0.0)
    assert poly.violates(np.array([10.0, 0.0, -3.0])) and not poly.segment_clear(A, B, 0.0)
    assert poly.segment_clear(A + np.array([0, 3, 0]), B + np.array([0, 3, 0]), 0.5)
    assert not poly.segment_clear(A + np.array([0, 3, 0]), B + np.array([0, 3, 0]), 1.5)
    path = np.array([A, B])
    assert path_clear_of_fences((incl, poly), path, 0.0) is poly
    assert path_clear_of_fences((incl,), path, 0.0) is None
