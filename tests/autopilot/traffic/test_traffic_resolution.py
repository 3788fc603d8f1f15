"""The detour shapes of autopilot.traffic.resolution: rejoin before the mission target, wait beside it, move aside."""

from __future__ import annotations

import numpy as np
import pytest

from autopilot.traffic.resolution import AvoidLimits, Maneuver, OwnShip, Resolver

LIMITS = AvoidLimits(down_min_m=-120.0, down_max_m=-2.0)


def test_offset_detour_rejoins_the_leg_before_the_target_even_with_legs_after_it() -> None:
    own = OwnShip(0, (0.0, 0.0, -20.0), (5.0, 0.0, 0.0), ((150.0, 0.0, -20.0), (150.0, 300.0, -20.0)), 5.0)
    resolver = Resolver(own, LIMITS, 60.0)
    path, s_after = resolver.offset(Maneuver.RIGHT, (0.0, 15.0, 0.0), (5.0, 10.0))
    assert s_after is not None and s_after < 150.0
    end = path.end_ned
    assert end[1] == pytest.approx(0.0) and end[0] < 150.0  # back on the first leg, before the target
    lateral = np.abs(path.sample(0.5)[:, 1])
    assert 14.9 < lateral.max() < 18.0  # the offset is reached (the C1 curve overshoots it a little outward)
    assert path.v_bound_m_s <= LIMITS.v_max_m_s * 1.001 and path.a_bound_m_s2 <= LIMITS.a_max_m_s2 * 1.001


def test_window_past_the_target_waits_beside_it() -> None:
    own = OwnShip(0, (0.0, 0.0, -20.0), (5.0, 0.0, 0.0), ((60.0, 0.0, -20.0), (60.0, 300.0, -20.0)), 5.0)
    path, s_after = Resolver(own, LIMITS, 60.0).offset(Maneuver.RIGHT, (0.0, 15.0, 0.0), (10.0, 30.0))
    assert s_after is None  # holds the end until the traffic is clear
    assert tuple(path.end_ned) == pytest.approx((60.0, 15.0, -20.0), abs=1e-6)
    _, vel, _ = path.state_tuple(path.duration_s)
    assert np.linalg.norm(vel) == pytest.approx(0.0, abs=1e-6)


def test_hovering_vehicle_moves_aside_and_holds() -> None:
    own = OwnShip(0, (10.0, 10.0, -20.0), (0.0, 0.0, 0.0), (), 5.0)
    path, s_after = Resolver(own, LIMITS, 60.0).offset(Maneuver.CLIMB, (0.0, 0.0, -7.0), (3.0, 8.0))
    assert s_after is None and tuple(path.end_ned) == pytest.approx((10.0, 10.0, -27.0), abs=1e-6)
    assert path.duration_s < 10.0  # at cruise speed, not crawling


# Encounter campaign case 85 (vertical, 4 vehicles), vehicle 2 at 76.6 s: 2 m short of its last waypoint at 10 m,
# flying 3.2 m/s, it resolved "descend 5 m, hold" with a curve starting at 16.5 m/s² down (faster than gravity:
# the motors cut), entered its LAND item 0.1 s later with that reference and hit the ground at 9.4 m/s.
CASE_85_OWN = OwnShip(0, (60.37, -117.65, -9.96), (1.3, -2.97, 0.02), ((61.32, -119.83, -9.99), (61.32, -119.83, 0.0)))


@pytest.mark.parametrize("down_m", [5.0, -5.0])
def test_vertical_offset_beside_a_close_target_is_within_the_limits(down_m: float) -> None:
    resolver = Resolver(CASE_85_OWN, LIMITS, 20.0)
    path, s_after = resolver.offset(Maneuver.DESCEND, (0.0, 0.0, down_m), (3.0, 8.0))
    assert s_after is None  # waits beside the target
    assert path.limits_ok
    assert path.a_bound_m_s2 <= LIMITS.a_max_m_s2 * 1.001 and path.v_bound_m_s <= LIMITS.v_max_m_s * 1.001
    assert tuple(path.end_ned) == pytest.approx((61.32, -119.83, -9.99 + down_m), abs=1e-6)


def test_a_candidate_beyond_the_acceleration_limit_is_refused() -> None:
    resolver = Resolver(CASE_85_OWN, LIMITS, 20.0)
    path, _ = resolver.offset(Maneuver.RIGHT, (3.0, 3.0, 0.0), (3.0, 8.0))  # a sharp turn 4 m aside: no fit
    assert not path.limits_ok
    assert resolver._where_refused(path) == "beyond the speed or acceleration limit"
    chosen = resolver.choose([(Maneuver.RIGHT, 4.2, (3.0, 3.0, 0.0))], (3.0, 8.0), [], [])
    assert chosen.maneuver is Maneuver.STOP and chosen.path is not None and chosen.path.limits_ok
    assert chosen.refused == ("turn right: beyond the speed or acceleration limit",)
