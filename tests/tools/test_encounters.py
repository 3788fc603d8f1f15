"""Seeded encounter worlds (tools.encounters): pure functions of the seed, valid fleet worlds (pads 20 m apart,
inside the fence, homes not in contact), the promised geometry (head-on pairs opposite, ring swaps antipodal,
depots interleaved, manned traffic at 20-120 m, some below the cruise) and the shipped campaign's mix (>= 1000
encounters, >= 150 manned, >= 100 ring swaps, >= 20 % with 8 vehicles)."""

from __future__ import annotations

import itertools
import math
import subprocess
import sys
from collections import Counter
from pathlib import Path

import pytest
from conftest import REPO_ROOT

from autopilot.mission.files import load_fleet_missions
from sim.fleet_world import load_fleet
from sim.vehicle_config import load_vehicle
from tools.campaign.cases import draw
from tools.campaign.spec import load_campaign
from tools.encounters import FENCE_RADIUS_M, KINDS, MIN_PAD_GAP_M, MIN_VEHICLES, Encounter, encounter_world


def _pads(world: dict) -> list[tuple[float, float]]:
    return [(v["home"]["north_m"], v["home"]["east_m"]) for v in world["vehicles"]]


def _ends(world: dict) -> list[tuple[float, float]]:
    return [
        (v["mission"][-2]["waypoint"]["north_m"], v["mission"][-2]["waypoint"]["east_m"]) for v in world["vehicles"]
    ]


def _alts(vehicle: dict) -> list[float]:
    items = vehicle["mission"]
    return [items[0]["takeoff"]["alt_m"], *(i["waypoint"]["alt_m"] for i in items if "waypoint" in i)]


def assert_valid(enc: Encounter) -> None:
    """Pads and landing points >= MIN_PAD_GAP_M apart (a ring swap lands on its partner's vacated pad), every
    waypoint inside the fence, the vehicles' collision spheres apart at their homes."""
    world = enc.world
    pads, ends = _pads(world), _ends(world)
    n = len(pads)
    assert n == enc.vehicles and MIN_VEHICLES[enc.kind] <= n <= 8
    for i, j in itertools.permutations(range(n), 2):
        assert math.dist(pads[i], pads[j]) >= MIN_PAD_GAP_M - 1e-6, (enc.seed, i, j)
        assert math.dist(ends[i], ends[j]) >= MIN_PAD_GAP_M - 1e-6, (enc.seed, i, j)
        if not (enc.kind == "ring_swap" and math.dist(ends[i], pads[j]) < 1e-6):
            assert math.dist(ends[i], pads[j]) >= MIN_PAD_GAP_M - 1e-6, (enc.seed, i, j)
    if enc.kind == "ring_swap":  # each lands on another's pad, no two on the same
        assert sorted(ends) == sorted(pads)
    radius_m = load_vehicle("x500").collision_radius_m
    assert 4 * radius_m < MIN_PAD_GAP_M  # homes far from contact
    for v in world["vehicles"]:
        ((fence,),) = [[f["inclusion_circle"] for f in v["fence"]]]
        assert fence == {"north_m": 0.0, "east_m": 0.0, "radius_m": FENCE_RADIUS_M}
        points = [(w["waypoint"]["north_m"], w["waypoint"]["east_m"]) for w in v["mission"] if "waypoint" in w]
        for p in [(v["home"]["north_m"], v["home"]["east_m"]), *points]:
            assert math.hypot(*p) < FENCE_RADIUS_M - 20.0
        assert all(10.0 <= a <= 70.0 for a in _alts(v)) and 0.1 <= v["speed_m_s"] <= 10.0
    for a in world.get("traffic", []):
        assert 20.0 <= a["path"][0]["alt_m"] <= 120.0 and a["emitter"] in ("rotorcraft", "light")


def test_the_same_seed_gives_the_same_world_and_seeds_differ() -> None:
    assert encounter_world(11).yaml_text() == encounter_world(11).yaml_text()
    assert encounter_world(11).yaml_text() != encounter_world(12).yaml_text()
    drawn = [encounter_world(s) for s in range(300)]
    assert {e.kind for e in drawn} == set(KINDS) and {e.vehicles for e in drawn} == set(range(2, 9))
    for e in drawn:
        assert_valid(e)
        assert e.manned == bool(e.world.get("traffic")) and (e.traffic == "none") == (not e.manned)


@pytest.mark.parametrize("kind", KINDS)
def test_every_kind_and_size_is_a_valid_fleet_world_both_sides_accept(kind: str, tmp_path: Path) -> None:
    for n in range(MIN_VEHICLES[kind], 9):
        for seed in (7, 8, 9):
            enc = encounter_world(seed, kind, n, manned=True)
            assert_valid(enc)
            path = tmp_path / f"{kind}_{n}.yaml"
            path.write_text(enc.yaml_text())
            plans = load_fleet_missions(path)  # the ground station's side
            fleet = load_fleet(path)  # the simulator's side
            assert len(plans) == len(fleet.vehicles) == n and 1 <= len(fleet.traffic) <= 2
            assert (enc.stagger_s > 0.0) == (kind in ("converging", "depot"))


def test_head_on_pairs_fly_opposite_courses_and_vertical_pairs_cross_altitudes() -> None:
    for kind in ("head_on", "vertical"):
        world = encounter_world(5, kind, 4, manned=False).world
        pads, ends = _pads(world), _ends(world)
        for a, b in ((0, 1), (2, 3)):
            ua = (ends[a][0] - pads[a][0], ends[a][1] - pads[a][1])
            ub = (ends[b][0] - pads[b][0], ends[b][1] - pads[b][1])
            cos = (ua[0] * ub[0] + ua[1] * ub[1]) / (math.hypot(*ua) * math.hypot(*ub))
            assert cos < -0.99
            if kind == "vertical":  # take-off altitude and the last waypoint's: one climbs as the other descends
                alts = [(_alts(v)[0], _alts(v)[-1]) for v in world["vehicles"]]
                assert alts[a] == alts[b][::-1] and alts[a][0] != alts[a][1]
                # the change happens between two waypoints either side of the meeting point (the area's centre)
                (n0, e0), (n1, e1) = [(w["waypoint"]["north_m"], w["waypoint"]["east_m"]) for w in
                                      world["vehicles"][a]["mission"][1:3]]  # fmt: skip
                assert math.hypot(n0, e0) < 15.0 and math.hypot(n1, e1) < 15.0


def test_ring_swaps_depots_overtaking_and_climbing_crossings_have_their_geometry() -> None:
    for seed in range(20):
        ring = encounter_world(seed, "ring_swap", manned=False)
        pads, ends = _pads(ring.world), _ends(ring.world)
        radius = math.hypot(*pads[0])
        assert all(abs(math.hypot(*p) - radius) < 0.05 for p in pads) and len({a for v in ring.world["vehicles"]
                                                                                for a in _alts(v)}) == 1  # fmt: skip
        if ring.vehicles % 2 == 0:  # antipodal: through the centre
            assert all(math.dist(p, (-q[0], -q[1])) < 0.05 for p, q in zip(pads, ends, strict=True))
        depot = encounter_world(seed, "depot", 6, manned=False)
        pads, ends = _pads(depot.world), _ends(depot.world)
        arriving = [math.hypot(*e) < 40.0 for e in ends]
        departing = [math.hypot(*p) < 40.0 for p in pads]
        assert any(arriving) and any(departing) and all(a != d for a, d in zip(arriving, departing, strict=True))
        assert arriving == sorted(arriving, reverse=True)  # arrivals start first: departures leave as they land
        fast = encounter_world(seed, "overtaking", 5, manned=False).world["vehicles"]
        speeds = [v["speed_m_s"] for v in fast]
        assert speeds == sorted(speeds) and 1.45 <= speeds[-1] / speeds[0] <= 3.01 and speeds[-1] <= 10.0
        climb = encounter_world(seed, "crossing_climb", 6, manned=False).world["vehicles"]
        assert all(_alts(v)[0] == _alts(v)[1] and _alts(v)[2] == _alts(v)[3] for v in climb)
        assert any(_alts(v)[1] != _alts(v)[2] for v in climb)  # climbs and descents between the via points


def test_manned_traffic_crosses_the_area_some_below_the_cruise_some_over_vehicles_on_pads() -> None:
    below = late = both = 0
    for seed in range(120):
        enc = encounter_world(seed, manned=True)
        lowest = min(a for v in enc.world["vehicles"] for a in _alts(v))
        for aircraft in enc.world["traffic"]:
            (n0, e0), (n1, e1) = [(p["north_m"], p["east_m"]) for p in aircraft["path"]]
            # its closest approach to the area's centre, and when it passes there (it starts at t = 0)
            t = max(0.0, min(1.0, -(n0 * (n1 - n0) + e0 * (e1 - e0)) / ((n1 - n0) ** 2 + (e1 - e0) ** 2)))
            assert math.hypot(n0 + t * (n1 - n0), e0 + t * (e1 - e0)) <= 30.5
            over_s = t * math.hypot(n1 - n0, e1 - e0) / aircraft["speed_m_s"]
            assert 8.0 <= over_s <= 110.0
            late += over_s >= 60.0
            below += aircraft["path"][0]["alt_m"] < lowest
        both += enc.traffic == "both"
    assert below >= 15 and late >= 20 and both >= 10


def test_the_shipped_campaign_draws_the_promised_mix() -> None:
    """Over the shipped encounter campaign (no flying): >= 1000 encounters, >= 150 with manned traffic, >= 100 ring
    swaps, >= 20 % with 8 vehicles; the warn-only file draws the same encounters."""
    avoid = load_campaign(REPO_ROOT / "missions/campaigns/encounters.yaml")
    warn = load_campaign(REPO_ROOT / "missions/campaigns/encounters_warn_only.yaml")
    assert avoid.cases == warn.cases >= 1000 and avoid.seed == warn.seed
    drawn = [dict(draw(avoid, k).overrides) for k in range(avoid.cases)]
    kinds = Counter(d["encounter.kind"] for d in drawn)
    assert sum(d["encounter.manned"] for d in drawn) >= 150
    assert kinds["ring_swap"] >= 100 and set(kinds) == set(KINDS)
    assert sum(d["encounter.vehicles"] == 8 for d in drawn) >= 0.2 * avoid.cases
    assert [draw(warn, k).sim_seed for k in (0, 500, 999)] == [draw(avoid, k).sim_seed for k in (0, 500, 999)]


def test_bad_requests_are_one_line_errors(tmp_path: Path) -> None:
    with pytest.raises(ValueError, match="2 to 8 vehicles"):
        encounter_world(1, "crossing", 9)
    with pytest.raises(ValueError, match="ring_swap encounter has 4 to 8"):
        encounter_world(1, "ring_swap", 3)
    with pytest.raises(ValueError, match="unknown encounter kind"):
        encounter_world(1, "spiral")
    assert encounter_world(1, vehicles=2).kind != "ring_swap"  # a drawn kind fits a given count
    out = tmp_path / "e.yaml"
    cmd = [sys.executable, "-m", "tools.encounters", "--seed", "4", "--vehicles", "3", "--out", str(out)]
    done = subprocess.run(cmd, cwd=REPO_ROOT, capture_output=True, text=True, timeout=60, check=False)
    assert done.returncode == 0 and "tools.run --world" in done.stdout and out.is_file()
    cmd[cmd.index("--vehicles") + 1] = "1"
    done = subprocess.run(cmd, cwd=REPO_ROOT, capture_output=True, text=True, timeout=60, check=False)
    assert done.returncode == 2 and done.stderr.startswith("encounters: error: an encounter has 2 to 8")
