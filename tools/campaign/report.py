"""``summary.json`` and ``report.md`` of a campaign: pass rate with its exact (Clopper-Pearson) 95 % interval,
the pass rate per level of every ``choice`` input, ECDF plots (PNG) of clearance, tracking error and energy,
the failures grouped by reason, and the ten worst cases with the command that replays each.

Fleet cases (rows with the traffic columns, ``tools.campaign.fleet_record``) add the pass rate per encounter kind,
vehicle count and traffic class (:func:`fleet_groups`), the traffic totals (contacts, pair-events inside the UAV
volume and the NMAC volume, excluded ground events, completion over the vehicles) and ECDFs of the separations
(closest airborne pair in the UAV volume's measure, closest 3D approach, closest approach to manned traffic)."""

from __future__ import annotations

import json
import math
import re
from collections import Counter, defaultdict
from pathlib import Path
from typing import Any

from tools.campaign.results import finite, read_rows
from tools.campaign.spec import CampaignSpec

SUMMARY_FILE = "summary.json"
REPORT_FILE = "report.md"
WORST_N = 10
#: (column, axis label, PNG name) of the ECDF plots.
ECDFS = (
    ("min_clearance_m", "minimum clearance to obstacles [m]", "ecdf_clearance.png"),
    ("tracking_pos_rms_m", "position tracking error RMS [m]", "ecdf_tracking.png"),
    ("energy_used_frac", "battery used [fraction of capacity]", "ecdf_energy.png"),
    ("traffic_min_sep_m", "closest airborne pair, max(horizontal, 2 x vertical) [m] (< 10: inside)", "ecdf_sep.png"),
    ("traffic_min_dist_m", "closest approach of two vehicles, surface to surface [m]", "ecdf_dist.png"),
    ("traffic_min_manned_m", "closest approach to a manned aircraft [m]", "ecdf_manned.png"),
)
#: Columns summarised in the distributions table (those with a value in some row).
METRICS = (
    "min_clearance_m", "tracking_pos_rms_m", "tracking_pos_max_m", "max_tilt_deg", "energy_used_frac",
    "traffic_min_sep_m", "traffic_min_dist_m", "traffic_min_manned_m", "traffic_completion",
)  # fmt: skip
#: The groups of fleet cases the pass rate is given per: (name, row column).
FLEET_GROUPS = (
    ("encounter kind", "vary.encounter.kind"),
    ("vehicles", "traffic_vehicles"),
    ("traffic class", "vary.encounter.traffic"),
)
#: Traffic totals over the fleet cases (row column, label).
TRAFFIC_TOTALS = (
    ("traffic_contacts", "vehicle-vehicle contacts (pairs)"),
    ("traffic_volume_entries", "pairs of airborne vehicles inside the UAV volume (10 m / 5 m)"),
    ("traffic_volume_vehicles", "vehicles in those pairs"),
    ("traffic_nmac", "(vehicle, manned aircraft) pairs inside the NMAC volume in flight"),
    ("traffic_nmac_vehicles", "vehicles in those pairs"),
    ("traffic_ground_excluded", "pairs inside a volume only with a vehicle on the ground (excluded)"),
)
_STATUS_ORDER = {"error": 0, "timeout": 1, "fail": 2, "ok": 3}


def pass_interval(passed: int, n: int) -> tuple[float, float]:
    """Exact (Clopper-Pearson) 95 % interval of the pass rate (scipy's ``binomtest``)."""
    if n == 0:
        return (math.nan, math.nan)
    from scipy.stats import binomtest

    ci = binomtest(passed, n).proportion_ci(confidence_level=0.95, method="exact")
    return (float(ci.low), float(ci.high))


def reason_groups(rows: list[dict[str, Any]]) -> dict[str, int]:
    """Failing rows counted per reason (a reason's numbers dropped: 'collisions', 'flight ended GROUND_IMPACT')."""
    counts: Counter[str] = Counter()
    for r in rows:
        if r["status"] == "ok":
            continue
        if r["status"] in ("timeout", "error"):
            counts[f"{r['status']}: {re.sub(r'[0-9.]+', 'N', str(r['reason']))[:80]}"] += 1
            continue
        for part in str(r["reason"]).split("; "):
            part = re.sub(r" at [0-9.]+ s$", "", part)
            counts[part if part.startswith("flight ended") else part.split(" ")[0]] += 1
    return dict(counts.most_common())


def worst(rows: list[dict[str, Any]], n: int = WORST_N) -> list[dict[str, Any]]:
    """Errors, timeouts and failures first, then the largest tracking error (fleet cases: the closest pair)."""

    def key(r: dict[str, Any]) -> tuple[int, float]:
        if "traffic_vehicles" in r:
            sep = r.get("traffic_min_sep_m")
            return (_STATUS_ORDER.get(r["status"], 9), sep if isinstance(sep, float) and math.isfinite(sep) else 1e9)
        rms = r.get("tracking_pos_rms_m")
        return (_STATUS_ORDER.get(r["status"], 9), -(rms if isinstance(rms, float) and math.isfinite(rms) else -1.0))

    return sorted(rows, key=key)[:n]


def per_level(spec: CampaignSpec, rows: list[dict[str, Any]]) -> dict[str, dict[str, dict[str, float]]]:
    """Pass rate (with its interval) per level of each ``choice`` input."""
    out: dict[str, dict[str, dict[str, float]]] = {}
    for key, dist in spec.vary:
        if dist.kind != "choice":
            continue
        column = key if key in ("vehicle", "params", "failures") else f"vary.{key}"
        by_level: dict[str, list[bool]] = defaultdict(list)
        for r in rows:
            by_level[str(r.get(column))].append(bool(r["passed"]))
        out[key] = {}
        for level, passes in sorted(by_level.items()):
            low, high = pass_interval(sum(passes), len(passes))
            out[key][level] = {
                "cases": len(passes),
                "pass_rate": sum(passes) / len(passes),
                "ci95_low": low,
                "ci95_high": high,
            }
    return out


def _level(value: Any) -> str:
    """A group's level as text (a float vehicle count as an integer)."""
    if isinstance(value, float) and value.is_integer():
        return str(int(value))
    return str(value)


def fleet_groups(rows: list[dict[str, Any]]) -> dict[str, dict[str, dict[str, float]]]:
    """For fleet cases: pass rate (with its interval) per encounter kind, vehicle count and traffic class (the
    groups whose column some row has); empty when no row is a fleet case."""
    fleet = [r for r in rows if "traffic_vehicles" in r]
    out: dict[str, dict[str, dict[str, float]]] = {}
    for name, column in FLEET_GROUPS:
        by_level: dict[str, list[bool]] = defaultdict(list)
        for r in fleet:
            if r.get(column) is not None:
                by_level[_level(r[column])].append(bool(r["passed"]))
        if not by_level:
            continue
        out[name] = {}
        for level, passes in sorted(by_level.items(), key=lambda kv: (len(kv[0]), kv[0])):
            low, high = pass_interval(sum(passes), len(passes))
            out[name][level] = {"cases": len(passes), "pass_rate": sum(passes) / len(passes), "ci95_low": low,
                                "ci95_high": high}  # fmt: skip
    return out


def traffic_totals(rows: list[dict[str, Any]]) -> dict[str, float] | None:
    """The traffic totals over the fleet cases that were judged (``ok``/``fail``) and the completion over their
    vehicles; None when no row is a fleet case."""
    judged = [r for r in rows if "traffic_vehicles" in r and r["status"] in ("ok", "fail")]
    if not judged:
        return None
    out = {column: sum(finite([r.get(column) for r in judged])) for column, _ in TRAFFIC_TOTALS}
    vehicles = sum(finite([r.get("traffic_vehicles") for r in judged]))
    done = sum(finite([r.get("traffic_completion", 0.0) * r.get("traffic_vehicles", 0.0) for r in judged]))
    return {
        "cases": float(len(judged)),
        "vehicles": vehicles,
        **out,
        "completion": done / vehicles if vehicles else math.nan,
    }


def _plot_ecdfs(rows: list[dict[str, Any]], out_dir: Path) -> list[str]:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    written = []
    for column, label, name in ECDFS:
        values = finite([r.get(column) for r in rows])
        if not values:
            continue
        fig, ax = plt.subplots(figsize=(6, 3.6))
        ax.ecdf(values)
        ax.set_xlabel(label)
        ax.set_ylabel("fraction of cases")
        ax.grid(True, alpha=0.3)
        ax.set_title(f"{column}: {len(values)} cases")
        fig.tight_layout()
        fig.savefig(out_dir / name, dpi=110)
        plt.close(fig)
        written.append(name)
    return written


def _stat(values: list[float]) -> dict[str, float] | None:
    if not values:
        return None
    s = sorted(values)
    return {"min": s[0], "median": s[len(s) // 2], "p95": s[min(len(s) - 1, int(0.95 * len(s)))], "max": s[-1]}


def summarise(spec: CampaignSpec, out_dir: Path, rows: list[dict[str, Any]]) -> dict[str, Any]:
    n = len(rows)
    passed = sum(bool(r["passed"]) for r in rows)
    low, high = pass_interval(passed, n)
    walls = finite([r.get("wall_time_s") for r in rows])
    return {
        "campaign": spec.name,
        "mode": spec.mode,
        "cases_planned": spec.cases,
        "cases_done": n,
        "status_counts": dict(Counter(r["status"] for r in rows)),
        "passed": passed,
        "pass_rate": passed / n if n else math.nan,
        "pass_rate_ci95": [low, high],
        "failures_by_reason": reason_groups(rows),
        "per_level": per_level(spec, rows),
        "fleet_groups": fleet_groups(rows),
        "traffic": traffic_totals(rows),
        "metrics": {c: _stat(finite([r.get(c) for r in rows])) for c in METRICS},
        "case_wall_s_mean": sum(walls) / len(walls) if walls else math.nan,
        "worst": [
            {
                "case_id": r["case_id"],
                "status": r["status"],
                "reason": r["reason"],
                "replay": replay_command(out_dir, r["case_id"]),
            }
            for r in worst(rows)
        ],
    }


def replay_command(out_dir: Path, case_id: int) -> str:
    return f"quadsitl campaign replay {out_dir} {case_id}"


def write_report(spec: CampaignSpec, out_dir: Path) -> dict[str, Any]:
    """Write ``summary.json``, ``report.md`` and the ECDF PNGs for the rows in ``out_dir``; the summary."""
    rows = read_rows(out_dir)
    summary = summarise(spec, out_dir, rows)
    (out_dir / SUMMARY_FILE).write_text(json.dumps(summary, indent=2) + "\n")
    plots = _plot_ecdfs(rows, out_dir)
    low, high = summary["pass_rate_ci95"]
    lines = [
        f"# Campaign {spec.name}",
        "",
        f"{summary['cases_done']} of {spec.cases} cases ({spec.mode}, root seed {spec.seed}, base "
        f"{', '.join(spec.bases)}). Status: "
        + ", ".join(f"{k} {v}" for k, v in sorted(summary["status_counts"].items())),
        "",
        f"**Pass rate {summary['pass_rate']:.1%}** ({summary['passed']}/{summary['cases_done']}), exact 95 % "
        f"interval [{low:.1%}, {high:.1%}] (Clopper-Pearson). Pass if: "
        + ", ".join(_rule_text(r) for r in spec.pass_if)
        + ".",
        "",
    ]
    lines += _pass_rate_table("Pass rate per input level", "input", summary["per_level"])
    lines += _fleet_lines(summary)
    lines += ["## Failures by reason", ""]
    lines += [f"- {count} x {reason}" for reason, count in summary["failures_by_reason"].items()] or ["- none"]
    lines += ["", "## Distributions", ""]
    for name in plots:
        lines += [f"![{name}]({name})", ""]
    lines += ["| metric | min | median | p95 | max |", "|---|---|---|---|---|"]
    for column, s in summary["metrics"].items():
        if s is not None:
            lines.append(f"| {column} | {s['min']:.3f} | {s['median']:.3f} | {s['p95']:.3f} | {s['max']:.3f} |")
    lines += [
        "",
        f"## The {min(WORST_N, len(rows))} worst cases",
        "",
        "| case | status | reason | tracking RMS [m] (fleet: closest pair [m]) | replay |",
        "|---|---|---|---|---|",
    ]
    for r in worst(rows):
        rms = r.get("traffic_min_sep_m" if "traffic_vehicles" in r else "tracking_pos_rms_m")
        rms_text = f"{rms:.3f}" if isinstance(rms, float) and math.isfinite(rms) else "-"
        reason = str(r["reason"]).replace("|", "/").replace("\n", " ")[:120] or "-"
        lines.append(
            f"| {r['case_id']} | {r['status']} | {reason} | {rms_text} | `{replay_command(out_dir, r['case_id'])}` |"
        )
    (out_dir / REPORT_FILE).write_text("\n".join(lines) + "\n")
    return summary


def _fleet_lines(summary: dict[str, Any]) -> list[str]:
    """The report's fleet sections: traffic totals and the pass rate per kind, vehicle count, traffic class."""
    traffic = summary["traffic"]
    if traffic is None:
        return []
    lines = [
        "## Traffic",
        "",
        f"Over {traffic['cases']:g} judged fleet cases, {traffic['vehicles']:g} vehicles (simulator truth; a pair "
        "inside a volume is one event however often; docs/traffic.md):",
        "",
        "| total | value |",
        "|---|---|",
    ]
    lines += [f"| {label} (`{column}`) | {traffic[column]:g} |" for column, label in TRAFFIC_TOTALS]
    lines += [f"| missions completed (`traffic_completion`, over the vehicles) | {traffic['completion']:.1%} |", ""]
    return lines + _pass_rate_table(
        "Pass rate per encounter kind, vehicle count and traffic class", "group", summary["fleet_groups"]
    )


def _pass_rate_table(title: str, key_header: str, groups: dict[str, dict[str, dict[str, Any]]]) -> list[str]:
    """A report section of pass rates per level of each key, with their exact 95 % intervals (none if no groups)."""
    if not groups:
        return []
    header = f"| {key_header} | level | cases | pass rate | 95 % interval |"
    lines = [f"## {title}", "", header, "|---|---|---|---|---|"]
    for key, levels in groups.items():
        for level, s in levels.items():
            lines.append(f"| {key} | `{level}` | {s['cases']} | {s['pass_rate']:.1%} | "
                         f"[{s['ci95_low']:.1%}, {s['ci95_high']:.1%}] |")  # fmt: skip
    return [*lines, ""]


def _rule_text(rule: Any) -> str:
    if rule.equals is not None:
        return f"{rule.column} = {str(rule.equals).lower()}"
    parts = [f">= {rule.min:g}" if rule.min is not None else "", f"<= {rule.max:g}" if rule.max is not None else ""]
    return f"{rule.column} {' and '.join(p for p in parts if p)}"
