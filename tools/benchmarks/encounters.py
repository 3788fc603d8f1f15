"""The encounter Monte Carlo (issue 23, docs/traffic.md): seeded fleets on conflicting routes, with the default
traffic avoidance and with warnings only, on the campaign engine.

``missions/campaigns/encounters.yaml`` (360 cases: 2-8 x500s head-on, crossing, overtaking, vertical, converging
on one depot with staggered take-offs; manned traffic in about one case of six) and
``encounters_warn_only.yaml`` (the same cases with NAV_TRAFF_AVOID 1) are flown on a LocalCluster (every case a
fleet flight in one process, ``tools.campaign.inproc_flight``: the simulator's fleet step and one autopilot per
vehicle with the EKF). ``--quick`` flies the first 4 cases of each. Keys: ``traffic_contacts`` (vehicle-vehicle
contacts over all cases, target 0), ``traffic_min_sep_m`` (the closest two airborne vehicles came in the UAV
volume's measure, max(horizontal, 2 x vertical) between centres: target >= 10 m, i.e. never inside 10 m / 5 m),
``traffic_volume_entries`` (vehicles that came inside it, target 0), ``traffic_min_dist_m`` (closest 3D approach,
surface to surface), ``traffic_nmac`` (vehicles inside a manned aircraft's NMAC volume, target 0),
``traffic_completion`` (fraction of all vehicles' missions completed, target >= 0.99), the same with ``_warn`` for
warnings only, and the counts.

The campaigns take hours on a 2-core machine; ``python -m tools.benchmarks.encounters --avoid-dir A --warn-dir W
[--merge-into bench/results.json]`` computes the keys from campaign folders flown with ``quadsitl campaign``
(the same files), printing the table (docs/traffic.md says how the committed numbers were made).
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
    dists = [r["traffic_min_dist_m"] for r in judged if math.isfinite(r["traffic_min_dist_m"])]
    return {
        "cases": float(len(rows)),
        "judged": float(len(judged)),
        "manned": float(sum(bool(r.get("vary.encounter.manned")) for r in judged)),
        "contacts": float(sum(r["traffic_contacts"] for r in judged)),
        "min_sep_m": min(seps) if seps else math.nan,
        "volume_entries": float(sum(r["traffic_volume_entries"] for r in judged)),
        "min_dist_m": min(dists) if dists else math.nan,
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
    return results(avoid, warn, quick)


def results(avoid: dict[str, float], warn: dict[str, float], quick: bool = False) -> list[BenchResult]:
    """The bench rows of the two campaigns' totals (``quick``: no target judged on the counts)."""
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
            target=">= 10",
            met=avoid["min_sep_m"] >= 10.0,
            note="closest airborne pair, max(horizontal, 2 x vertical) between centres: < 10 is inside 10 m / 5 m",
        ),
        BenchResult(
            "traffic_volume_entries",
            avoid["volume_entries"],
            target="== 0",
            met=avoid["volume_entries"] == 0,
            note="vehicles that came inside another's 10 m / 5 m volume",
        ),
        BenchResult("traffic_min_dist_m", avoid["min_dist_m"], note="closest 3D approach, surface to surface"),
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
        BenchResult("traffic_volume_entries_warn", warn["volume_entries"], note="warn only"),
        BenchResult("traffic_nmac_warn", warn["nmac"], note="warn only"),
        BenchResult("traffic_completion_warn", warn["completion"], note="warn only"),
    ]


def main(argv: list[str] | None = None) -> int:
    """Keys from campaign folders already flown (see the module docstring)."""
    import argparse
    import json

    from tools.campaign.results import read_rows

    parser = argparse.ArgumentParser(prog="python -m tools.benchmarks.encounters", description=main.__doc__)
    parser.add_argument("--avoid-dir", type=Path, required=True, help="a flown encounters.yaml campaign folder")
    parser.add_argument("--warn-dir", type=Path, required=True, help="a flown encounters_warn_only.yaml folder")
    parser.add_argument("--merge-into", type=Path, default=None, help="merge the keys into this results JSON")
    args = parser.parse_args(argv)
    rows = []
    for folder, spec in ((args.avoid_dir, AVOID), (args.warn_dir, WARN)):
        copy = folder / "campaign.yaml"
        if not copy.is_file() or copy.read_text() != spec.read_text():
            parser.error(
                f"{folder}: not a campaign flown from {spec.relative_to(REPO_ROOT)} (its campaign.yaml differs)"
            )
        rows.append(read_rows(folder))
    bench = results(totals(rows[0]), totals(rows[1]))
    for r in bench:
        met = "" if r.met is None else ("yes" if r.met else "NO")
        print(f"{r.key:<32} {r.value:>12.6g}  {r.target:<8} {met:<4} {r.note}")
    if args.merge_into is not None:
        merged = json.loads(args.merge_into.read_text()) if args.merge_into.is_file() else {}
        merged.update({r.key: r.value for r in bench})
        args.merge_into.write_text(json.dumps(merged, indent=2, sort_keys=True) + "\n")
        print(f"merged into {args.merge_into}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
