"""Right of way and the sense of a resolution: antisymmetric between two vehicles (no mirroring)."""

from __future__ import annotations

import numpy as np

from autopilot.traffic.rules import Role, climbs, right_of_encounter, role
from autopilot.traffic.tracks import TrafficTrack
from mavlink_bridge.contract.traffic import TrafficSource


def _track(source: TrafficSource, target_id: int, vel: tuple[float, float, float]) -> TrafficTrack:
    return TrafficTrack(source, target_id, "", (0.0, 0.0, 0.0), vel, 0)


def test_manned_traffic_always_has_right_of_way() -> None:
    heli = _track(TrafficSource.MANNED, 1, (40.0, 0.0, 0.0))
    assert role(1, heli, (5.0, 0.0, 0.0), (500.0, 100.0, 0.0)) is Role.GIVE_WAY


def test_higher_system_id_gives_way_and_both_give_way_head_on() -> None:
    crossing_vel, rel = (0.0, 5.0, 0.0), (50.0, -50.0, 0.0)
    assert role(2, _track(TrafficSource.UAV, 1, crossing_vel), (5.0, 0.0, 0.0), rel) is Role.GIVE_WAY
    assert role(1, _track(TrafficSource.UAV, 2, crossing_vel), (5.0, 0.0, 0.0), rel) is Role.STAND_ON
    head_on = _track(TrafficSource.UAV, 2, (-5.0, 0.3, 0.0))
    assert role(1, head_on, (5.0, 0.0, 0.0), (100.0, 2.0, 0.0)) is Role.GIVE_WAY


def test_both_vehicles_resolve_to_opposite_sides_on_random_geometries() -> None:
    """Each turns right of its velocity relative to the other: the two directions are exactly opposite, so the
    two displacements add up (the mirror case, both moving the same way, cannot happen)."""
    rng = np.random.default_rng(3)
    for _ in range(500):
        pa, pb = rng.uniform(-200, 200, 3), rng.uniform(-200, 200, 3)
        va, vb = rng.uniform(-8, 8, 3), rng.uniform(-8, 8, 3)
        if rng.random() < 0.1:
            vb = va.copy()  # no relative motion: away from each other
        da = right_of_encounter(tuple(pb - pa), tuple(vb - va), 1, 2)
        db = right_of_encounter(tuple(pa - pb), tuple(va - vb), 2, 1)
        assert np.allclose(np.array(da), -np.array(db))
    assert right_of_encounter((0.0, 0.0, 3.0), (0.0, 0.0, 0.0), 1, 2) == (0.0, 1.0)
    assert right_of_encounter((0.0, 0.0, -3.0), (0.0, 0.0, 0.0), 2, 1) == (0.0, -1.0)


def test_head_on_both_turn_right_of_their_own_course() -> None:
    east_of_northbound = right_of_encounter((100.0, 0.0, 0.0), (-10.0, 0.0, 0.0), 1, 2)
    assert east_of_northbound == (0.0, 1.0)


def test_vertical_sense_is_opposite_between_two_uavs() -> None:
    assert climbs(1, _track(TrafficSource.UAV, 2, (0, 0, 0)), 0.0, 5.0, 5.0)
    assert not climbs(2, _track(TrafficSource.UAV, 1, (0, 0, 0)), 0.0, 5.0, 5.0)
    assert not climbs(1, _track(TrafficSource.MANNED, 7, (0, 0, 0)), 0.0, 40.0, 20.0)  # the nearer way out
