"""Campaigns on the embedded LocalCluster: rows, report, replay of a failing case, sitl = inproc bit for bit,
and a hung case that becomes a ``timeout`` row with its processes killed."""

from __future__ import annotations

import json
import os
import time
from pathlib import Path

import pyarrow.parquet as pq
import pytest
from campaign_files import write_campaign

from tools.campaign.cli import main

pytestmark = [pytest.mark.slow]

ROW_COLUMNS = {
    "case_id", "campaign", "root_seed", "sim_seed", "mode", "vehicle", "params", "failures",
    "vary.world.wind.north_m_s",
    "status", "passed", "reason", "end_reason", "items_total", "items_reached", "items_bypassed", "items_missed",
    "landed", "collisions", "min_clearance_m", "fence_breaches", "tracking_pos_rms_m", "max_tilt_deg",
    "energy_used_frac", "failsafes", "sim_time_s", "wall_time_s", "truth_hash", "versions", "world_yaml",
}  # fmt: skip


def _rows(out: Path) -> list[dict]:
    return pq.read_table(out / "results.parquet").to_pylist()


def _processes_mentioning(text: str) -> list[int]:
    pids = []
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                if text in (entry / "cmdline").read_bytes().replace(b"\0", b" ").decode(errors="replace"):
                    pids.append(int(entry.name))
            except OSError:
                pass
    return [p for p in pids if p != os.getpid()]


@pytest.fixture(scope="module")
def inproc_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    folder = tmp_path_factory.mktemp("inproc")
    out = folder / "out"
    rc = main([str(write_campaign(folder, cases=4)), "--out", str(out), "--workers", "2", "--no-progress"])
    assert rc == 1  # case 0 loses a motor: the campaign finished with a failing case
    return out


def test_rows_summary_and_report(inproc_run: Path) -> None:
    rows = _rows(inproc_run)
    assert [r["case_id"] for r in rows] == [0, 1, 2, 3]
    assert set(rows[0]) >= ROW_COLUMNS
    crash = rows[0]
    assert crash["status"] == "fail" and crash["end_reason"] == "GROUND_IMPACT" and not crash["landed"]
    assert "flight ended GROUND_IMPACT" in crash["reason"]
    for r in rows[1:]:
        assert r["status"] == "ok" and r["passed"] and r["landed"] and r["items_missed"] == 0, r["reason"]
        assert r["end_reason"] == "COMPLETED" and 15.0 < r["sim_time_s"] < 25.0  # ends landed and disarmed
        assert r["disarmed"]
        assert len(r["truth_hash"]) == 64 and r["tracking_pos_rms_m"] < 1.0
    assert len({r["truth_hash"] for r in rows}) == 4
    summary = json.loads((inproc_run / "summary.json").read_text())
    assert summary["cases_done"] == 4 and summary["passed"] == 3
    low, high = summary["pass_rate_ci95"]
    assert low == pytest.approx(0.194, abs=1e-3) and high == pytest.approx(0.9937, abs=1e-3)  # Clopper-Pearson 3/4
    assert summary["worst"][0]["case_id"] == 0
    assert summary["worst"][0]["replay"] == f"quadsitl campaign replay {inproc_run} 0"
    report = (inproc_run / "report.md").read_text()
    assert "Pass rate 75.0%" in report and "flight ended GROUND_IMPACT" in report
    assert (inproc_run / "ecdf_tracking.png").stat().st_size > 1000
    assert (inproc_run / "ecdf_energy.png").is_file()
    assert not (inproc_run / "shards").exists()  # merged


def test_replay_reproduces_the_failing_case(inproc_run: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["replay", str(inproc_run), "0"]) == 0
    out = capsys.readouterr().out
    assert "MATCH" in out and "GROUND_IMPACT" in out
    assert (inproc_run / "replay" / "case-000000" / "flight.rrd").stat().st_size > 10_000
    assert main(["replay", str(inproc_run), "9"]) == 2
    assert "no row for case 9" in capsys.readouterr().err


@pytest.mark.sitl
def test_sitl_flies_the_inproc_flights_bit_for_bit_and_replays(inproc_run: Path, tmp_path: Path) -> None:
    out = tmp_path / "out"
    rc = main(
        [str(write_campaign(tmp_path, cases=2, mode="sitl")), "--out", str(out), "--workers", "2", "--no-progress"]
    )
    assert rc == 1
    sitl, inproc = _rows(out), _rows(inproc_run)[:2]
    for a, b in zip(sitl, inproc, strict=True):
        assert a["mode"] == "sitl" and b["mode"] == "inproc"
        for key in (
            "case_id",
            "sim_seed",
            "vary.world.wind.north_m_s",
            "failures",
            "status",
            "end_reason",
            "truth_hash",
        ):
            assert a[key] == b[key], key
    assert _processes_mentioning(str(out)) == []
    assert main(["replay", str(out), "0"]) == 0  # the failing case, as a real lockstep flight with a recording


@pytest.mark.sitl
def test_a_case_past_its_deadline_is_a_timeout_row_and_its_processes_are_killed(tmp_path: Path) -> None:
    out = tmp_path / "out"
    path = write_campaign(tmp_path, cases=1, mode="sitl", deadline_s=2.0)
    t0 = time.monotonic()
    assert main([str(path), "--out", str(out), "--workers", "1", "--no-progress"]) == 1
    assert time.monotonic() - t0 < 60.0
    (row,) = _rows(out)
    assert row["status"] == "timeout" and "deadline 2 s" in row["reason"] and not row["passed"]
    assert _processes_mentioning(str(out)) == []  # supervisor, autopilot and sim all gone
    assert json.loads((out / "summary.json").read_text())["failures_by_reason"] == {
        "timeout: wall deadline N s reached: the case's processes were killed": 1
    }
