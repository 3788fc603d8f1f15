"""Encounter campaigns (``encounter:``, fleet cases): the key's FILE:LINE errors, cases drawn from the case's seed
with the generator's world, the flight record of a fleet run (tools.campaign.fleet_record), and one real fleet case
end to end."""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from tools.campaign.cases import draw, materialise
from tools.campaign.fleet_record import record
from tools.campaign.replay import replay_case
from tools.campaign.results import read_rows
from tools.campaign.runner import run_campaign
from tools.campaign.spec import ENCOUNTER_BASE, CampaignFileError, load_campaign
from tools.encounters import encounter_world

GOOD = "name: enc\nencounter: {}\ncases: 4\nseed: 2\n"


def _spec(tmp_path: Path, body: str) -> Path:
    path = tmp_path / "c.yaml"
    path.write_text(body)
    return path


@pytest.mark.parametrize(
    ("body", "line", "words"),
    [
        ("name: enc\nencounter: {kind: spiral}\ncases: 4\nseed: 2\n", 2, ["encounter.kind: bad value 'spiral'"]),
        ("name: enc\nencounter: {vehicles: 9}\ncases: 4\nseed: 2\n", 2, ["encounter.vehicles", "2 to 8"]),
        ("name: enc\nencounter: {crowd: 3}\ncases: 4\nseed: 2\n", 2, ["encounter.crowd: unknown key"]),
        ("name: enc\nencounter: {kind: ring_swap, vehicles: 3}\ncases: 4\nseed: 2\n", 2, ["ring_swap encounter has 4"]),
        (GOOD + "base: x.yaml\n", 5, ["generates its worlds"]),
        (GOOD + "vary:\n  vehicle: {choice: [x500]}\n", 5, ["varies only params"]),
    ],
)
def test_encounter_key_errors_name_file_line_and_fix(tmp_path: Path, body: str, line: int, words: list[str]) -> None:
    with pytest.raises(CampaignFileError) as err:
        load_campaign(_spec(tmp_path, body))
    assert str(err.value).startswith(f"{tmp_path / 'c.yaml'}:{line}:"), err.value
    assert all(w in str(err.value) for w in words) and "fix:" in str(err.value)


def test_a_case_flies_the_generators_world_of_its_seed(tmp_path: Path) -> None:
    spec = load_campaign(_spec(tmp_path, "name: enc\nencounter: {vehicles: 3}\ncases: 4\nseed: 2\n"))
    case = draw(spec, 2)
    assert case == draw(spec, 2) and case.base == ENCOUNTER_BASE
    enc = encounter_world(case.sim_seed, vehicles=3)
    assert dict(case.overrides) == {
        "encounter.kind": enc.kind,
        "encounter.vehicles": 3,
        "encounter.manned": enc.manned,
        "encounter.traffic": enc.traffic,
        "encounter.stagger_s": enc.stagger_s,
    }
    assert materialise(spec, case).world_yaml == enc.yaml_text()
    shipped = [load_campaign(f"missions/campaigns/{n}.yaml") for n in ("encounters", "encounters_warn_only")]
    assert [draw(s, 7).sim_seed for s in shipped] == [draw(shipped[0], 7).sim_seed] * 2  # the same encounters
    assert "NAV_TRAFF_AVOID: 1.0" in materialise(shipped[1], draw(shipped[1], 7)).params_yaml


def test_the_flight_record_of_a_fleet_run() -> None:
    truth = [
        {"name": "a", "end_reason": "STOPPED", "truth_sha256": "1", "min_separation_m": 7.5,
         "min_volume_sep_m": 12.0, "min_manned_distance_m": 80.0},
        {"name": "b", "end_reason": "COLLISION", "truth_sha256": "2", "min_separation_m": 0.0,
         "min_volume_sep_m": 9.0, "min_manned_distance_m": None},
        {"name": "c", "end_reason": "STOPPED", "truth_sha256": "3", "min_separation_m": 0.0,
         "min_volume_sep_m": 9.0, "min_manned_distance_m": None},
    ]  # fmt: skip
    rows = [
        {"ok": True, "items_total": 4, "items_reached": 4, "landed": True, "disarmed": True, "reason": ""},
        {"ok": False, "items_total": 4, "items_reached": 2, "landed": False, "disarmed": False,
         "reason": "failsafe during the mission: Failsafe: geofence breached"},
        {"ok": True, "items_total": 4, "items_reached": 4, "landed": True, "disarmed": True, "reason": "",
         "fence_exits": 1},  # out of its fence by the truth, with no text (on the ground)
    ]  # fmt: skip
    sim = {
        "vehicle_contacts": 1, "manned_nmacs": 1, "collisions": 2, "vehicles": truth,
        # pair-events: b-c and a-b inside the UAV volume (b in both: 3 vehicles), a under HELI1 and PLANE1 in
        # flight (one vehicle, two events), c over a parked vehicle once and under HELI1 on its pad once
        "volume_events": [{"a": "b", "b": "c", "at_s": 10.0}, {"a": "a", "b": "b", "at_s": 12.0}],
        "volume_ground_excluded": [{"a": "a", "b": "c", "at_s": 40.0}],
        "nmac_events": [{"a": "a", "b": "HELI1", "at_s": 20.0}, {"a": "a", "b": "PLANE1", "at_s": 30.0}],
        "nmac_ground_excluded": [{"a": "c", "b": "HELI1", "at_s": 21.0}],
    }  # fmt: skip
    flight = record({"sim": sim, "vehicles": rows})
    assert flight["sim"]["end_reason"] == "COLLISION" and flight["texts"] == ["Failsafe: geofence breached"]
    assert flight["autopilot"] == {
        "items_total": 12, "items_reached": 10, "items_bypassed": 0, "landed": False, "disarmed": False,
        "fence_breaches": 2,
    }  # fmt: skip
    assert flight["traffic"] == {
        "traffic_contacts": 1, "traffic_min_sep_m": 9.0, "traffic_volume_entries": 2, "traffic_volume_vehicles": 3,
        "traffic_min_dist_m": 0.0, "traffic_nmac": 2, "traffic_nmac_vehicles": 1, "traffic_ground_excluded": 2,
        "traffic_min_manned_m": 80.0, "traffic_completion": 2 / 3, "traffic_vehicles": 3,
    }  # fmt: skip
    assert "error" in record({"sim": {}, "vehicles": [], "errors": ["quadsitl up died"]})


def test_a_row_says_stuck_or_unfinished_when_a_vehicle_did_not_finish() -> None:
    """The two held-out manned cases that stopped at 125 s with a vehicle stalled on its pad (three items missed,
    not landed) said COMPLETED: a stuck vehicle (the ground station's ``stuck:`` reason, or inproc's ``stuck``
    flag) makes the row STUCK, a vehicle still flying at the limit UNFINISHED."""
    truth = [{"name": n, "end_reason": "COMPLETED", "truth_sha256": n} for n in ("a", "b")]
    done = {"ok": True, "items_total": 4, "items_reached": 4, "landed": True, "disarmed": True, "reason": ""}
    stalled = {"ok": False, "items_total": 4, "items_reached": 1, "landed": True, "disarmed": False,
               "reason": "stuck: no mission progress for 120 s of sim time (crashed?)"}  # fmt: skip
    flying = {**stalled, "landed": False, "reason": "still flying when the case ended at 600.0 s of sim time"}
    cases = (([done, stalled], "STUCK"), ([done, {**flying, "stuck": True}], "STUCK"), ([done, flying], "UNFINISHED"))
    for rows, reason in (*cases, ([done, done], "COMPLETED")):
        assert record({"sim": {"vehicles": truth}, "vehicles": rows})["sim"]["end_reason"] == reason


def test_a_vehicle_that_landed_and_disarmed_after_the_judges_last_look_is_no_longer_flying() -> None:
    """The judge looks once a second; a vehicle that landed and disarmed in the case's last second, its mission
    complete, was scored "still flying" (failure search of the depot, case 4: 28 of 28 items, every vehicle landed
    and disarmed, completion 0.75)."""
    from types import SimpleNamespace

    from tools.campaign.inproc_flight import _MISSION_COMPLETE, _row

    summary = {"items_total": 7, "reached_seqs": list(range(7)), "mission_state": _MISSION_COMPLETE,
               "sim_time_s": 200.0, "landed": True, "disarmed": True}  # fmt: skip
    v = SimpleNamespace(autopilot=SimpleNamespace(summary=lambda wall_s: summary), reason="", upload_error="",
                        texts=[], done=False, name="alpha", stuck=False, fence_exits=0)  # fmt: skip
    row = _row(v, 1.0, 200.0)  # type: ignore[arg-type]
    assert row["ok"] and row["reason"] == "", row
    flying = _row(SimpleNamespace(**{**vars(v), "autopilot": SimpleNamespace(  # type: ignore[arg-type]
        summary=lambda wall_s: {**summary, "landed": False, "disarmed": False})}), 1.0, 200.0)  # fmt: skip
    assert not flying["ok"] and flying["reason"].startswith("still flying"), flying


@pytest.mark.sitl
@pytest.mark.slow
def test_one_head_on_encounter_flown_as_a_campaign_case(tmp_path: Path) -> None:
    body = "name: enc\nencounter: {kind: head_on, vehicles: 2, manned: false}\ncases: 1\nseed: 5\ndeadline_s: 400\n"
    body += "pass_if: {traffic_contacts: 0, traffic_completion: {min: 1.0}}\n"
    spec = load_campaign(_spec(tmp_path, body))
    run_campaign(spec, tmp_path / "out", workers=1, progress=False)
    (row,) = read_rows(tmp_path / "out")
    assert row["status"] == "ok", row["reason"]
    assert row["vary.encounter.kind"] == "head_on" and row["traffic_vehicles"] == 2.0
    assert row["traffic_contacts"] == 0.0 and row["traffic_completion"] == 1.0 and row["traffic_nmac"] == 0.0
    assert row["traffic_min_sep_m"] > 0.0 and math.isnan(row["traffic_min_manned_m"])
    assert row["landed"] and row["items_missed"] == 0


@pytest.mark.slow
def test_an_encounter_flown_in_process_replays_bit_for_bit(tmp_path: Path) -> None:
    """``mode: inproc`` flies a fleet case with scripted, staggered starts on sim time: replaying its row gives the
    same per-vehicle truth hashes (the sitl mode's wall-clock ground station cannot promise that)."""
    body = "name: enc\nencounter: {kind: converging, vehicles: 2, manned: false}\ncases: 1\nseed: 5\n"
    body += "mode: inproc\nsim_time_s: 400\npass_if: {traffic_contacts: 0, traffic_completion: {min: 1.0}}\n"
    spec = load_campaign(_spec(tmp_path, body))
    run_campaign(spec, tmp_path / "out", workers=1, progress=False)
    (row,) = read_rows(tmp_path / "out")
    assert row["status"] == "ok", row["reason"]
    assert row["mode"] == "inproc" and row["traffic_vehicles"] == 2.0 and row["vary.encounter.stagger_s"] > 0.0
    assert row["traffic_contacts"] == 0.0 and row["traffic_completion"] == 1.0 and row["items_missed"] == 0
    assert row["sim_time_s"] < 400.0  # ends when every vehicle has landed, not at the limit
    replay = replay_case(tmp_path / "out", 0)
    assert replay.matched, replay.text
    assert sorted(p.name for p in replay.recording.parent.glob("*.rrd")) == [
        "flight_uav0.rrd", "flight_uav1.rrd", "flight_world.rrd"
    ]  # fmt: skip
