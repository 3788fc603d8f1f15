"""Reproduce the paper's experiments: fixed PID vs NLVG-PID+ES, both tuned by the same ES (SPEC §6, §12).

Usage::

    python -m tools.research.paper_table [--out results/paper] [--quick] [--vehicle x500] [--iterations N]
        [--restarts R] [--workers N | --scheduler tcp://HOST:PORT]

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
from tools.research.experiments.noisy_eval import hover_metrics, route_metrics, step_metrics, tradeoff_point
from tools.research.experiments.noisy_pipeline import noisy_config, tune_noisy_pair
from tools.research.experiments.paper_pipeline import (
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
from tools.research.experiments.paper_plots import plot_mass_change, plot_steps, plot_tracking, plot_tradeoff
from tools.research.experiments.rollout import StepTrace
from tools.research.experiments.tuner import RolloutMap, engine_rollouts, in_process, plot_convergence
from tools.research.paper_markdown import markdown

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
    parser = argparse.ArgumentParser(prog="python -m tools.research.paper_table", description=__doc__.splitlines()[0])
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
        print(f"tools.research.paper_table: {exc}", file=sys.stderr)
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
