"""``quadsitl campaign search`` / ``estimate``: the search: and estimate: keys' FILE:LINE errors, a CMA-ES search
that finds a failing case on the hop (real in-process flights), its rows, report, replay bit for bit and resume."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from tools.campaign.cli import main
from tools.campaign.results import read_rows
from tools.campaign.spec import CampaignFileError, load_campaign

HOP = Path(__file__).resolve().parents[2] / "missions" / "hop.yaml"
HEAD = f"""\
name: hop-search
base: {HOP}
cases: 16
seed: 2
mode: inproc
estimator: truth
sim_time_s: 4
arm_at_s: 0.5
vary:
  world.wind.north_m_s: {{uniform: [-10, 4]}}
  world.wind.east_m_s: {{uniform: [-6, 6]}}
  world.wind.seed: {{randint: [0, 1000000]}}
  world.payload_kg: {{choice: [0.0, 0.8]}}
"""


def _file(tmp_path: Path, tail: str) -> Path:
    path = tmp_path / "s.yaml"
    path.write_text(HEAD + tail)
    return path


@pytest.mark.parametrize(
    ("tail", "line", "words"),
    [
        ("search: {objective: clearance, method: cma}\n", 14, ["search.method: unknown method 'cma'", "'cmaes'"]),
        ("search: {objective: clearance, method: cmaes}\n", 14, ["world.payload_kg is a choice", "method: cem"]),
        ("search: {objective: clearence, method: cem}\n", 14, ["unknown objective 'clearence'", "'clearance'"]),
        ("search: {objective: {column: tracking_max, max: 1}, method: cem}\n", 14, ["unknown column"]),
        ("search: {objective: {column: max_tilt_deg}, method: cem}\n", 14, ["exactly one numeric min or max"]),
        ("search: {objective: {name: tracking, floor_m: 1}, method: cem}\n", 14, ["takes only 'bound_m'"]),
        ("search: {method: cem}\n", 14, ["missing 'objective'"]),
        ("search:\n  objective: tracking\n  method: cem\n  inputs: [world.wind.seed]\n", 17, ["a randint"]),
        ("search:\n  objective: tracking\n  method: cem\n  inputs: [world.wind.nort_m_s]\n", 17, ["not a vary entry"]),
        ("search: {objective: tracking, method: cem, popsize: 1}\n", 14, ["popsize: expected an integer >= 2"]),
        ("search: {objective: tracking, method: cem}\nestimate: {rho: 0.9}\n", 15, ["estimate.rho", "[0.01, 0.5]"]),
        ("search: {objective: tracking, method: cem}\nestimate: {levels: 3}\n", 15, ["estimate.levels: unknown key"]),
    ],
)
def test_search_keys_errors_name_file_line_and_fix(tmp_path: Path, tail: str, line: int, words: list[str]) -> None:
    path = _file(tmp_path, tail)
    with pytest.raises(CampaignFileError) as err:
        load_campaign(path)
    message = str(err.value)
    assert message.startswith(f"{path}:{line}"), message
    assert "\n" not in message and "fix: " in message
    for word in words:
        assert word in message, message


def test_a_campaign_without_search_is_refused_in_one_line(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    assert main(["search", str(_file(tmp_path, "")), "--out", str(tmp_path / "o"), "--no-progress"]) == 2
    err = capsys.readouterr().err.strip()
    assert "no 'search:' key" in err and "\n" not in err


@pytest.fixture(scope="module")
def searched(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A CMA-ES search of the hop's wind (payload fixed by inputs:) for a 0.45 m tracking bound: 16 flights."""
    folder = tmp_path_factory.mktemp("search")
    tail = "search:\n  objective: {name: tracking, bound_m: 0.45}\n  method: cmaes\n  popsize: 8\n"
    tail += "  inputs: [world.wind.north_m_s, world.wind.east_m_s]\n"
    out = folder / "out"
    rc = main(["search", str(_file(folder, tail)), "--out", str(out), "--workers", "1", "--no-progress"])
    assert rc == 1  # a failing case was found
    return out


def test_the_search_finds_a_failure_and_every_flight_is_a_row(searched: Path) -> None:
    rows = read_rows(searched)
    summary = json.loads((searched / "summary.json").read_text())
    assert [r["case_id"] for r in rows] == list(range(16))
    assert summary["flights"] == 16 and summary["lowest_margin"] < 0.0
    assert summary["flights_to_first_failure"] is not None
    assert all(r["replay"] == f"quadsitl campaign replay {searched} {r['case_id']}" for r in rows)
    margins = {r["case_id"]: r["margin"] for r in rows}
    assert all(margins[r["case_id"]] == pytest.approx(0.45 - r["tracking_pos_max_m"]) for r in rows)
    assert summary["worst"][0]["margin"] == min(margins.values())
    assert {r["search_role"] for r in rows} == {"cmaes"} and {r["search_batch"] for r in rows} == {0, 1}
    report = (searched / "report.md").read_text()
    assert "Lowest margin" in report and "quadsitl campaign replay" in report
    assert (searched / "margin_vs_flights.png").stat().st_size > 1000


def test_a_searched_failing_case_replays_bit_for_bit(searched: Path, capsys: pytest.CaptureFixture) -> None:
    worst = json.loads((searched / "summary.json").read_text())["worst"][0]
    assert main(["replay", str(searched), str(worst["case_id"])]) == 0
    assert "MATCH" in capsys.readouterr().out


def test_resume_reads_the_flown_batches_back_and_extends_the_budget(searched: Path, tmp_path: Path) -> None:
    before = {r["case_id"]: r["truth_hash"] for r in read_rows(searched)}
    campaign = searched / "campaign.yaml"
    args = [str(campaign), "--out", str(searched), "--workers", "1", "--no-progress", "--budget", "24"]
    assert main(["search", *args]) == 2  # without --resume a folder with results is refused
    assert main(["search", *args, "--resume"]) == 1
    rows = read_rows(searched)
    assert len(rows) == 24 and {k: before[k] for k in before} == {r["case_id"]: r["truth_hash"] for r in rows[:16]}
    summary = json.loads((searched / "summary.json").read_text())
    assert summary["flights"] == 24 and summary["flights_flown_now"] == 8


def test_estimate_flies_levels_and_a_final_batch_beside_plain_monte_carlo(tmp_path: Path) -> None:
    tail = "search: {objective: {name: tracking, bound_m: 0.45}, method: cem}\n"
    tail += "estimate: {rho: 0.2, level_batch: 10, final: 10, max_levels: 1}\n"
    out = tmp_path / "is"
    args = ["--out", str(out), "--workers", "1", "--no-progress", "--mc", "6"]
    assert main(["estimate", str(_file(tmp_path, tail)), *args]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["flights"] == 20 and len(summary["levels"]) == 1
    rows = read_rows(out)
    final = [r for r in rows if r["search_role"] == "is-final"]
    assert [r["case_id"] for r in final] == list(range(10, 20))
    assert all(r["is_log_w"] == r["is_log_w"] for r in final)  # the final batch's weights are in its rows
    assert all(r["is_log_w"] != r["is_log_w"] for r in rows if r["search_role"] == "ce-level")  # NaN elsewhere
    assert summary["mc"]["flights"] == 6 and len(read_rows(out / "mc")) == 6
    assert 0.0 <= summary["p_is"] <= summary["p_is_ci95"][1]
