"""Losses of separation as pair-events (sim.separation_events, sim.fleet): each pair once however often it comes
inside, events with a vehicle on the ground kept apart and written in the fleet summary with their count."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from mavlink_bridge.contract.traffic import AdsbEmitterType
from sim.fleet import FleetSim
from sim.fleet_run import fleet_airframes
from sim.fleet_world import ScriptedAircraft, TrafficWaypoint, load_fleet
from sim.separation_events import MannedPairs, PairEvent, pair_events
from sim.traffic import NMAC_HOR_M, ScriptedTraffic
from sim.world import load_world

TRIO_YAML = """\
name: trio
home: {lat_deg: 47.3977, lon_deg: 8.5456, alt_m: 488}
vehicles:
  - {name: alpha, home: {north_m: 0, east_m: 0}}
  - {name: bravo, home: {north_m: 0, east_m: 30}}
  - {name: charlie, home: {north_m: 0, east_m: 60}}
"""


def _fleet_sim(tmp_path: Path) -> FleetSim:
    path = tmp_path / "trio.yaml"
    path.write_text(TRIO_YAML)
    fleet = load_fleet(path)
    return FleetSim(load_world(path), fleet, fleet_airframes(fleet, "x500"), seed=3)


def test_a_pair_inside_the_uav_volume_is_one_event_however_often_and_ground_pairs_are_apart(tmp_path: Path) -> None:
    sim = _fleet_sim(tmp_path)
    batch = sim.batches[0]
    sim.step()  # all on their pads, 30 m apart: nothing
    assert sim.volume_pairs == {} and sim.volume_pairs_ground == {}
    for _ in range(3):  # alpha and bravo in and out of the volume three times: one event
        batch.state[:, 0:3] = ((0.0, 0.0, -20.0), (0.0, 6.0, -23.0), (0.0, 60.0, 0.0))
        sim.step()
        batch.state[:, 0:3] = ((0.0, 0.0, -20.0), (0.0, 16.0, -20.0), (0.0, 60.0, 0.0))
        sim.step()
    assert list(sim.volume_pairs) == [(0, 1)] and sim.volume_pairs_ground == {}
    first = sim.volume_pairs[(0, 1)]
    batch.state[:, 0:3] = ((0.0, 0.0, -20.0), (0.0, 56.0, -3.0), (0.0, 60.0, 0.0))  # bravo low over charlie's pad
    sim.step()
    assert sim.on_ground[2] and list(sim.volume_pairs_ground) == [(1, 2)] and sim.volume_pairs[(0, 1)] == first


def test_manned_pairs_count_each_vehicle_aircraft_pair_once_and_the_grounded_apart() -> None:
    path = (TrafficWaypoint(0.0, -1000.0, 25.0), TrafficWaypoint(0.0, 1000.0, 25.0))
    heli = ScriptedAircraft("HELI1", 0xA1B2C3, AdsbEmitterType.ROTOCRAFT, path, 50.0, 0.0)
    pairs = MannedPairs(ScriptedTraffic((heli,)), 3)
    # one on its pad under the path, one hovering 5 m up beside it, one far aside
    pos_ned = np.array([[0.0, 0.0, 0.0], [0.0, 10.0, -5.0], [NMAC_HOR_M + 50.0, 0.0, -15.0]])
    for t_s in np.arange(0.0, 40.0, 0.1):
        pairs.update(float(t_s), pos_ned, np.array([True, False, False]))
    assert list(pairs.airborne) == [(1, 0)] and list(pairs.ground) == [(0, 0)]
    assert pairs.airborne[(1, 0)] == pytest.approx(20.0 + (10.0 - NMAC_HOR_M) / 50.0, abs=0.11)  # 10 m east
    events = pair_events(pairs.airborne, ["a", "b", "c"], ["HELI1"])
    assert events == [PairEvent("b", "HELI1", pairs.airborne[(1, 0)])]
