"""The campaign report (tools.campaign.report) on rows built here, no flying: for fleet cases the pass rate per
encounter kind, vehicle count and traffic class, the traffic totals (pair-events, ground exclusions, completion over
the vehicles) and the separation ECDFs and distributions; for any campaign the pass rate per level of its choice
inputs."""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest

from tools.campaign.report import fleet_groups, traffic_totals, worst, write_report
from tools.campaign.results import ShardWriter
from tools.campaign.spec import load_campaign


def _row(case_id: int, kind: str, n: int, traffic: str, passed: bool, **extra: float) -> dict:
    row = {
        "case_id": case_id, "status": "ok" if passed else "fail", "passed": passed, "reason": "" if passed else
        "traffic_volume_entries 1 > 0", "tracking_pos_rms_m": math.nan, "min_clearance_m": math.nan,
        "vary.encounter.kind": kind, "vary.encounter.vehicles": float(n), "vary.encounter.traffic": traffic,
        "traffic_vehicles": float(n), "traffic_contacts": 0.0, "traffic_volume_entries": 0.0 if passed else 1.0,
        "traffic_volume_vehicles": 0.0 if passed else 2.0, "traffic_nmac": 0.0, "traffic_nmac_vehicles": 0.0,
        "traffic_ground_excluded": 0.0, "traffic_min_sep_m": 14.0 if passed else 6.0, "traffic_min_dist_m": 9.0,
        "traffic_min_manned_m": math.nan, "traffic_completion": 1.0, "wall_time_s": 10.0,
    }  # fmt: skip
    return {**row, **extra}


ROWS = [
    _row(0, "ring_swap", 8, "none", False),
    _row(1, "ring_swap", 8, "none", True),
    _row(2, "depot", 4, "rotorcraft", False, traffic_nmac=2.0, traffic_nmac_vehicles=1.0, traffic_min_manned_m=90.0,
         traffic_ground_excluded=1.0, traffic_completion=0.75),
    _row(3, "head_on", 2, "light", True, traffic_min_manned_m=400.0),
    {**_row(4, "head_on", 2, "none", False), "status": "error", "reason": "ValueError: boom"},
]  # fmt: skip


def test_pass_rate_per_kind_vehicle_count_and_traffic_class() -> None:
    groups = fleet_groups(ROWS)
    assert list(groups) == ["encounter kind", "vehicles", "traffic class"]
    assert {k: v["cases"] for k, v in groups["encounter kind"].items()} == {"depot": 1, "head_on": 2, "ring_swap": 2}
    assert groups["encounter kind"]["ring_swap"]["pass_rate"] == 0.5
    assert list(groups["vehicles"]) == ["2", "4", "8"] and groups["vehicles"]["2"]["pass_rate"] == 0.5
    assert groups["traffic class"]["light"]["pass_rate"] == 1.0 and groups["traffic class"]["rotorcraft"]["cases"] == 1
    low, high = groups["encounter kind"]["ring_swap"]["ci95_low"], groups["encounter kind"]["ring_swap"]["ci95_high"]
    assert low == pytest.approx(0.0126, abs=1e-3) and high == pytest.approx(0.9874, abs=1e-3)  # Clopper-Pearson 1/2
    assert fleet_groups([{"case_id": 0, "passed": True, "status": "ok"}]) == {}  # not a fleet campaign
    assert worst(ROWS)[0]["case_id"] == 4 and [r["case_id"] for r in worst(ROWS)[1:3]] == [0, 2]  # closest first


def test_traffic_totals_count_judged_cases_and_weigh_completion_by_vehicles() -> None:
    t = traffic_totals(ROWS)
    assert t is not None and (t["cases"], t["vehicles"]) == (4.0, 22.0)  # the error row is not judged
    assert (t["traffic_volume_entries"], t["traffic_volume_vehicles"], t["traffic_nmac"]) == (2.0, 4.0, 2.0)
    assert t["traffic_ground_excluded"] == 1.0 and t["completion"] == pytest.approx((8 + 8 + 3 + 2) / 22)
    assert traffic_totals([{"status": "ok"}]) is None


def test_the_report_of_a_fleet_campaign_has_its_groups_totals_and_separation_ecdfs(tmp_path: Path) -> None:
    path = tmp_path / "enc.yaml"
    path.write_text("name: enc\nencounter: {}\ncases: 5\nseed: 2\nmode: inproc\n")
    writer = ShardWriter(tmp_path / "out")
    for r in ROWS:
        writer.add(r)
    writer.flush()
    summary = write_report(load_campaign(path), tmp_path / "out")
    report = (tmp_path / "out" / "report.md").read_text()
    assert "## Pass rate per encounter kind, vehicle count and traffic class" in report
    assert (
        "| encounter kind | `ring_swap` | 2 | 50.0% |" in report
        and "| traffic class | `light` | 1 | 100.0% |" in report
    )
    assert "(`traffic_ground_excluded`) | 1 |" in report and "(`traffic_nmac`) | 2 |" in report
    assert "| traffic_min_sep_m | 6.000 |" in report  # the distributions table is no longer empty
    for name in ("ecdf_sep.png", "ecdf_dist.png", "ecdf_manned.png"):
        assert (tmp_path / "out" / name).stat().st_size > 1000 and f"]({name})" in report
    assert json.loads((tmp_path / "out" / "summary.json").read_text())["traffic"] == summary["traffic"]


def test_the_report_of_a_campaign_with_choice_inputs_has_a_pass_rate_per_level(tmp_path: Path) -> None:
    path = tmp_path / "wind.yaml"
    path.write_text(
        f"name: wind\nbase: {Path(__file__).resolve().parents[2] / 'missions' / 'delivery.yaml'}\ncases: 3\n"
        "seed: 1\nvary:\n  world.payload_kg: {choice: [0.0, 0.8]}\n  world.wind.seed: {randint: [0, 10]}\n"
    )
    writer = ShardWriter(tmp_path / "out")
    for case_id, payload, passed in ((0, 0.0, True), (1, 0.8, False), (2, 0.8, True)):
        writer.add({"case_id": case_id, "status": "ok" if passed else "fail", "passed": passed,
                    "reason": "" if passed else "landed False", "tracking_pos_rms_m": 0.5,
                    "vary.world.payload_kg": payload, "vary.world.wind.seed": 3.0})  # fmt: skip
    writer.flush()
    summary = write_report(load_campaign(path), tmp_path / "out")
    report = (tmp_path / "out" / "report.md").read_text()
    assert list(summary["per_level"]) == ["world.payload_kg"]  # a randint input is not a level
    assert "## Pass rate per input level" in report
    assert "| input | level | cases | pass rate | 95 % interval |" in report
    assert "| world.payload_kg | `0.0` | 1 | 100.0% |" in report
    assert "| world.payload_kg | `0.8` | 2 | 50.0% |" in report
    assert "## Pass rate per encounter kind" not in report  # not a fleet campaign
