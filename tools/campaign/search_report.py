"""``summary.json`` and ``report.md`` of a search (the margin found against flights spent, a PNG of it, the worst
cases with their inputs and replay commands) and of an estimate (the levels, the importance-sampling estimate
with its interval, effective sample size and mean weight, the plain Monte Carlo beside it)."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np

from tools.campaign.estimate import mc_interval
from tools.campaign.report import REPORT_FILE, SUMMARY_FILE
from tools.campaign.results import read_rows
from tools.campaign.search import first_failure
from tools.campaign.spec import CampaignSpec

WORST_N = 10
PLOT_FILE = "margin_vs_flights.png"


def _inputs(spec: CampaignSpec, r: dict[str, Any]) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for key, _ in spec.vary:
        value = r.get(key if key in ("vehicle", "params", "failures") else f"vary.{key}")
        out[key] = round(value, 4) if isinstance(value, float) else value
    return out


def _worst(spec: CampaignSpec, rows: list[dict[str, Any]]) -> list[dict[str, Any]]:
    known = [r for r in rows if isinstance(r.get("margin"), float) and math.isfinite(r["margin"])]
    return [
        {"case_id": r["case_id"], "margin": r["margin"], "status": r["status"], "reason": r["reason"],
         "inputs": _inputs(spec, r), "sim_seed": r["sim_seed"], "replay": r["replay"]}
        for r in sorted(known, key=lambda r: (r["margin"], r["case_id"]))[:WORST_N]
    ]  # fmt: skip


def _worst_table(worst: list[dict[str, Any]]) -> list[str]:
    lines = ["| case | margin | status | inputs | replay |", "|---|---|---|---|---|"]
    for w in worst:
        inputs = ", ".join(f"{k} {v}" for k, v in w["inputs"].items())
        lines.append(f"| {w['case_id']} | {w['margin']:.4g} | {w['status']} | {inputs} | `{w['replay']}` |")
    return lines


def _plot(rows: list[dict[str, Any]], out_dir: Path, title: str) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    ids = np.array([r["case_id"] + 1 for r in rows])
    m = np.array([r["margin"] for r in rows], dtype=float)
    best = np.fmin.accumulate(np.where(np.isfinite(m), m, np.inf))
    fig, ax = plt.subplots(figsize=(6, 3.6))
    ax.scatter(ids, m, s=6, alpha=0.5, label="each flight")
    ax.step(ids, best, where="post", color="C3", label="lowest so far")
    ax.axhline(0.0, color="k", lw=0.8)
    ax.set_xlabel("flights")
    ax.set_ylabel("margin (< 0: failure)")
    ax.set_title(title)
    ax.grid(True, alpha=0.3)
    ax.legend()
    fig.tight_layout()
    fig.savefig(out_dir / PLOT_FILE, dpi=110)
    plt.close(fig)


def _progress_line(p: dict[str, Any]) -> str:
    return f"| {p['batch']} | {p['flights']} | {p['lowest_so_far']:.4g} | {p['batch_lowest']:.4g} | " + (
        f"{p['batch_median']:.4g} |"
    )


def write_search_report(spec: CampaignSpec, outcome: Any) -> dict[str, Any]:
    """The search's summary and report (``outcome``: a :class:`~.search_run.SearchOutcome`)."""
    assert spec.search is not None
    out_dir = outcome.out_dir
    rows = read_rows(out_dir)
    progress = []
    best = math.inf
    for b in outcome.batches:
        finite = [m for m in b.margins if math.isfinite(m)]
        best = min([best, *finite])
        progress.append({"batch": b.index, "flights": b.first_case + len(b.margins), "lowest_so_far": best,
                         "batch_lowest": min(finite, default=math.nan),
                         "batch_median": float(np.median(finite)) if finite else math.nan})  # fmt: skip
    flown = sum(len(b.margins) for b in outcome.batches)
    summary = {
        "campaign": spec.name,
        "kind": "search",
        "method": spec.search.method,
        "objective": spec.search.objective.name,
        "margin": spec.search.objective.text,
        "searched_inputs": [k for k in (spec.search.inputs or [k for k, d in spec.vary if d.kind != "randint"])],
        "root_seed": spec.seed,
        "flights": flown,
        "flights_flown_now": outcome.flown,
        "lowest_margin": best,
        "failures": sum(1 for b in outcome.batches for m in b.margins if m < 0.0),
        "flights_to_first_failure": first_failure(list(outcome.batches)),
        "progress": progress,
        "worst": _worst(spec, rows),
    }
    (out_dir / SUMMARY_FILE).write_text(json.dumps(summary, indent=2) + "\n")
    if rows:
        _plot(rows, out_dir, f"{spec.name}: {spec.search.method}, margin {spec.search.objective.text}")
    ftf = summary["flights_to_first_failure"]
    lines = [
        f"# Search {spec.name}",
        "",
        f"{spec.search.method} over {', '.join(summary['searched_inputs'])}; margin = "
        f"{spec.search.objective.text} (< 0: a failure); root seed {spec.seed}, {flown} flights ({spec.mode}).",
        "",
        f"**Lowest margin {best:.4g}**; {summary['failures']} failing flights; first failure at flight "
        f"{ftf if ftf is not None else '- (none found)'}.",
        "",
        f"![margin against flights]({PLOT_FILE})",
        "",
        "| batch | flights | lowest so far | batch lowest | batch median |",
        "|---|---|---|---|---|",
        *[_progress_line(p) for p in progress],
        "",
        f"## The {len(summary['worst'])} lowest margins",
        "",
        *_worst_table(summary["worst"]),
    ]
    (out_dir / REPORT_FILE).write_text("\n".join(lines) + "\n")
    return summary


def _level(lv: Any) -> dict[str, Any]:
    return {"level": lv.index, "flights": len(lv.margins), "gamma": lv.gamma,
            "failures": sum(m < 0 for m in lv.margins)}  # fmt: skip


def write_estimate_report(
    spec: CampaignSpec, outcome: Any, mc_rows: list[dict[str, Any]] | None, mc_dir: Path | None
) -> dict[str, Any]:
    """The estimate's summary and report (``outcome``: a :class:`~.search_run.EstimateOutcome`)."""
    assert spec.search is not None
    res, out_dir = outcome.result, outcome.out_dir
    est = res.estimate
    mc = None
    if mc_rows is not None:
        margins = [spec.search.objective.margin(r) for r in mc_rows]
        known = [m for m in margins if math.isfinite(m)]
        fails = sum(m < 0.0 for m in known)
        mc = {"dir": str(mc_dir), "flights": len(known), "no_verdict": len(margins) - len(known), "failures": fails,
              "p": fails / len(known) if known else math.nan, "ci95": list(mc_interval(fails, len(known)))}  # fmt: skip
        mc["inside_is_ci95"] = est.ci95[0] <= mc["p"] <= est.ci95[1]
        mc["ci95_overlap"] = mc["ci95"][0] <= est.ci95[1] and est.ci95[0] <= mc["ci95"][1]
    flights = sum(len(lv.margins) for lv in res.levels) + len(res.final_margins)
    summary = {
        "campaign": spec.name,
        "kind": "estimate",
        "objective": spec.search.objective.name,
        "margin": spec.search.objective.text,
        "root_seed": spec.seed,
        "flights": flights,
        "levels": [_level(lv) for lv in res.levels],
        "failure_level_reached": res.reached,
        "p_is": est.p,
        "p_is_ci95": list(est.ci95),
        "ess_kish": est.ess,
        "mean_weight": est.mean_weight,
        "final_flights": est.n,
        "final_failures": est.failures,
        "final_no_verdict": len(res.final_margins) - est.n,
        "mc": mc,
    }
    (out_dir / SUMMARY_FILE).write_text(json.dumps(summary, indent=2) + "\n")
    lines = [
        f"# Failure probability of {spec.name}",
        "",
        f"Margin = {spec.search.objective.text} (< 0: a failure), under the campaign's own input distribution; "
        f"root seed {spec.seed}; {flights} flights ({spec.mode}).",
        "",
        f"**P(failure) = {est.p:.3g}**, 95 % interval [{est.ci95[0]:.3g}, {est.ci95[1]:.3g}] (importance sampling, "
        f"{est.n} flights from 0.9 q + 0.1 p, {est.failures} failures); Kish effective sample size {est.ess:.1f}, "
        f"mean weight {est.mean_weight:.3f}.",
        "",
    ]
    if not res.reached:
        lines += ["The cross-entropy levels did **not** reach the failure level: the estimate may be low.", ""]
    lines += ["| level | flights | level reached (gamma) | failures |", "|---|---|---|---|"]
    lines += [f"| {x['level']} | {x['flights']} | {x['gamma']:.4g} | {x['failures']} |" for x in summary["levels"]]
    if mc is not None:
        lines += ["", f"Plain Monte Carlo ({mc['dir']}): {mc['failures']} failures in {mc['flights']} flights, "
                  f"P = {mc['p']:.3g}, exact 95 % interval [{mc['ci95'][0]:.3g}, {mc['ci95'][1]:.3g}]; inside the "
                  f"importance-sampling interval: {'yes' if mc['inside_is_ci95'] else 'no'}."]  # fmt: skip
    (out_dir / REPORT_FILE).write_text("\n".join(lines) + "\n")
    return summary
