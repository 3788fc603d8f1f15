"""The encounter Monte Carlo (issue 23, docs/traffic.md): seeded fleets on conflicting routes, with the default
traffic avoidance and with warnings only, on the campaign engine.

``missions/campaigns/encounters.yaml`` (360 cases: 2-8 x500s head-on, crossing, overtaking, vertical, converging
on one depot with staggered take-offs; manned traffic in about one case of six) and
``encounters_warn_only.yaml`` (the same cases with NAV_TRAFF_AVOID 1) are flown on a LocalCluster (every case a
real fleet flight: one simulator, one autopilot per vehicle, the fleet ground station). ``--quick`` flies the
first 4 cases of each. Keys: ``traffic_contacts`` (vehicle-vehicle contacts over all cases, target 0),
``traffic_min_sep_m`` (the closest approach of two vehicles over all cases, surface to surface),
``traffic_nmac`` (vehicles inside a manned aircraft's NMAC volume, target 0), ``traffic_completion`` (fraction of
all vehicles' missions completed, target >= 0.99), the same with ``_warn`` for warnings only, and the counts.
"""

from __future__ import annotations

import dataclasses
import math
import tempfile
from pathlib import Path
from typing import Any

from tools.benchmarks import BenchResult

REPO_ROOT = Path(__file__).resolve().parent.parent.parent
AVOID = REPO_ROOT / "missions" / "campaigns" / "encounters.yaml"
WARN = REPO_ROOT / "missions" / "campaigns" / "encounters_warn_only.yaml"
QUICK_CASES = 4


def _rows(campaign: Path, cases: int | None, out_dir: Path, workers: int | None) -> list[dict[str, Any]]:
    from tools.campaign.results import read_rows
    from tools.campaign.runner import run_campaign
    from tools.campaign.spec import load_campaign

    spec = load_campaign(campaign)
    if cases is not None:
        spec = dataclasses.replace(spec, cases=cases)
    run_campaign(spec, out_dir, workers=workers, progress=False)
    return read_rows(out_dir)


def totals(rows: list[dict[str, Any]]) -> dict[str, float]:
    """The Monte Carlo's numbers over the rows of one campaign (cases that could not be judged are counted apart)."""
    judged = [r for r in rows if r["status"] in ("ok", "fail")]
    vehicles = sum(r["traffic_vehicles"] for r in judged)
    seps = [r["traffic_min_sep_m"] for r in judged if math.isfinite(r["traffic_min_sep_m"])]
    return {
        "cases": float(len(rows)),
        "judged": float(len(judged)),
        "manned": float(sum(bool(r.get("vary.encounter.manned")) for r in judged)),
        "contacts": float(sum(r["traffic_contacts"] for r in judged)),
        "min_sep_m": min(seps) if seps else math.nan,
        "nmac": float(sum(r["traffic_nmac"] for r in judged)),
        "completion": sum(r["traffic_completion"] * r["traffic_vehicles"] for r in judged) / vehicles
        if vehicles
        else math.nan,
        "fence_breaches": float(sum(r["fence_breaches"] for r in judged)),
    }


def run(quick: bool, cases: int | None = None, workers: int | None = None) -> list[BenchResult]:
    n = QUICK_CASES if quick else cases
    with tempfile.TemporaryDirectory(prefix="bench-encounters-") as tmp:
        avoid = totals(_rows(AVOID, n, Path(tmp) / "avoid", workers))
        warn = totals(_rows(WARN, n, Path(tmp) / "warn", workers))
    what = f"{avoid['judged']:g}/{avoid['cases']:g} encounters judged ({avoid['manned']:g} with manned traffic)"
    return [
        BenchResult(
            "traffic_encounters",
            avoid["judged"],
            target=">= 300",
            met=None if quick else avoid["judged"] >= 300,
            note=what,
        ),
        BenchResult(
            "traffic_encounters_manned", avoid["manned"], target=">= 50", met=None if quick else avoid["manned"] >= 50
        ),
        BenchResult(
            "traffic_contacts",
            avoid["contacts"],
            target="== 0",
            met=avoid["contacts"] == 0,
            note="vehicle-vehicle contacts, NAV_TRAFF_AVOID 5 (avoid)",
        ),
        BenchResult(
            "traffic_min_sep_m",
            avoid["min_sep_m"],
            note="closest two vehicles came, surface to surface (volume: 10 m h / 5 m v about centres)",
        ),
        BenchResult(
            "traffic_nmac",
            avoid["nmac"],
            target="== 0",
            met=avoid["nmac"] == 0,
            note="vehicles inside a manned NMAC volume",
        ),
        BenchResult(
            "traffic_completion",
            avoid["completion"],
            target=">= 0.99",
            met=avoid["completion"] >= 0.99,
            note="vehicles' missions completed",
        ),
        BenchResult("traffic_fence_breaches", avoid["fence_breaches"], target="== 0", met=avoid["fence_breaches"] == 0),
        BenchResult(
            "traffic_contacts_warn", warn["contacts"], note="the same encounters, NAV_TRAFF_AVOID 1 (warn only)"
        ),
        BenchResult("traffic_min_sep_m_warn", warn["min_sep_m"], note="warn only"),
        BenchResult("traffic_nmac_warn", warn["nmac"], note="warn only"),
        BenchResult("traffic_completion_warn", warn["completion"], note="warn only"),
    ]
