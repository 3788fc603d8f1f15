"""The SITL must-show suite's keys (tools.benchmarks.sitl_traffic) from a fleet run's summary, no flying; its
two worlds are valid fleet worlds with the promised geometry."""

from __future__ import annotations

import itertools
import math

from sim.fleet_world import load_fleet
from tools.benchmarks.sitl_traffic import WORLDS, world_results
from tools.campaign.fleet_record import record


def test_keys_come_from_the_simulators_pair_events_and_the_ground_stations_rows() -> None:
    truth = [{"name": n, "end_reason": "STOPPED", "truth_sha256": n, "min_volume_sep_m": 8.0} for n in "ab"]
    sim = {
        "vehicles": truth, "vehicle_contacts": 0, "volume_events": [{"a": "a", "b": "b", "at_s": 30.0}],
        "nmac_events": [], "volume_ground_excluded": [], "nmac_ground_excluded": [{"a": "a", "b": "H", "at_s": 9}],
    }  # fmt: skip
    rows = [
        {"name": "a", "ok": True, "landed": True, "disarmed": True, "reason": ""},
        {"name": "b", "ok": False, "landed": True, "disarmed": True, "reason": "failsafe during the mission: x"},
    ]
    flight = record({"sim": sim, "vehicles": rows})
    flight["vehicle_rows"] = rows
    keys = {r.key: r for r in world_results("w", flight)}
    assert keys["sitl_w_volume_entries"].value == 1.0 and not keys["sitl_w_volume_entries"].met
    assert keys["sitl_w_nmac"].met and keys["sitl_w_ground_excluded"].value == 1.0
    assert keys["sitl_w_completion"].value == 0.5 and "b: failsafe" in keys["sitl_w_volume_entries"].note
    missing = {r.key: r for r in world_results("w", {"error": "tools.run wrote no summary", "sim": {}})}
    assert math.isnan(missing["sitl_w_nmac"].value) and not missing["sitl_w_nmac"].met


def test_the_ring_swap_and_the_depot_with_a_helicopter() -> None:
    (_, ring, _), (_, depot, _) = WORLDS
    fleet = load_fleet(ring)
    homes = [(v.home_north_m, v.home_east_m) for v in fleet.vehicles]
    assert len(homes) == 6 and all(abs(math.hypot(*h) - 40.0) < 0.05 for h in homes) and not fleet.traffic
    assert min(math.dist(a, b) for a, b in itertools.combinations(homes, 2)) >= 20.0
    fleet = load_fleet(depot)
    homes = [(v.home_north_m, v.home_east_m) for v in fleet.vehicles]
    assert len(homes) == 5 and min(math.dist(a, b) for a, b in itertools.combinations(homes, 2)) >= 20.0
    (heli,) = fleet.traffic
    assert heli.emitter.name == "ROTOCRAFT" and {p.alt_m for p in heli.path} == {25.0}
    assert {p.north_m for p in heli.path} == {60.0}  # 60 m from the depot's centre
