"""Reproduce the paper's experiments: fixed PID vs NLVG-PID+ES, both tuned by the same ES (SPEC §6, §12).

Usage::

    python -m tools.paper_table [--out results/paper] [--quick] [--vehicle x500] [--iterations N] [--restarts R]
        [--workers N | --scheduler tcp://HOST:PORT]

The extremum-seeking rollouts (every tune's cost evaluations: one task per experiment) run on the campaign engine
(:mod:`tools.campaign.engine`): an embedded LocalCluster of ``--workers`` processes (default: one per core), or a
running Dask cluster at ``--scheduler``. The tasks do not depend on either, so neither do the numbers.

Writes into ``--out``:

* ``paper_table.json``: the SPEC §12 schema ({"step": {phi, theta, x, y: {pid, nlvg: {IAE, ITAE,
  ITSE}}}, "storm"/"lissajous": {pid, nlvg: {pos_rms_m, att_rms_deg}}}) for the noise-free setting, and the same
  schema under ``"noisy_effort"`` for the noisy effort-aware setting (means over the held-out seeds);
* ``paper_extras.json``: ratios, portability table, payload change, step overshoot/settling, tuning budget and
  wall times; under ``"noisy_effort"``: the noise model, seeds, λ, μ, every metric with its 95 % CI and the
  per-seed NLVG/PID ratios, hover jitter/chatter, the λ sweep, J and the tuned gains;
* ``paper_table.md``: Table 1 layout with NLVG/PID ratios, the tracking, portability and payload tables;
* plots: ``step_attitude.png``, ``step_position.png``, ``storm_errors.png``, ``lissajous_errors.png``,
  ``payload_change.png``, ``convergence_<level>_<structure>.png``, ``tradeoff_noisy.png`` (the λ sweep),
  ``step_attitude_noisy.png``, ``step_position_noisy.png``, ``lissajous_errors_noisy.png``; tuned gains
  ``gains_pid.yaml``, ``gains_nlvg.yaml``, ``gains_noisy_pid.yaml``, ``gains_noisy_nlvg.yaml``.
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

from tools.campaign.engine import SchedulerError, TaskEngine
from tools.experiments.noisy_eval import hover_metrics, route_metrics, step_metrics, tradeoff_point
from tools.experiments.noisy_pipeline import noisy_config, tune_noisy_pair
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
from tools.experiments.paper_plots import plot_mass_change, plot_steps, plot_tracking, plot_tradeoff
from tools.experiments.rollout import StepTrace
from tools.experiments.tuner import RolloutMap, engine_rollouts, in_process, plot_convergence

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
    lines += noisy_markdown(extras)
    return "\n".join(lines)


def _mci(mc: dict[str, float], digits: int = 3) -> str:
    """``mean ± ci95``."""
    return f"{_fmt(mc['mean'], digits)} ± {_fmt(mc['ci95'], 2)}"


def noisy_markdown(extras: dict[str, Any]) -> list[str]:
    """The noisy effort-aware setting: ratios with 95 % CIs over the held-out seeds, step shape, hover, sweep."""
    nz = extras["noisy_effort"]
    shape = extras["step_overshoot_settling"]
    lines = [
        "## Noise-free large steps: overshoot and 5 % settling time",
        "",
        "| Channel | PID overshoot | NLVG overshoot | PID settling (s) | NLVG settling (s) |",
        "|---|---|---|---|---|",
    ]
    for ch, row in shape.items():
        p, n = row["pid"], row["nlvg"]
        lines.append(
            f"| {ch} | {p['overshoot']:.1%} | {n['overshoot']:.1%} | {_fmt(p['settling_s'], 3)} "
            f"| {_fmt(n['settling_s'], 3)} |"
        )
    lines += [
        "",
        "# The noisy, effort-aware setting",
        "",
        f"Feedback noise: white + Gauss-Markov drift on position, velocity, attitude and rates "
        f"(`tools/experiments/feedback_noise.py`); training seeds {nz['train_seeds']}, evaluation on held-out "
        f"seeds {nz['eval_seeds']} (mean ± 95 % CI over seeds; ratios NLVG/PID taken per seed, both structures "
        f"meet the same noise and gusts). Cost: true-error mean e² + λ·chatter² + μ·overshoot², λ = "
        f"{nz['effort_weight']} × {nz['headline_effort_scale']:g}, μ = {nz['overshoot_weight']}. "
        "PID tuned first, NLVG (k1, k2, δ1, δ2) warm-started at it.",
        "",
        "| Channel | IAE ratio | ITAE ratio | ITSE ratio | PID overshoot | NLVG overshoot | PID settling (s) "
        "| NLVG settling (s) | chatter ratio |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for ch, row in nz["steps"].items():
        r, v = row["ratio"], row["values"]
        lines.append(
            f"| {ch} | {_mci(r['IAE'])} | {_mci(r['ITAE'])} | {_mci(r['ITSE'])} | {v['pid']['overshoot']:.1%} "
            f"| {v['nlvg']['overshoot']:.1%} | {_fmt(v['pid']['settling_s'], 3)} | {_fmt(v['nlvg']['settling_s'], 3)} "
            f"| {_mci(r['chatter_per_s'])} |"
        )
    lines += [
        "",
        "| Route / hover (wind) | PID pos (m) | NLVG pos (m) | pos ratio | PID att (°) | NLVG att (°) | att ratio "
        "| chatter ratio |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for name in ("storm", "lissajous", "hover"):
        row = nz[name]
        v, r = row["values"], row["ratio"]
        lines.append(
            f"| {name} | {_fmt(v['pid']['pos_rms_m'])} | {_fmt(v['nlvg']['pos_rms_m'])} | {_mci(r['pos_rms_m'])} "
            f"| {_fmt(v['pid']['att_rms_deg'])} | {_fmt(v['nlvg']['att_rms_deg'])} | {_mci(r['att_rms_deg'])} "
            f"| {_mci(r['chatter_per_s'])} |"
        )
    lines += [
        "",
        "λ sweep (`tradeoff_noisy.png`): per λ multiplier, both structures re-tuned; 1 m x-step RMS true error, "
        "hover attitude jitter and motor chatter on the held-out seeds.",
        "",
        "| λ× | PID step (m) | NLVG step (m) | PID jitter (°) | NLVG jitter (°) | PID chatter (1/s) "
        "| NLVG chatter (1/s) |",
        "|---|---|---|---|---|---|---|",
    ]
    for pt in nz["tradeoff"]:
        p, n = pt["pid"], pt["nlvg"]
        lines.append(
            f"| {pt['effort_scale']:g} | {_fmt(p['step_rms_m'])} | {_fmt(n['step_rms_m'])} | {_fmt(p['jitter_deg'])} "
            f"| {_fmt(n['jitter_deg'])} | {_fmt(p['chatter_per_s'])} | {_fmt(n['chatter_per_s'])} |"
        )
    jw = nz["j_nlvg_warm_start_at_pid"]
    lines += [
        "",
        "ES cost J (training seeds), initial → best: "
        + ", ".join(f"{k} {_fmt(v[0])} → {_fmt(v[1])}" for k, v in nz["j"].items())
        + "; the NLVG's J at its warm start (the tuned PID's gains): "
        + ", ".join(f"{k} {_fmt(v)}" for k, v in jw.items())
        + ".",
        "",
    ]
    return lines


def _pct(ratio: float) -> str:
    return "n/a" if not math.isfinite(ratio) else f"{(ratio - 1.0) * 100.0:+.1f} %"


def _first_block(tr: StepTrace) -> StepTrace:
    """The PID/NLVG pair of the first noise seed (for the step plots)."""
    return replace(tr, error=tr.error[:2], response=tr.response[:2], diverged=tr.diverged[:2], chatter=tr.chatter[:2])


def step_shape(traces: dict[str, StepTrace]) -> dict[str, dict[str, dict[str, float]]]:
    """Noise-free large steps: overshoot (fraction of the step) and 5 % settling time (s) per structure."""
    return {
        key: {
            s: {"overshoot": float(tr.overshoot[i]), "settling_s": float(tr.settling_time_s(0.05)[i])}
            for i, s in enumerate(STRUCTURES)
        }
        for key, tr in traces.items()
    }


def noisy_setting(
    settings: PaperSettings, vehicle: str, out: Path, log, rollouts: RolloutMap = in_process
) -> tuple[dict[str, Any], dict[str, Any]]:
    """The noisy effort-aware setting: λ sweep (tuning both structures per λ, rollouts mapped by ``rollouts``),
    held-out-seed evaluation of the headline λ (×1): Table 1 with overshoot/settling, routes, hover; returns
    (table part, extras part)."""
    att_cfg = noisy_config("attitude", vehicle)
    noise, seeds = att_cfg.noise, att_cfg.eval_seeds
    durations = {"attitude": settings.step_duration_attitude_s, "position": settings.step_duration_position_s}
    sweep = []
    pairs = {}
    for scale in settings.effort_scales:
        pair = tune_noisy_pair(vehicle, scale, settings.noisy_iterations, log, settings.tune_step_scale, rollouts)
        pairs[scale] = pair
        point = tradeoff_point(pair.gains, vehicle, noise, seeds, settings.hover_s, settings.step_duration_position_s)
        sweep.append({"effort_scale": scale, **point})
        log(f"noisy λ×{scale:g}: tuned and evaluated")
    plot_tradeoff(sweep, out / "tradeoff_noisy.png")
    head = pairs[1.0] if 1.0 in pairs else pairs[settings.effort_scales[-1]]
    for s in STRUCTURES:
        head.gains[s].to_yaml(out / f"gains_noisy_{s}.yaml")
    steps, traces = step_metrics(head.gains, vehicle, noise, seeds, durations)
    storm, _ = route_metrics(head.gains, vehicle, "storm", settings.noisy_storm_duration_s, noise, seeds)
    liss, liss_tr = route_metrics(head.gains, vehicle, "lissajous", settings.noisy_lissajous_duration_s, noise, seeds)
    hover = hover_metrics(head.gains, vehicle, settings.hover_s, noise, seeds)
    log("noisy setting evaluated")
    plot_steps({k: _first_block(t) for k, t in traces.items()}, ("phi", "theta"), out / "step_attitude_noisy.png", True)
    plot_steps({k: _first_block(t) for k, t in traces.items()}, ("x", "y"), out / "step_position_noisy.png", False)
    plot_tracking(liss_tr, "Lissajous, noisy feedback", out / "lissajous_errors_noisy.png")
    table = {
        "step": {
            k: {s: {m: v["values"][s][m] for m in ("IAE", "ITAE", "ITSE")} for s in STRUCTURES}
            for k, v in steps.items()
        },
        "storm": {s: {m: storm["values"][s][m] for m in ("pos_rms_m", "att_rms_deg")} for s in STRUCTURES},
        "lissajous": {s: {m: liss["values"][s][m] for m in ("pos_rms_m", "att_rms_deg")} for s in STRUCTURES},
    }
    extras = {
        "noise": noise.to_dict(),
        "eval_seeds": list(seeds),
        "train_seeds": list(att_cfg.seeds),
        "effort_weight": {lv: noisy_config(lv, vehicle).effort_weight for lv in ("attitude", "position")},
        "overshoot_weight": {lv: noisy_config(lv, vehicle).overshoot_weight for lv in ("attitude", "position")},
        "headline_effort_scale": 1.0 if 1.0 in pairs else settings.effort_scales[-1],
        "steps": steps,
        "storm": storm,
        "lissajous": liss,
        "hover": hover,
        "tradeoff": sweep,
        "j": {
            f"{lv}_{s}": [head.outcomes[(lv, s)].result.j_initial, head.outcomes[(lv, s)].result.j_best]
            for lv in LEVELS
            for s in STRUCTURES
        },
        "j_nlvg_warm_start_at_pid": head.j_warm_start,
        "rollouts": {f"{lv}_{s}": head.outcomes[(lv, s)].result.n_evaluations for lv in LEVELS for s in STRUCTURES},
        "gains": {s: head.gains[s].to_dict()["channels"] for s in STRUCTURES},
    }
    return table, extras


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m tools.paper_table", description=__doc__.splitlines()[0])
    parser.add_argument("--out", default="results/paper", help="output directory")
    parser.add_argument("--quick", action="store_true", help="tiny budgets and short routes (smoke test)")
    parser.add_argument("--vehicle", default="x500", help="vehicle for tuning, steps and routes")
    parser.add_argument("--iterations", type=int, default=None, help="NLVG ES iterations (PID: equal rollouts)")
    parser.add_argument("--restarts", type=int, default=None, help="ES restarts")
    parser.add_argument(
        "--workers", type=int, default=None, help="ES rollout worker processes (campaign engine; default: the cores)"
    )
    parser.add_argument("--scheduler", default=None, help="run the ES rollouts on a running Dask scheduler")
    args = parser.parse_args(argv)
    if args.workers is not None and args.workers < 1:
        parser.error(f"--workers must be >= 1, got {args.workers}")
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

    try:
        engine = TaskEngine(workers=args.workers, scheduler=args.scheduler)
        engine.start()
    except SchedulerError as exc:
        print(f"tools.paper_table: {exc}", file=sys.stderr)
        return 2
    with engine:
        log(f"ES rollouts on the campaign engine: {engine.n_workers} worker(s)")
        return _paper(args, settings, out, log, engine_rollouts(engine), t_start)


def _paper(
    args: argparse.Namespace, settings: PaperSettings, out: Path, log, rollouts: RolloutMap, t_start: float
) -> int:
    """Tune both structures (ES rollouts mapped by ``rollouts``), fly every table of the paper, write them."""
    pair = tune_both(settings, log, rollouts)
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
    noisy_table, noisy_extras = noisy_setting(settings, args.vehicle, out, log, rollouts)

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
        "step_overshoot_settling": step_shape(step_traces),
        "noisy_effort": noisy_extras,
        "wall_s": time.perf_counter() - t_start,
    }
    table["noisy_effort"] = noisy_table
    (out / "paper_table.json").write_text(json.dumps(_json_safe(table), indent=2) + "\n")
    (out / "paper_extras.json").write_text(json.dumps(_json_safe(extras), indent=2) + "\n")
    (out / "paper_table.md").write_text(markdown(table, extras))
    log(f"wrote {out}/paper_table.json, paper_extras.json, paper_table.md and plots")
    return 0


if __name__ == "__main__":
    sys.exit(main())
