"""The encounter Monte Carlo's bench keys (tools.benchmarks.encounters): pair-event totals over the rows of both
campaigns, the risk and loss-of-separation ratios over the same encounters with their bootstrap intervals, the
pass rate per kind, vehicle count and traffic class; keys merged only from rows flown by the flight code at HEAD."""

from __future__ import annotations

import json
import math
import subprocess
from pathlib import Path

import pytest

from tools.benchmarks.encounters import AVOID, WARN, flown_at, main, not_head_flight_code, ratio, results, totals
from tools.campaign.results import ShardWriter


def _row(case_id: int = 0, status: str = "ok", **traffic: object) -> dict:
    base = {
        "case_id": case_id, "traffic_vehicles": 2.0, "traffic_contacts": 0.0, "traffic_min_sep_m": 12.0,
        "traffic_volume_entries": 0.0, "traffic_volume_vehicles": 0.0, "traffic_min_dist_m": 9.0, "traffic_nmac": 0.0,
        "traffic_nmac_vehicles": 0.0, "traffic_ground_excluded": 0.0, "traffic_completion": 1.0, "fence_breaches": 0,
        "end_reason": "COMPLETED", "vary.encounter.manned": False, "vary.encounter.kind": "head_on",
        "vary.encounter.traffic": "none", "passed": status == "ok",
    }  # fmt: skip
    return {**base, "status": status, **traffic}


def test_totals_count_pair_events_weigh_completion_by_vehicles_and_skip_unjudged_cases() -> None:
    rows = [
        _row(0, traffic_vehicles=8.0, traffic_completion=0.75, traffic_min_sep_m=9.5, traffic_volume_entries=2.0,
             traffic_volume_vehicles=3.0, **{"vary.encounter.kind": "ring_swap"}, end_reason="STUCK"),
        _row(1, **{"vary.encounter.manned": True}, traffic_nmac=2.0, traffic_nmac_vehicles=1.0,
             traffic_ground_excluded=1.0, traffic_min_sep_m=math.nan),
        _row(2, "error", traffic_contacts=5.0, traffic_min_sep_m=0.1),  # could not be judged: counted apart
    ]  # fmt: skip
    t = totals(rows)
    assert (t["cases"], t["judged"], t["manned"], t["ring_swaps"], t["eight"]) == (3.0, 2.0, 1.0, 1.0, 1.0)
    assert t["completion"] == pytest.approx((8 * 0.75 + 2) / 10) and t["stuck"] == 1.0
    assert (t["contacts"], t["nmac"], t["nmac_vehicles"], t["ground_excluded"]) == (0.0, 2.0, 1.0, 1.0)
    assert (t["volume_entries"], t["volume_vehicles"], t["min_sep_m"]) == (2.0, 3.0, 9.5)
    keys = {r.key: r for r in results(rows, [_row(0, traffic_contacts=3.0), _row(1, traffic_nmac=4.0)])}
    assert not keys["traffic_min_sep_m"].met and not keys["traffic_volume_entries"].met
    assert not keys["traffic_completion"].met and keys["traffic_contacts"].met and not keys["traffic_nmac"].met
    assert keys["traffic_contacts_warn"].value == 3.0 and not keys["traffic_encounters"].met  # 2 < 1000
    assert keys["traffic_risk_ratio"].value == 0.5 and math.isnan(keys["traffic_los_ratio"].value)  # warn: 0 entries
    assert keys["traffic_pass_rate_kind_ring_swap"].value == 1.0 and keys["traffic_pass_rate_vehicles_8"].value == 1.0
    assert "traffic_pass_rate_class_none" in keys and keys["traffic_encounters_eight_share"].value == 0.5


def test_the_ratios_match_encounters_by_case_id_with_a_seeded_bootstrap_interval() -> None:
    """Events with avoidance / warn-only over the same encounters (case ids judged both ways), 95 % percentile
    bootstrap over the encounters: reproducible, containing the estimate, narrowing with more encounters."""
    avoid = [_row(k, traffic_nmac=float(k % 5 == 0)) for k in range(200)] + [_row(999, traffic_nmac=50.0)]
    warn = [_row(k, traffic_nmac=float(k % 2 == 0)) for k in range(200)] + [_row(7, "timeout")]
    value, low, high, matched = ratio(avoid, warn, "traffic_nmac")
    assert matched == 200 and value == pytest.approx(40 / 100)  # case 999 flew only with avoidance: left out
    assert low < value < high and (low, high) == ratio(avoid, warn, "traffic_nmac")[1:3]
    assert low > 0.25 and high < 0.6
    small = ratio(avoid[:40], warn[:40], "traffic_nmac")
    assert small[2] - small[1] > high - low
    assert math.isnan(ratio(avoid, [_row(k) for k in range(200)], "traffic_nmac")[0])  # warn-only had none


def test_no_event_with_avoidance_still_bounds_the_ratio_above_zero() -> None:
    """0 pair-events with avoidance against 66 warn-only: the bootstrap alone says [0, 0]; the exact Poisson-ratio
    bound (Clopper-Pearson on 0 of 66, 1 - 0.025 ** (1 / 66) = 0.0544 as p, p / (1 - p)) keeps it honest."""
    avoid = [_row(k) for k in range(100)]
    warn = [_row(k, traffic_nmac=float(k % 3 == 0) * 2.0) for k in range(100)]  # 34 cases x 2 = 68 events
    warn[0]["traffic_nmac"] = 0.0  # 66 events
    value, low, high, matched = ratio(avoid, warn, "traffic_nmac")
    p_high = 1.0 - 0.025 ** (1.0 / 66.0)
    assert (value, low, matched) == (0.0, 0.0, 100)
    assert high == pytest.approx(p_high / (1.0 - p_high)) and 0.05 < high < 0.06


def test_keys_from_folders_refuse_a_folder_of_another_campaign(tmp_path: Path) -> None:
    for name in ("a", "w"):
        (tmp_path / name).mkdir()
        (tmp_path / name / "campaign.yaml").write_text(AVOID.read_text() + "# edited\n")
    with pytest.raises(SystemExit) as exc:
        main(["--avoid-dir", str(tmp_path / "a"), "--warn-dir", str(tmp_path / "w")])
    assert exc.value.code == 2


def _git(root: Path, *args: str) -> str:
    out = subprocess.run(["git", "-C", str(root), *args], capture_output=True, text=True, check=True)
    return out.stdout.strip()


def test_rows_name_the_commit_that_flew_them_and_only_heads_flight_code_counts(tmp_path: Path) -> None:
    """A campaign folder flown over several sessions: each row's ``versions`` names its commit; a commit that
    changed only the docs flies the code at HEAD, one before a change under autopilot/ does not, nor one git does
    not know, nor HEAD itself with uncommitted flight code (``+dirty``)."""
    rows = [{"versions": "quadsitl 0.1, numpy 2.1, python 3.11.7, git abc1234"}] * 2 + [{"versions": "numpy 2.1"}]
    rows.append({"versions": "numpy 2.1, git abc1234+dirty"})  # flown from uncommitted flight code
    assert flown_at(rows) == {"abc1234": 2, "unknown": 1, "abc1234+dirty": 1}
    repo = tmp_path / "repo"
    (repo / "autopilot").mkdir(parents=True)
    _git(tmp_path, "init", "-q", str(repo))
    for name, text in (("autopilot/guard.py", "A = 1\n"), ("README.md", "docs\n"), ("autopilot/guard.py", "A = 2\n")):
        (repo / name).write_text(text)
        _git(repo, "add", "-A")
        _git(repo, "-c", "user.name=t", "-c", "user.email=t@t", "commit", "-qm", name)
    before, docs, head = _git(repo, "rev-list", "--max-count=3", "HEAD").split()[::-1]
    assert not_head_flight_code([head, docs, before, "0badc0de"], repo) == [docs, before, "0badc0de"]
    assert not_head_flight_code([f"{head}+dirty"], repo) == [f"{head}+dirty"]
    assert not_head_flight_code([head], repo) == []


def test_keys_are_not_merged_from_rows_of_other_flight_code(tmp_path: Path) -> None:
    for name, spec in (("a", AVOID), ("w", WARN)):
        (tmp_path / name).mkdir()
        (tmp_path / name / "campaign.yaml").write_text(spec.read_text())
        writer = ShardWriter(tmp_path / name)
        writer.add({**_row(0), "versions": "numpy 2.1, git 0badc0de"})
        writer.flush()
    out = tmp_path / "results.json"
    with pytest.raises(SystemExit) as exc:
        main(["--avoid-dir", str(tmp_path / "a"), "--warn-dir", str(tmp_path / "w"), "--merge-into", str(out)])
    assert exc.value.code == 2 and not out.exists()


def test_without_the_warn_only_folder_no_comparison_is_kept(tmp_path: Path) -> None:
    """Keys from the avoid folder alone: no ``_warn`` keys and no ratios, and merging drops those of an earlier set
    from the file (they compared other encounters), with its pass-rate keys; other suites' keys stay."""
    folder = tmp_path / "a"
    folder.mkdir()
    (folder / "campaign.yaml").write_text(AVOID.read_text())
    head = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True, check=True,
                          cwd=Path(__file__).parent).stdout.strip()  # fmt: skip
    writer = ShardWriter(folder)
    writer.add({**_row(0), "versions": f"numpy 2.1, git {head}"})
    writer.flush()
    out = tmp_path / "results.json"
    old = {"traffic_nmac_warn": 176.0, "traffic_risk_ratio": 0.0, "traffic_los_ratio_ci95_high": 0.004,
           "traffic_pass_rate_kind_depot": 0.5, "fleet_rtf_n8": 2.5}  # fmt: skip
    out.write_text(json.dumps(old))
    assert main(["--avoid-dir", str(folder), "--merge-into", str(out)]) == 0
    merged = json.loads(out.read_text())
    assert merged["fleet_rtf_n8"] == 2.5 and merged["traffic_encounters"] == 1.0
    assert not [k for k in merged if k.endswith("_warn") or "_ratio" in k or k == "traffic_pass_rate_kind_depot"]
    assert merged["traffic_pass_rate_kind_head_on"] == 1.0
