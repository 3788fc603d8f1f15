"""The encounter Monte Carlo's bench keys (tools.benchmarks.encounters): totals over the rows of both campaigns."""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from tools.benchmarks.encounters import AVOID, main, results, totals


def _row(status: str = "ok", **traffic: float) -> dict:
    base = {
        "traffic_vehicles": 2.0, "traffic_contacts": 0.0, "traffic_min_sep_m": 12.0, "traffic_volume_entries": 0.0,
        "traffic_min_dist_m": 9.0, "traffic_nmac": 0.0, "traffic_completion": 1.0, "fence_breaches": 0,
        "vary.encounter.manned": False,
    }  # fmt: skip
    return {**base, "status": status, **traffic}


def test_totals_weigh_completion_by_vehicles_and_skip_unjudged_cases() -> None:
    rows = [
        _row(traffic_vehicles=8.0, traffic_completion=0.75, traffic_min_sep_m=9.5, traffic_volume_entries=2.0),
        _row(**{"vary.encounter.manned": True}, traffic_nmac=1.0, traffic_min_sep_m=math.nan),
        _row("error", traffic_contacts=5.0, traffic_min_sep_m=0.1),  # could not be judged: counted apart
    ]
    t = totals(rows)
    assert (t["cases"], t["judged"], t["manned"]) == (3.0, 2.0, 1.0)
    assert t["completion"] == pytest.approx((8 * 0.75 + 2) / 10)
    assert (t["contacts"], t["nmac"], t["volume_entries"], t["min_sep_m"]) == (0.0, 1.0, 2.0, 9.5)
    keys = {r.key: r for r in results(t, totals([_row(traffic_contacts=3.0)]))}
    assert not keys["traffic_min_sep_m"].met and not keys["traffic_volume_entries"].met
    assert not keys["traffic_completion"].met and keys["traffic_contacts"].met
    assert keys["traffic_contacts_warn"].value == 3.0 and not keys["traffic_encounters"].met  # 2 < 300


def test_keys_from_folders_refuse_a_folder_of_another_campaign(tmp_path: Path) -> None:
    for name in ("a", "w"):
        (tmp_path / name).mkdir()
        (tmp_path / name / "campaign.yaml").write_text(AVOID.read_text() + "# edited\n")
    with pytest.raises(SystemExit) as exc:
        main(["--avoid-dir", str(tmp_path / "a"), "--warn-dir", str(tmp_path / "w")])
    assert exc.value.code == 2
