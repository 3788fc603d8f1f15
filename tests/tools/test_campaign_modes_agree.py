"""Every shipped campaign's default mode is one that flies its cases bit for bit: a single-vehicle campaign's
case flies to the same truth hash in process and as a real lockstep flight (so ``inproc`` is its default), and a
fleet (encounter) campaign stays ``inproc`` (its ``sitl`` flight arms on the wall clock: the same world, not the
same bits). Each case is cut to its first 50 s of sim time (past the first injected failure) to keep the test
short; ``python -m tools.benchmarks --only campaign`` compares whole cases."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import pytest

from tools.campaign.cases import draw, materialise
from tools.campaign.runner import payload_for
from tools.campaign.spec import load_campaign
from tools.campaign.task import run_case

pytestmark = [pytest.mark.slow]

SHIPPED = sorted((Path(__file__).resolve().parents[2] / "missions" / "campaigns").glob("*.yaml"))
PREFIX_S = 50.0


def _first_case_with_a_failure(spec: object) -> int:
    """The first case id that injects a failure (0 when the campaign injects none)."""
    return next((k for k in range(50) if draw(spec, k).failures), 0)  # type: ignore[arg-type]


@pytest.mark.parametrize("path", SHIPPED, ids=[p.stem for p in SHIPPED])
def test_every_shipped_campaign_flies_in_process(path: Path) -> None:
    spec = load_campaign(path)
    assert spec.mode == "inproc", f"{path.name}: a fleet replays bit for bit only in process, and a single vehicle "
    "flies the same hash in both modes (below)"


@pytest.mark.sitl
@pytest.mark.parametrize("name", ["delivery_wind_payload", "delivery_failures"])
def test_a_shipped_case_flies_to_the_same_truth_hash_in_both_modes(tmp_path: Path, name: str) -> None:
    spec = load_campaign(SHIPPED[0].parent / f"{name}.yaml")
    spec = dataclasses.replace(spec, sim_time_s=PREFIX_S)
    case = draw(spec, _first_case_with_a_failure(spec))
    rows = {}
    for mode in ("inproc", "sitl"):
        moded = dataclasses.replace(spec, mode=mode)
        rows[mode] = run_case(payload_for(moded, case, materialise(moded, case), tmp_path / mode))
    inproc, sitl = rows["inproc"], rows["sitl"]
    assert inproc["status"] == sitl["status"] and inproc["end_reason"] == sitl["end_reason"], (inproc, sitl)
    assert inproc["sim_time_s"] == sitl["sim_time_s"] == pytest.approx(PREFIX_S)
    assert len(inproc["truth_hash"]) == 64 and inproc["truth_hash"] == sitl["truth_hash"]
