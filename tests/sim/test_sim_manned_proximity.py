"""The simulator's NMAC truth (sim.traffic.MannedProximity): closest approach to scripted aircraft and the first
time inside 500 ft horizontally and 100 ft vertically at once, for the encounter Monte Carlo."""

from __future__ import annotations

import numpy as np
import pytest

from mavlink_bridge.contract.traffic import AdsbEmitterType
from sim.fleet_world import ScriptedAircraft, TrafficWaypoint
from sim.traffic import NMAC_HOR_M, NMAC_VER_M, MannedProximity, ScriptedTraffic


def _heli(alt_m: float) -> ScriptedTraffic:
    path = (TrafficWaypoint(0.0, -1000.0, alt_m), TrafficWaypoint(0.0, 1000.0, alt_m))
    return ScriptedTraffic((ScriptedAircraft("HELI1", 0xA1B2C3, AdsbEmitterType.ROTOCRAFT, path, 50.0, 0.0),))


def test_an_aircraft_passing_inside_the_volume_is_an_nmac_and_one_above_it_is_not() -> None:
    low, high = MannedProximity(_heli(40.0), 2), MannedProximity(_heli(40.0 + NMAC_VER_M + 20.0), 2)
    pos_ned = np.array([[0.0, 0.0, -15.0], [NMAC_HOR_M + 50.0, 0.0, -15.0]])  # one under its path, one aside
    for t_s in np.arange(0.0, 40.0, 0.1):
        low.update(float(t_s), pos_ned)
        high.update(float(t_s), pos_ned)
    assert low.nmac_at_s[0] == pytest.approx(20.0 - NMAC_HOR_M / 50.0, abs=0.11)  # entering 152 m before it
    assert low.nmac_at_s[1] is None and high.nmac_at_s == [None, None]
    assert low.min_distance_m[0] == pytest.approx(25.0, abs=0.01)  # straight overhead, 25 m up
    assert high.min_distance_m[0] == pytest.approx(25.0 + NMAC_VER_M + 20.0, abs=0.01)


def test_no_aircraft_in_the_air_changes_nothing() -> None:
    empty = MannedProximity(ScriptedTraffic(()), 1)
    late = MannedProximity(_heli(40.0), 1)
    empty.update(1.0, np.zeros((1, 3)))
    late.update(100.0, np.zeros((1, 3)))  # past the end of its path: gone
    assert np.isinf(empty.min_distance_m).all() and np.isinf(late.min_distance_m).all()


def test_a_vehicle_standing_on_the_ground_under_a_low_aircraft_is_not_an_nmac() -> None:
    """NMACs are between aircraft in flight: a pad under a helicopter's path at 25 m is recorded apart."""
    proximity = MannedProximity(_heli(25.0), 3)
    # one standing on its pad, one holding its take-off 20 cm up, one hovering 5 m up beside them
    pos_ned = np.array([[0.0, 0.0, 0.0], [0.0, 20.0, -0.2], [0.0, 10.0, -5.0]])
    for t_s in np.arange(0.0, 40.0, 0.1):
        proximity.update(float(t_s), pos_ned, np.array([True, False, False]))
    assert proximity.nmac_at_s[:2] == [None, None] and None not in proximity.ground_nmac_at_s[:2]
    assert proximity.nmac_at_s[2] is not None and proximity.ground_nmac_at_s[2] is None
