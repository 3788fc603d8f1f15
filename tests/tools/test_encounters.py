"""Seeded encounter worlds (tools.encounters): pure functions of the seed, valid fleet worlds, the promised
geometry (pads apart, head-on pairs opposite, manned traffic inside the NMAC height over the area)."""

from __future__ import annotations

import itertools
import math
import subprocess
import sys
from pathlib import Path

import pytest
from conftest import REPO_ROOT

from autopilot.mission.files import load_fleet_missions
from sim.fleet_world import load_fleet
from tools.encounters import CRUISE_ALT_M, KINDS, MIN_PAD_GAP_M, encounter_world


def _pads(world: dict) -> list[tuple[float, float]]:
    return [(v["home"]["north_m"], v["home"]["east_m"]) for v in world["vehicles"]]


def _ends(world: dict) -> list[tuple[float, float]]:
    return [(v["mission"][1]["waypoint"]["north_m"], v["mission"][1]["waypoint"]["east_m"]) for v in world["vehicles"]]


def test_the_same_seed_gives_the_same_world_and_seeds_differ() -> None:
    assert encounter_world(11).yaml_text() == encounter_world(11).yaml_text()
    assert encounter_world(11).yaml_text() != encounter_world(12).yaml_text()
    drawn = [encounter_world(s) for s in range(300)]
    assert {e.kind for e in drawn} == set(KINDS) and {e.vehicles for e in drawn} == set(range(2, 9))
    assert 25 <= sum(e.manned for e in drawn) <= 80  # one in six


@pytest.mark.parametrize("kind", KINDS)
def test_every_kind_and_size_is_a_fleet_world_both_sides_accept(kind: str, tmp_path: Path) -> None:
    for n in (2, 5, 8):
        enc = encounter_world(7, kind, n, manned=True)
        path = tmp_path / f"{kind}_{n}.yaml"
        path.write_text(enc.yaml_text())
        plans = load_fleet_missions(path)  # the ground station's side
        fleet = load_fleet(path)  # the simulator's side
        assert len(plans) == len(fleet.vehicles) == n and len(fleet.traffic) == 1
        pads, ends = _pads(enc.world), _ends(enc.world)
        for i, j in itertools.permutations(range(n), 2):
            assert math.dist(pads[i], pads[j]) >= MIN_PAD_GAP_M - 1e-6
            assert math.dist(ends[i], pads[j]) >= MIN_PAD_GAP_M - 1e-6
        assert (enc.stagger_s > 0.0) == (kind == "converging")


def test_head_on_pairs_fly_opposite_courses_and_vertical_pairs_cross_altitudes() -> None:
    for kind in ("head_on", "vertical"):
        world = encounter_world(5, kind, 4).world
        pads, ends = _pads(world), _ends(world)
        for a, b in ((0, 1), (2, 3)):
            ua = (ends[a][0] - pads[a][0], ends[a][1] - pads[a][1])
            ub = (ends[b][0] - pads[b][0], ends[b][1] - pads[b][1])
            cos = (ua[0] * ub[0] + ua[1] * ub[1]) / (math.hypot(*ua) * math.hypot(*ub))
            assert cos < -0.99
            if kind == "vertical":  # take-off altitude and the last waypoint's: one climbs as the other descends
                alts = [
                    (v["mission"][0]["takeoff"]["alt_m"], v["mission"][-2]["waypoint"]["alt_m"])
                    for v in world["vehicles"]
                ]
                assert alts[a] == alts[b][::-1] and alts[a][0] != alts[a][1]
                # the change happens between two waypoints either side of the meeting point (the area's centre)
                (n0, e0), (n1, e1) = [(w["waypoint"]["north_m"], w["waypoint"]["east_m"]) for w in
                                      world["vehicles"][a]["mission"][1:3]]  # fmt: skip
                assert math.hypot(n0, e0) < 12.0 and math.hypot(n1, e1) < 12.0


def test_manned_traffic_crosses_the_area_inside_the_nmac_height() -> None:
    for seed in range(40):
        aircraft = encounter_world(seed, manned=True).world["traffic"][0]
        (n0, e0), (n1, e1) = [(p["north_m"], p["east_m"]) for p in aircraft["path"]]
        # its closest approach to the area's centre, and its altitude against the 15 m cruise
        t = max(0.0, min(1.0, -(n0 * (n1 - n0) + e0 * (e1 - e0)) / ((n1 - n0) ** 2 + (e1 - e0) ** 2)))
        assert math.hypot(n0 + t * (n1 - n0), e0 + t * (e1 - e0)) <= 30.5
        assert abs(aircraft["path"][0]["alt_m"] - CRUISE_ALT_M) < 30.0 + 5.0


def test_bad_requests_are_one_line_errors(tmp_path: Path) -> None:
    with pytest.raises(ValueError, match="2 to 8 vehicles"):
        encounter_world(1, "crossing", 9)
    with pytest.raises(ValueError, match="unknown encounter kind"):
        encounter_world(1, "spiral")
    out = tmp_path / "e.yaml"
    cmd = [sys.executable, "-m", "tools.encounters", "--seed", "4", "--vehicles", "3", "--out", str(out)]
    done = subprocess.run(cmd, cwd=REPO_ROOT, capture_output=True, text=True, timeout=60, check=False)
    assert done.returncode == 0 and "tools.run --world" in done.stdout and out.is_file()
    cmd[cmd.index("--vehicles") + 1] = "1"
    done = subprocess.run(cmd, cwd=REPO_ROOT, capture_output=True, text=True, timeout=60, check=False)
    assert done.returncode == 2 and done.stderr.startswith("encounters: error: an encounter has 2 to 8")
