"""The encounter Monte Carlo (issues 23, 28, docs/traffic.md): seeded fleets on conflicting routes, with the
default traffic avoidance and with warnings only, over the same encounters, on the campaign engine.

``missions/campaigns/encounters.yaml`` (1000 cases of 2-8 x500s: head-on, crossing, overtaking, vertical,
converging, ring swaps, crossings with climbs and descents, a depot with take-offs and landings interleaved; manned
rotorcraft and light aircraft in about one case of five) and ``encounters_warn_only.yaml`` (the same cases with
NAV_TRAFF_AVOID 1) are flown on a LocalCluster (every case a fleet flight in one process,
``tools.campaign.inproc_flight``). ``--quick`` flies the first 4 cases of each.

Losses of separation are pair-events (``tools.campaign.fleet_record``; DEGAS counts NMACs this way for ACAS X):
``traffic_volume_entries`` (pairs of airborne vehicles inside the 10 m / 5 m UAV volume), ``traffic_nmac``
((vehicle, manned aircraft) pairs inside the NMAC volume with the vehicle in flight), each with its ``_vehicles``
count, ``traffic_ground_excluded`` (pairs inside a volume only while a vehicle stood on the ground: not counted
above, written so nothing is excluded silently), ``traffic_contacts`` (pairs that touched), ``traffic_completion``
(fraction of all vehicles' missions completed), ``traffic_encounters`` (cases judged) with the manned, ring-swap
and 8-vehicle counts, the same with ``_warn`` for warnings only. Over the cases judged both ways (by case id):
``traffic_risk_ratio`` = NMAC pair-events with avoidance / warn-only (DEGAS's risk ratio) and ``traffic_los_ratio``
= UAV-volume pair-events with avoidance / warn-only (its loss-of-separation ratio), each with a 95 % interval
(``_ci95_low``/``_ci95_high``: percentile bootstrap over the encounters, ``BOOTSTRAP`` resamples of the matched
cases, seeded), and the pass rate per encounter kind, vehicle count and traffic class (printed, and keys
``traffic_pass_rate_<group>_<level>``).

The campaigns take hours on a 2-core machine; ``python -m tools.benchmarks.encounters --avoid-dir A [--warn-dir W]
[--merge-into bench/results.json]`` computes the keys from campaign folders flown with ``quadsitl campaign``
(the same files; without the warn-only folder, no ``_warn`` keys and no ratios, and merging drops those from the
file: they would compare another set), printing the tables (docs/traffic.md says how the committed numbers were
made). The folders may have been flown over several sessions (``make encounters`` resumes the committed ones in
``bench/campaigns/``):
every row names the git commit that flew it, and the keys are merged only when each of those commits has the same
flight code (``FLIGHT_CODE``) as the checkout's HEAD: a committed number is a claim about the code at main.
"""

from __future__ import annotations

import dataclasses
import math
import re
import subprocess
import tempfile
from pathlib import Path
from typing import Any

import numpy as np

from tools.benchmarks import BenchResult
from tools.campaign.task import FLIGHT_CODE

REPO_ROOT = Path(__file__).resolve().parent.parent.parent
AVOID = REPO_ROOT / "missions" / "campaigns" / "encounters.yaml"
WARN = REPO_ROOT / "missions" / "campaigns" / "encounters_warn_only.yaml"
QUICK_CASES = 4
BOOTSTRAP = 2000
BOOTSTRAP_SEED = 28
#: The must-show of issue 28 (counts of the drawn mix, and the outcome with avoidance).
MIN_ENCOUNTERS, MIN_MANNED, MIN_RING_SWAPS, MIN_EIGHT_SHARE, MIN_COMPLETION = 1000, 150, 100, 0.2, 0.995
_JUDGED = ("ok", "fail")


def _rows(campaign: Path, cases: int | None, out_dir: Path, workers: int | None) -> list[dict[str, Any]]:
    from tools.campaign.results import read_rows
    from tools.campaign.runner import run_campaign
    from tools.campaign.spec import load_campaign

    spec = load_campaign(campaign)
    if cases is not None:
        spec = dataclasses.replace(spec, cases=cases)
    run_campaign(spec, out_dir, workers=workers, progress=False)
    return read_rows(out_dir)


def _sum(rows: list[dict[str, Any]], column: str) -> float:
    return float(sum(r[column] for r in rows if math.isfinite(r[column])))


def totals(rows: list[dict[str, Any]]) -> dict[str, float]:
    """The Monte Carlo's numbers over the rows of one campaign (cases that could not be judged are counted apart)."""
    judged = [r for r in rows if r["status"] in _JUDGED]
    vehicles = _sum(judged, "traffic_vehicles")
    seps = [r["traffic_min_sep_m"] for r in judged if math.isfinite(r["traffic_min_sep_m"])]
    dists = [r["traffic_min_dist_m"] for r in judged if math.isfinite(r["traffic_min_dist_m"])]
    done = sum(
        r["traffic_completion"] * r["traffic_vehicles"] for r in judged if math.isfinite(r["traffic_completion"])
    )
    return {
        "cases": float(len(rows)),
        "judged": float(len(judged)),
        "manned": float(sum(bool(r.get("vary.encounter.manned")) for r in judged)),
        "ring_swaps": float(sum(r.get("vary.encounter.kind") == "ring_swap" for r in judged)),
        "eight": float(sum(r["traffic_vehicles"] == 8 for r in judged)),
        "vehicles": vehicles,
        "contacts": _sum(judged, "traffic_contacts"),
        "volume_entries": _sum(judged, "traffic_volume_entries"),
        "volume_vehicles": _sum(judged, "traffic_volume_vehicles"),
        "nmac": _sum(judged, "traffic_nmac"),
        "nmac_vehicles": _sum(judged, "traffic_nmac_vehicles"),
        "ground_excluded": _sum(judged, "traffic_ground_excluded"),
        "min_sep_m": min(seps) if seps else math.nan,
        "min_dist_m": min(dists) if dists else math.nan,
        "completion": done / vehicles if vehicles else math.nan,
        "fence_breaches": float(sum(r["fence_breaches"] for r in judged)),
        "stuck": float(sum(r["end_reason"] == "STUCK" for r in judged)),
    }


def ratio(
    avoid: list[dict[str, Any]], warn: list[dict[str, Any]], column: str, resamples: int = BOOTSTRAP
) -> tuple[float, float, float, int]:
    """Events of ``column`` with avoidance / warn-only over the cases judged both ways (matched by case id), its
    95 % interval and the number of matched cases. NaN when warn-only has no event.

    The interval is the wider of two: the percentile bootstrap over the matched encounters (seeded; resamples
    without a warn-only event left out), which keeps the clustering of events within one encounter, and the exact
    interval of a ratio of two Poisson counts over the same exposure (``a`` given ``a + w`` is binomial with
    p = r / (1 + r); Clopper-Pearson on p). The bootstrap alone collapses to [0, 0] when avoidance has no event,
    a certainty the encounters flown cannot give: 0 against 66 warn-only events bounds the ratio by 0.057."""
    by_id = {r["case_id"]: r for r in warn if r["status"] in _JUDGED}
    pairs = [
        (r[column], by_id[r["case_id"]][column]) for r in avoid if r["status"] in _JUDGED and r["case_id"] in by_id
    ]
    if not pairs:
        return (math.nan, math.nan, math.nan, 0)
    a, w = (np.array(x, dtype=np.float64) for x in zip(*pairs, strict=True))
    if w.sum() == 0.0:
        return (math.nan, math.nan, math.nan, len(pairs))
    idx = np.random.default_rng(BOOTSTRAP_SEED).integers(0, len(pairs), size=(resamples, len(pairs)))
    num, den = a[idx].sum(axis=1), w[idx].sum(axis=1)
    boot = num[den > 0.0] / den[den > 0.0]
    low, high = np.percentile(boot, [2.5, 97.5])
    exact_low, exact_high = _poisson_ratio_interval(round(float(a.sum())), round(float(w.sum())))
    return (float(a.sum() / w.sum()), min(float(low), exact_low), max(float(high), exact_high), len(pairs))


def _poisson_ratio_interval(events_avoid: int, events_warn: int) -> tuple[float, float]:
    """Exact 95 % interval of the ratio of two Poisson rates over the same exposure, from the conditional binomial
    (Clopper-Pearson on events_avoid of events_avoid + events_warn, p mapped to p / (1 - p))."""
    from tools.campaign.report import pass_interval

    p_low, p_high = pass_interval(events_avoid, events_avoid + events_warn)
    return (p_low / (1.0 - p_low), p_high / (1.0 - p_high) if p_high < 1.0 else math.inf)


def flown_at(rows: list[dict[str, Any]]) -> dict[str, int]:
    """The git commits the rows were flown at (their ``versions`` column's ``git <commit>``, ``+dirty`` kept:
    uncommitted flight code; ``unknown`` when a row has none) and how many rows each flew, in the order first
    seen."""
    commits: dict[str, int] = {}
    for r in rows:
        found = re.search(r"\bgit ([0-9a-f]{4,40}(?:\+dirty)?)(?![\w+])", str(r.get("versions") or ""))
        commit = found.group(1) if found else "unknown"
        commits[commit] = commits.get(commit, 0) + 1
    return commits


def not_head_flight_code(commits: list[str], root: Path = REPO_ROOT) -> list[str]:
    """The commits among ``commits`` whose ``FLIGHT_CODE`` differs from HEAD's in the checkout at ``root`` (or that
    git does not know there, or that flew uncommitted flight code: ``+dirty``)."""
    stale = []
    for commit in commits:
        if commit.endswith("+dirty"):
            stale.append(commit)
            continue
        try:
            diff = subprocess.run(["git", "-C", str(root), "diff", "--quiet", commit, "HEAD", "--", *FLIGHT_CODE],
                                  capture_output=True, timeout=60, check=False)  # fmt: skip
            same = diff.returncode == 0
        except (OSError, subprocess.TimeoutExpired):
            same = False
        if not same:
            stale.append(commit)
    return stale


def pass_rates(rows: list[dict[str, Any]]) -> dict[str, dict[str, dict[str, float]]]:
    """Pass rate (with its exact interval) per encounter kind, vehicle count and traffic class (the report's)."""
    from tools.campaign.report import fleet_groups

    return fleet_groups(rows)


def run(quick: bool, cases: int | None = None, workers: int | None = None) -> list[BenchResult]:
    n = QUICK_CASES if quick else cases
    with tempfile.TemporaryDirectory(prefix="bench-encounters-") as tmp:
        avoid = _rows(AVOID, n, Path(tmp) / "avoid", workers)
        warn = _rows(WARN, n, Path(tmp) / "warn", workers)
    _print_groups(avoid, warn)
    return results(avoid, warn, quick)


#: The keys of the warn-only comparison (``_warn`` and the two ratios): dropped from a results file merged without it.
WARN_KEY = re.compile(r"^traffic_\w+_warn$|^traffic_(risk|los)_ratio")


def results(
    avoid_rows: list[dict[str, Any]], warn_rows: list[dict[str, Any]] | None, quick: bool = False
) -> list[BenchResult]:
    """The bench rows of the two campaigns (``quick``: no target judged on the counts); ``warn_rows`` None: the
    warn-only campaign not flown yet (no ``_warn`` keys, no ratios)."""
    avoid = totals(avoid_rows)

    def count(key: str, value: float, low: float, note: str) -> BenchResult:
        return BenchResult(key, value, target=f">= {low:g}", met=None if quick else value >= low, note=note)

    def zero(key: str, value: float, note: str) -> BenchResult:
        return BenchResult(key, value, target="== 0", met=value == 0, note=note)

    judged = avoid["judged"]
    out = [
        count(
            "traffic_encounters",
            judged,
            MIN_ENCOUNTERS,
            f"judged of {avoid['cases']:g}, {avoid['vehicles']:g} vehicles",
        ),
        count("traffic_encounters_manned", avoid["manned"], MIN_MANNED, "with manned traffic"),
        count("traffic_encounters_ring_swap", avoid["ring_swaps"], MIN_RING_SWAPS, "antipodal ring swaps of 4-8"),
        count(
            "traffic_encounters_eight_share",
            avoid["eight"] / judged if judged else math.nan,
            MIN_EIGHT_SHARE,
            "share with 8 vehicles",
        ),
        zero("traffic_contacts", avoid["contacts"], "pairs of vehicles that touched, NAV_TRAFF_AVOID 5 (avoid)"),
        zero("traffic_volume_entries", avoid["volume_entries"], "pairs of airborne vehicles inside 10 m / 5 m"),
        BenchResult("traffic_volume_vehicles", avoid["volume_vehicles"], note="vehicles in those pairs"),
        zero("traffic_nmac", avoid["nmac"], "(vehicle, manned aircraft) pairs inside the NMAC volume in flight"),
        BenchResult("traffic_nmac_vehicles", avoid["nmac_vehicles"], note="vehicles in those pairs"),
        BenchResult(
            "traffic_ground_excluded",
            avoid["ground_excluded"],
            note="pairs inside a volume only with a vehicle on the ground: not counted above",
        ),
        BenchResult(
            "traffic_min_sep_m",
            avoid["min_sep_m"],
            target=">= 10",
            met=avoid["min_sep_m"] >= 10.0,
            note="closest airborne pair, max(horizontal, 2 x vertical) between centres: < 10 is inside 10 m / 5 m",
        ),
        BenchResult("traffic_min_dist_m", avoid["min_dist_m"], note="closest 3D approach, surface to surface"),
        BenchResult(
            "traffic_completion",
            avoid["completion"],
            target=f">= {MIN_COMPLETION:g}",
            met=avoid["completion"] >= MIN_COMPLETION,
            note="vehicles' missions completed",
        ),
        zero("traffic_fence_breaches", avoid["fence_breaches"], ""),
        BenchResult("traffic_stuck", avoid["stuck"], note="cases ended STUCK"),
    ]
    for group, levels in pass_rates(avoid_rows).items():
        for level, s in levels.items():
            slug = group.split()[-1]
            out.append(BenchResult(f"traffic_pass_rate_{slug}_{level}", s["pass_rate"], note=f"{s['cases']:g} cases"))
    if warn_rows is None:
        return out
    for key, column, what in (
        ("traffic_risk_ratio", "traffic_nmac", "NMAC pair-events"),
        ("traffic_los_ratio", "traffic_volume_entries", "UAV-volume pair-events"),
    ):
        value, low, high, matched = ratio(avoid_rows, warn_rows, column)
        note = f"{what} avoid / warn-only, {matched} encounters judged both ways; 95 % [{low:.3g}, {high:.3g}]"
        out += [
            BenchResult(key, value, note=note),
            BenchResult(f"{key}_ci95_low", low),
            BenchResult(f"{key}_ci95_high", high),
        ]
    warn = totals(warn_rows)
    warn_keys = ("contacts", "volume_entries", "volume_vehicles", "nmac", "nmac_vehicles", "ground_excluded")
    for name, key in [*((k, k) for k in (*warn_keys, "min_sep_m", "completion")), ("encounters", "judged")]:
        out.append(BenchResult(f"traffic_{name}_warn", warn[key], note="the same encounters, NAV_TRAFF_AVOID 1"))
    return out


def _print_groups(avoid: list[dict[str, Any]], warn: list[dict[str, Any]]) -> None:
    """The pass rate per encounter kind, vehicle count and traffic class, both ways."""
    both = (pass_rates(avoid), pass_rates(warn))
    print(f"{'group':<8} {'level':<16} {'cases':>6} {'avoid pass':>11} {'95 % interval':>17} {'warn pass':>10}")
    for group, levels in both[0].items():
        for level, s in levels.items():
            w = both[1].get(group, {}).get(level)
            warn_text = f"{w['pass_rate']:.1%}" if w else "-"
            print(f"{group.split()[-1]:<8} {level:<16} {s['cases']:>6g} {s['pass_rate']:>11.1%} "
                  f"[{s['ci95_low']:6.1%}, {s['ci95_high']:6.1%}] {warn_text:>10}")  # fmt: skip


def main(argv: list[str] | None = None) -> int:
    """Keys from campaign folders already flown (see the module docstring)."""
    import argparse
    import json

    from tools.campaign.results import read_rows

    parser = argparse.ArgumentParser(prog="python -m tools.benchmarks.encounters", description=main.__doc__)
    parser.add_argument("--avoid-dir", type=Path, required=True, help="a flown encounters.yaml campaign folder")
    warn_help = "a flown encounters_warn_only.yaml folder (without it: no _warn keys, no ratios)"
    parser.add_argument("--warn-dir", type=Path, default=None, help=warn_help)
    parser.add_argument("--merge-into", type=Path, default=None, help="merge the keys into this results JSON")
    args = parser.parse_args(argv)

    def flown(folder: Path, spec: Path) -> list[dict[str, Any]]:
        """The folder's rows, after checking it flew ``spec`` and saying which commits flew them."""
        copy = folder / "campaign.yaml"
        if not copy.is_file() or copy.read_text() != spec.read_text():
            parser.error(
                f"{folder}: not a campaign flown from {spec.relative_to(REPO_ROOT)} (its campaign.yaml differs)"
            )
        rows = read_rows(folder)
        commits = flown_at(rows)
        stale = not_head_flight_code(list(commits))
        said = ", ".join(f"{c} ({n} rows)" for c, n in commits.items())
        print(f"{folder}: flown at {said}; flight code as at HEAD: {'no: ' + ', '.join(stale) if stale else 'yes'}")
        if stale and args.merge_into is not None:
            why = f"{', '.join(stale)}: {' '.join(FLIGHT_CODE)} differ"
            parser.error(f"{folder}: rows flown by other flight code than HEAD's ({why}); fly them again first")
        return rows

    avoid = flown(args.avoid_dir, AVOID)
    warn = flown(args.warn_dir, WARN) if args.warn_dir is not None else None
    if warn is None:
        print("warn-only: no folder given (no _warn keys, no risk or loss-of-separation ratio)")
    _print_groups(avoid, warn or [])
    bench = results(avoid, warn)
    for r in bench:
        met = "" if r.met is None else ("yes" if r.met else "NO")
        print(f"{r.key:<40} {r.value:>12.6g}  {r.target:<8} {met:<4} {r.note}")
    if args.merge_into is not None:
        merged = json.loads(args.merge_into.read_text()) if args.merge_into.is_file() else {}
        # the keys of this set only: pass rates of groups it has not, and a comparison it was not flown with, go
        for key in [k for k in merged if k.startswith("traffic_pass_rate_") or (warn is None and WARN_KEY.match(k))]:
            del merged[key]
        merged.update({r.key: r.value for r in bench})
        args.merge_into.write_text(json.dumps(merged, indent=2, sort_keys=True) + "\n")
        print(f"merged into {args.merge_into}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
