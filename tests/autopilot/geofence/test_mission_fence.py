"""Geofence geometry: point in zone, segment clearance with margins, inclusion groups, FENCE item parsing."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from autopilot.geofence.fence import (
    CircleZone,
    FenceError,
    Geofence,
    PolygonZone,
    circle_fence_items,
    geofence_from_items,
    polygon_fence_items,
    segment_to_segments_distance,
)
from mavlink_bridge.contract.frames import GeoPoint, LocalNedFrame

HOME = GeoPoint(30.2635, 120.1233, 12.0)
SQUARE = ((10.0, -5.0), (10.0, 5.0), (20.0, 5.0), (20.0, -5.0))


def test_circle_contains_and_segment_clear() -> None:
    z = CircleZone((50.0, 0.0), 5.0, inclusion=False)
    assert z.contains((50.0, 4.9, -10.0)) and not z.contains((50.0, 5.1, -10.0))
    assert not z.segment_clear((0.0, 0.0, -10.0), (100.0, 0.0, -10.0))  # straight through
    assert z.segment_clear((0.0, 6.0, -10.0), (100.0, 6.0, -10.0))  # 1 m outside
    assert not z.segment_clear((0.0, 6.0, -10.0), (100.0, 6.0, -10.0), margin_m=1.5)
    assert z.segment_clear((0.0, 0.0, -10.0), (40.0, 0.0, -10.0), margin_m=4.0)  # stops 5 m short


def test_polygon_contains_and_segment_clear() -> None:
    z = PolygonZone(SQUARE, inclusion=False)
    assert z.contains((15.0, 0.0, 0.0)) and not z.contains((25.0, 0.0, 0.0)) and not z.contains((15.0, 6.0, 0.0))
    assert not z.segment_clear((0.0, 0.0, -5.0), (30.0, 0.0, -5.0))  # crosses two edges
    assert not z.segment_clear((0.0, 0.0, -5.0), (15.0, 0.0, -5.0))  # ends inside
    assert z.segment_clear((0.0, 7.0, -5.0), (30.0, 7.0, -5.0))  # passes 2 m east of the east edge
    assert not z.segment_clear((0.0, 7.0, -5.0), (30.0, 7.0, -5.0), margin_m=2.5)
    assert z.boundary_distance_m((15.0, 7.0, 0.0)) == pytest.approx(2.0)


def test_concave_polygon_uses_even_odd_rule() -> None:
    u_shape = (
        (0.0, 0.0),
        (0.0, 30.0),
        (30.0, 30.0),
        (30.0, 20.0),
        (10.0, 20.0),
        (10.0, 10.0),
        (30.0, 10.0),
        (30.0, 0.0),
    )
    z = PolygonZone(u_shape, inclusion=True)
    assert z.contains((5.0, 15.0, 0.0)) and not z.contains((20.0, 15.0, 0.0)) and z.contains((20.0, 5.0, 0.0))
    assert z.segment_clear((20.0, 3.0, 0.0), (5.0, 3.0, 0.0), margin_m=1.0)
    assert not z.segment_clear((20.0, 5.0, 0.0), (20.0, 25.0, 0.0))  # crosses the notch


def test_inclusion_groups_and_exclusions_combine() -> None:
    fence = Geofence(
        (
            CircleZone((0.0, 0.0), 100.0, inclusion=True, group=0),
            PolygonZone(((-10.0, -10.0), (-10.0, 200.0), (10.0, 200.0), (10.0, -10.0)), inclusion=True, group=1),
            CircleZone((50.0, 0.0), 5.0, inclusion=False),
        )
    )
    assert not fence.violates((0.0, 0.0, -10.0))
    assert fence.violates((50.0, 0.0, -10.0))  # exclusion
    assert not fence.violates((0.0, 150.0, -10.0))  # outside group 0, inside group 1
    assert fence.violates((150.0, 0.0, -10.0))  # outside both groups
    assert fence.violates((0.0, 97.0, -10.0), margin_m=5.0) is False  # group 1 still holds it with margin
    assert fence.violates((95.0, 0.0, -10.0), margin_m=6.0)
    assert fence.segment_clear((0.0, 0.0, 0.0), (0.0, 150.0, 0.0))  # along the corridor of group 1
    assert not fence.segment_clear((0.0, 0.0, 0.0), (150.0, 0.0, 0.0))
    assert not fence.segment_clear((30.0, 0.0, 0.0), (70.0, 0.0, 0.0))  # through the exclusion
    assert Geofence().segment_clear((0.0, 0.0, 0.0), (1e6, 0.0, 0.0)) and not Geofence().violates((1e6, 0.0, 0.0))


def test_segment_distance_matches_brute_force() -> None:
    rng = np.random.default_rng(3)
    for _ in range(20):
        a, b = rng.uniform(-10, 10, 2), rng.uniform(-10, 10, 2)
        starts, ends = rng.uniform(-10, 10, (4, 2)), rng.uniform(-10, 10, (4, 2))
        got = segment_to_segments_distance(a, b, starts, ends)
        t = np.linspace(0.0, 1.0, 201)
        for k in range(4):
            p = a + t[:, None] * (b - a)
            q = starts[k] + t[:, None] * (ends[k] - starts[k])
            brute = np.min(np.linalg.norm(p[:, None, :] - q[None, :, :], axis=-1))
            assert got[k] == pytest.approx(brute, abs=0.15)


def test_zones_from_fence_items_round_trip_geometry() -> None:
    frame = LocalNedFrame(HOME)
    c = frame.geodetic_from_ned(60.0, 10.0, 0.0)
    verts = [frame.geodetic_from_ned(n, e, 0.0) for n, e in SQUARE]
    items = circle_fence_items(0, c.lat_deg, c.lon_deg, 8.0, inclusion=False)
    items += polygon_fence_items(1, [(v.lat_deg, v.lon_deg) for v in verts], inclusion=True, group=2)
    fence = geofence_from_items(items, HOME)
    circle, poly = fence.zones
    assert isinstance(circle, CircleZone) and circle.center_ne_m == pytest.approx((60.0, 10.0), abs=1e-6)
    assert isinstance(poly, PolygonZone) and poly.inclusion and poly.group == 2
    assert np.allclose(poly.vertices_ne_m, SQUARE, atol=1e-6)
    bad = [*items[:3], replace(items[3], param1=3.0), items[4]]
    with pytest.raises(FenceError, match="fence item 3: polygon vertex 3 of 4"):
        geofence_from_items(bad, HOME)


@pytest.mark.parametrize("inclusion", [True, False])
def test_allowed_distance_is_the_boundary_distance_signed_by_the_allowed_side(inclusion: bool) -> None:
    """Positive on the allowed side (inside an inclusion, outside an exclusion), negative on the other, for a circle
    and the same square as a polygon; the polygon's edges are built once and reused."""
    circle = CircleZone((0.0, 0.0), 10.0, inclusion)
    square = PolygonZone(((-10.0, -10.0), (-10.0, 10.0), (10.0, 10.0), (10.0, -10.0)), inclusion)
    sign = 1.0 if inclusion else -1.0
    assert circle.allowed_distance_m((3.0, 4.0, -5.0)) == pytest.approx(sign * 5.0)
    assert circle.allowed_distance_m((30.0, 40.0)) == pytest.approx(-sign * 40.0)
    assert square.allowed_distance_m((0.0, 7.0)) == pytest.approx(sign * 3.0)
    assert square.allowed_distance_m((0.0, 14.0)) == pytest.approx(-sign * 4.0)
    assert square._edges()[0] is square._edges()[0]
