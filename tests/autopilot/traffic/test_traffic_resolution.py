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
