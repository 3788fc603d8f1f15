"""``tools.research.tune_es --ship``: tune both structures on one airframe's own closed loop and write the gain files.

Writes into ``out_dir`` (default ``results/loop_tuning/<vehicle>``): ``pid.yaml`` (the ES-tuned fixed PID) and
``nlvg.yaml`` (the ES-tuned NLVG-PID), each with its provenance (command, vehicle, routes, seeds, λ, J), and
``summary.json`` (J before/after, rollouts, wall time, the paper PID's reference errors); then copies the
``ship`` structure's file to the airframe's default gains (:func:`autopilot.control.param_decls.airframe_gains_path`).
Which structure ships is decided by the delivery campaign (``tools/benchmarks/gains_campaign.py``).
"""

from __future__ import annotations

import json
import shutil
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from autopilot.control.gains import CascadeGains
from autopilot.control.param_decls import airframe_gains_path, shipped_gains
from tools.campaign.engine import TaskEngine
from tools.research.experiments.loop_tuner import LoopOutcomeOfTune, LoopPair, engine_mapper, in_process, tune_pair

ROOT = Path(__file__).resolve().parents[3]


def default_out_dir(vehicle: str) -> Path:
    return ROOT / "results" / "loop_tuning" / vehicle


def _provenance(o: LoopOutcomeOfTune, command: str, pair: LoopPair) -> dict[str, Any]:
    cfg = o.config
    return {
        "command": command,
        "tuned_on": "the product's closed loop in process: sim sensors -> EKF -> commander, navigator, cascade",
        "vehicle": cfg.vehicle,
        "structure": str(cfg.structure),
        "estimator": cfg.estimator,
        "routes": [list(r) for r in cfg.routes],
        "train_seeds": list(cfg.seeds),
        "effort_weight": cfg.effort_weight,
        "es_seed": int(cfg.es.seed),
        "iterations": int(o.result.j_history.shape[0] - 1),
        "restarts": int(o.result.j_history.shape[1]),
        "rollouts": int(o.result.n_evaluations) * len(cfg.routes) * len(cfg.seeds),
        "j_initial": float(o.result.j_initial),
        "j_best": float(o.result.j_best),
        "j_paper_pid": float(sum(w for _r, w in cfg.routes) + cfg.effort_weight),
        "paper_pid_pos_err_rms_m": [float(np.sqrt(v)) for v in pair.reference.mse_m2],
    }


def ship_paper_pid(vehicle: str, command: str, candidates_from: str | None = None) -> Path:
    """Write the paper's fixed PID as ``vehicle``'s defaults: the choice where neither tuned set beats it on both
    true tracking error and chatter in the delivery campaign. ``candidates_from``: the airframe whose tuned sets
    the campaign compares with it."""
    target = airframe_gains_path(vehicle)
    prov: dict[str, Any] = {
        "command": command,
        "vehicle": vehicle,
        "structure": "paper_pid",
        "reason": "the tuned NLVG-PID and fixed PID did not beat the paper's fixed PID on both true tracking error "
        "and motor chatter on the delivery mission in wind with the EKF (python -m tools.benchmarks --only "
        "gains_campaign), so this airframe keeps the paper's PID",
    }
    if candidates_from:
        prov["candidates_from"] = candidates_from
    CascadeGains.fixed_pid().to_yaml(target, provenance=prov)
    return target


def ship_loop(
    vehicle: str,
    *,
    iterations: int,
    restarts: int,
    workers: int | None,
    ship: str,
    out_dir: Path | None,
    command: str,
    log: Callable[[str], None] = print,
) -> dict[str, Path]:
    """Tune (module docstring), write the files, copy ``ship`` ("nlvg" | "pid" | "none") to the defaults."""
    out = out_dir or default_out_dir(vehicle)
    out.mkdir(parents=True, exist_ok=True)
    base = shipped_gains(vehicle)
    if workers == 0:
        pair = tune_pair(vehicle, base, in_process, iterations, restarts, log=log)
    else:
        with TaskEngine(workers=workers) as engine:
            pair = tune_pair(vehicle, base, engine_mapper(engine), iterations, restarts, log=log)
    paths = {"pid": out / "pid.yaml", "nlvg": out / "nlvg.yaml", "summary": out / "summary.json"}
    summary: dict[str, Any] = {}
    for name, o in (("pid", pair.pid), ("nlvg", pair.nlvg)):
        prov = _provenance(o, command, pair)
        o.gains.to_yaml(paths[name], provenance=prov)
        k_best = dict(zip(o.result.names, o.result.k_best.tolist(), strict=True))
        summary[name] = {**prov, "wall_s": o.wall_s, "k_best": k_best}
    paths["summary"].write_text(json.dumps(summary, indent=2) + "\n")
    if ship != "none":
        target = airframe_gains_path(vehicle)
        shutil.copyfile(paths[ship], target)
        paths["shipped"] = target
        log(f"shipped the {ship} gains for {vehicle}: {target}")
    return paths
