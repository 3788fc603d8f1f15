"""Reproduce the paper's experiments: fixed PID vs NLVG-PID+ES, both tuned by the same ES (SPEC §6, §12).

Usage::

    python -m tools.paper_table [--out results/paper] [--quick] [--vehicle x500] [--iterations N] [--restarts R]

Writes into ``--out``:

* ``paper_table.json``: exactly the SPEC §12 schema ({"step": {phi, theta, x, y: {pid, nlvg: {IAE, ITAE,
  ITSE}}}, "storm"/"lissajous": {pid, nlvg: {pos_rms_m, att_rms_deg}}});
* ``paper_extras.json``: ratios, portability table, payload change, tuning budget and wall times;
* ``paper_table.md``: Table 1 layout with NLVG/PID ratios, the tracking, portability and payload tables;
* plots: ``step_attitude.png``, ``step_position.png``, ``storm_errors.png``, ``lissajous_errors.png``,
  ``payload_change.png``, ``convergence_<level>_<structure>.png``; tuned gains ``gains_pid.yaml``,
  ``gains_nlvg.yaml``.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from dataclasses import replace
from pathlib import Path
from typing import Any

from tools.experiments.paper_pipeline import (
    LEVELS,
    RECOVERY_BAND_M,
    STRUCTURES,
    WIND_GUST_M_S,
    WIND_MEAN_NED_M_S,
    PaperSettings,
    payload_table,
    portability_table,
    step_table,
    tracking_table,
    tune_both,
)
from tools.experiments.paper_plots import plot_mass_change, plot_steps, plot_tracking
from tools.experiments.tuner import plot_convergence

#: the paper's claims (section 4 and Table 1) for the honest comparison
PAPER_CLAIMS = {"IAE": 0.91, "ITSE": 0.85, "lissajous_att": 0.5, "lissajous_pos": 0.85}


def _ratio(nlvg: float, pid: float) -> float:
    if not (math.isfinite(nlvg) and math.isfinite(pid)) or pid == 0.0:
        return math.nan
    return nlvg / pid


def _json_safe(x: Any) -> Any:
    if isinstance(x, dict):
        return {k: _json_safe(v) for k, v in x.items()}
    if isinstance(x, list | tuple):
        return [_json_safe(v) for v in x]
    if isinstance(x, float) and not math.isfinite(x):
        return None if math.isnan(x) else ("inf" if x > 0 else "-inf")
    return x


def ratios(table: dict[str, Any]) -> dict[str, dict[str, float]]:
    """NLVG/PID per step channel and metric, and per route and error."""
    out: dict[str, dict[str, float]] = {}
    for ch, row in table["step"].items():
        out[ch] = {m: _ratio(row["nlvg"][m], row["pid"][m]) for m in ("IAE", "ITAE", "ITSE")}
    for route in ("storm", "lissajous"):
        row = table[route]
        out[route] = {m: _ratio(row["nlvg"][m], row["pid"][m]) for m in ("pos_rms_m", "att_rms_deg")}
    return out


def _fmt(v: float, digits: int = 4, inf_text: str = "diverged") -> str:
    return inf_text if not math.isfinite(v) else f"{v:.{digits}g}"


def markdown(table: dict[str, Any], extras: dict[str, Any]) -> str:
    r = extras["ratios"]
    lines = [
        "# Fixed PID vs NLVG-PID + ES (paper Table 1 layout)",
        "",
        f"Vehicle {extras['vehicle']}; both structures tuned by the same central-difference ES "
        f"({extras['budget']['restarts']} restarts; rollouts: PID {extras['budget']['rollouts']['pid']}, "
        f"NLVG {extras['budget']['rollouts']['nlvg']}). Attitude errors in degrees (t_peak 0.15 s), "
        "position errors in m (t_peak 0.37 s).",
        "",
        "| Channel | PID IAE | PID ITAE | PID ITSE | | NLVG IAE | NLVG ITAE | NLVG ITSE "
        "| IAE ratio | ITAE ratio | ITSE ratio |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    labels = {"phi": "φ (roll, °)", "theta": "θ (pitch, °)", "x": "x (m)", "y": "y (m)"}
    for ch, row in table["step"].items():
        p, n = row["pid"], row["nlvg"]
        lines.append(
            f"| {labels[ch]} | {_fmt(p['IAE'])} | {_fmt(p['ITAE'])} | {_fmt(p['ITSE'])} | "
            f"| {_fmt(n['IAE'])} | {_fmt(n['ITAE'])} | {_fmt(n['ITSE'])} "
            f"| {_fmt(r[ch]['IAE'], 3)} | {_fmt(r[ch]['ITAE'], 3)} | {_fmt(r[ch]['ITSE'], 3)} |"
        )
    lines += [
        "",
        "Paper's ratios: IAE 0.90-0.91, ITAE 0.86-0.92, ITSE 0.79-0.85.",
        "",
        "## Route tracking (RMS of the error norm)",
        "",
        "| Route | PID pos (m) | NLVG pos (m) | pos change | PID att (°) | NLVG att (°) | att change |",
        "|---|---|---|---|---|---|---|",
    ]
    for route in ("storm", "lissajous"):
        p, n = table[route]["pid"], table[route]["nlvg"]
        rp, ra = r[route]["pos_rms_m"], r[route]["att_rms_deg"]
        lines.append(
            f"| {route} | {_fmt(p['pos_rms_m'])} | {_fmt(n['pos_rms_m'])} | {_pct(rp)} "
            f"| {_fmt(p['att_rms_deg'])} | {_fmt(n['att_rms_deg'])} | {_pct(ra)} |"
        )
    rc = extras["ratios_small_steps_and_calm_routes"]
    lines += [
        "",
        f"Routes flown in wind: mean {extras['routes_wind']['mean_ned_m_s']} m/s NED, gusts "
        f"{extras['routes_wind']['gust_m_s']} m/s (1σ), the same seeded gusts for both controllers. In calm air:",
        "",
        "| Route (calm) | PID pos (m) | NLVG pos (m) | pos change | PID att (°) | NLVG att (°) | att change |",
        "|---|---|---|---|---|---|---|",
    ]
    for route in ("storm", "lissajous"):
        p, n = extras["routes_calm"][route]["pid"], extras["routes_calm"][route]["nlvg"]
        lines.append(
            f"| {route} | {_fmt(p['pos_rms_m'])} | {_fmt(n['pos_rms_m'])} | {_pct(rc[route]['pos_rms_m'])} "
            f"| {_fmt(p['att_rms_deg'])} | {_fmt(n['att_rms_deg'])} | {_pct(rc[route]['att_rms_deg'])} |"
        )
    lines += [
        "",
        "Small steps (0.02 rad, 0.05 m), NLVG/PID ratios: "
        + ", ".join(
            f"{ch} IAE {_fmt(rc[ch]['IAE'], 3)} ITAE {_fmt(rc[ch]['ITAE'], 3)} ITSE {_fmt(rc[ch]['ITSE'], 3)}"
            for ch in ("phi", "theta", "x", "y")
        ),
        "",
        "Paper's Lissajous claim: attitude error −50 %, position error −15 %.",
        "",
        "## Portability: gains tuned on x500, unchanged, Lissajous route (in the same wind)",
        "",
        "| Vehicle | PID pos (m) | NLVG pos (m) | PID att (°) | NLVG att (°) |",
        "|---|---|---|---|---|",
    ]
    for vehicle, row in extras["portability"].items():
        p, n = row["pid"], row["nlvg"]
        lines.append(
            f"| {vehicle} | {_fmt(p['pos_rms_m'])} | {_fmt(n['pos_rms_m'])} "
            f"| {_fmt(p['att_rms_deg'])} | {_fmt(n['att_rms_deg'])} |"
        )
    lines += [
        "",
        f"## Payload change mid-hover ({extras['payload_vehicle']}, controller not told)",
        "",
        "| Change | Mass (kg) | PID max alt dev (m) | NLVG max alt dev (m) | PID recovery (s) | NLVG recovery (s) |",
        "|---|---|---|---|---|---|",
    ]
    nr = "not recovered"
    for key, row in extras["payload"].items():
        p, n = row["pid"], row["nlvg"]
        lines.append(
            f"| {key} | {p['mass_before_kg']:.3g} → {p['mass_after_kg']:.3g} | {_fmt(p['max_alt_dev_m'])} "
            f"| {_fmt(n['max_alt_dev_m'])} | {_fmt(p['recovery_s'], inf_text=nr)} "
            f"| {_fmt(n['recovery_s'], inf_text=nr)} |"
        )
    lines += ["", f"Recovery: time until |altitude error| stays below {extras['recovery_band_m']} m.", ""]
    return "\n".join(lines)


def _pct(ratio: float) -> str:
    return "n/a" if not math.isfinite(ratio) else f"{(ratio - 1.0) * 100.0:+.1f} %"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m tools.paper_table", description=__doc__.splitlines()[0])
    parser.add_argument("--out", default="results/paper", help="output directory")
    parser.add_argument("--quick", action="store_true", help="tiny budgets and short routes (smoke test)")
    parser.add_argument("--vehicle", default="x500", help="vehicle for tuning, steps and routes")
    parser.add_argument("--iterations", type=int, default=None, help="NLVG ES iterations (PID: equal rollouts)")
    parser.add_argument("--restarts", type=int, default=None, help="ES restarts")
    args = parser.parse_args(argv)
    settings = PaperSettings.quick() if args.quick else PaperSettings()
    if args.iterations is not None:
        settings = replace(settings, nlvg_iterations=args.iterations)
    if args.restarts is not None:
        settings = replace(settings, restarts=args.restarts)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    t_start = time.perf_counter()

    def log(msg: str) -> None:
        print(f"[paper {time.perf_counter() - t_start:6.1f} s] {msg}", file=sys.stderr, flush=True)

    pair = tune_both(settings, log)
    for s in STRUCTURES:
        pair.gains[s].to_yaml(out / f"gains_{s}.yaml")
    for (level, s), outcome in pair.outcomes.items():
        plot_convergence(outcome.result, f"{level} {s}", out / f"convergence_{level}_{s}.png")
    steps, step_traces = step_table(pair, args.vehicle, settings)
    small_steps, _ = step_table(pair, args.vehicle, settings, large=False)
    log("step responses done")
    storm, storm_trace = tracking_table(pair, args.vehicle, "storm", settings.storm_duration_s)
    storm_calm, _ = tracking_table(pair, args.vehicle, "storm", settings.storm_duration_s, gusty=False)
    log("storm route done")
    liss, liss_trace = tracking_table(pair, args.vehicle, "lissajous", settings.lissajous_duration_s)
    liss_calm, _ = tracking_table(pair, args.vehicle, "lissajous", settings.lissajous_duration_s, gusty=False)
    log("lissajous route done")
    table = {"step": steps, "storm": storm, "lissajous": liss}
    calm = {"step": small_steps, "storm": storm_calm, "lissajous": liss_calm}
    port = portability_table(pair, settings.lissajous_duration_s)
    log("portability done")
    payload, payload_traces = payload_table(pair, settings)
    log("payload change done")

    plot_steps(step_traces, ("phi", "theta"), out / "step_attitude.png", degrees=True)
    plot_steps(step_traces, ("x", "y"), out / "step_position.png", degrees=False)
    plot_tracking(storm_trace, "storm", out / "storm_errors.png")
    plot_tracking(liss_trace, "Lissajous", out / "lissajous_errors.png")
    plot_mass_change(payload_traces, settings.payload_vehicle, out / "payload_change.png")

    extras = {
        "vehicle": args.vehicle,
        "quick": args.quick,
        "ratios": ratios(table),
        "routes_wind": {"mean_ned_m_s": list(WIND_MEAN_NED_M_S), "gust_m_s": WIND_GUST_M_S},
        "small_steps": small_steps,
        "routes_calm": {"storm": storm_calm, "lissajous": liss_calm},
        "ratios_small_steps_and_calm_routes": ratios(calm),
        "paper_claims": PAPER_CLAIMS,
        "portability": port,
        "payload": payload,
        "payload_vehicle": settings.payload_vehicle,
        "recovery_band_m": RECOVERY_BAND_M,
        "budget": {
            "restarts": settings.restarts,
            "iterations": {
                f"{lv}_{s}": int(pair.outcomes[(lv, s)].result.j_history.shape[0] - 1)
                for lv in LEVELS
                for s in STRUCTURES
            },
            "rollouts": {s: int(sum(pair.outcomes[(lv, s)].result.n_evaluations for lv in LEVELS)) for s in STRUCTURES},
            "j": {
                f"{lv}_{s}": [pair.outcomes[(lv, s)].result.j_initial, pair.outcomes[(lv, s)].result.j_best]
                for lv in LEVELS
                for s in STRUCTURES
            },
            "tune_wall_s": {f"{lv}_{s}": pair.outcomes[(lv, s)].wall_s for lv in LEVELS for s in STRUCTURES},
        },
        "durations_s": {"storm": settings.storm_duration_s, "lissajous": settings.lissajous_duration_s},
        "wall_s": time.perf_counter() - t_start,
    }
    (out / "paper_table.json").write_text(json.dumps(_json_safe(table), indent=2) + "\n")
    (out / "paper_extras.json").write_text(json.dumps(_json_safe(extras), indent=2) + "\n")
    (out / "paper_table.md").write_text(markdown(table, extras))
    log(f"wrote {out}/paper_table.json, paper_extras.json, paper_table.md and plots")
    return 0


if __name__ == "__main__":
    sys.exit(main())
