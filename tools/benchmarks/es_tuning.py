"""ES tuning wall time (SPEC §11): a full central-difference ES tune of one cascade level.

The level is the attitude loop of the x500 (``tools/research/experiments/attitude_nlvg.yaml``): k1 and k2 of
(kp, ki, kd), 6 parameters, 5 restarts, 20 iterations, each iteration one batch of 5·13 = 65 closed-loop
rollouts per step experiment (roll and pitch steps of 1 s at 250 Hz control / 1 kHz physics).
Quick mode: 3 iterations, 2 restarts (a smoke check, not comparable with the target). The rollouts run on the
campaign engine as in ``make paper`` (one task per step experiment and batch, ``--workers`` / ``--scheduler`` of
``tools.benchmarks``); an untimed tune first warms every worker's kernels.
"""

from __future__ import annotations

from pathlib import Path

from tools.benchmarks import BenchResult
from tools.campaign.engine import TaskEngine
from tools.research.experiments.tune_config import load_tune_config
from tools.research.experiments.tuner import engine_rollouts, tune

CONFIG = Path(__file__).resolve().parent.parent / "research" / "experiments" / "attitude_nlvg.yaml"
TARGET_WALL_S = 60.0


def run(quick: bool, *, workers: int | None = None, scheduler: str | None = None) -> list[BenchResult]:
    config = load_tune_config(CONFIG)
    config = config.with_budget(iterations=3, restarts=2) if quick else config.with_budget(iterations=20, restarts=5)
    warm = config.with_budget(iterations=0, restarts=1)
    with TaskEngine(workers=workers, scheduler=scheduler) as engine:
        rollouts = engine_rollouts(engine)
        n_workers = engine.n_workers
        tune(warm, rollouts=rollouts)  # load numba caches / compile in every worker outside the timed run
        outcome = tune(config, rollouts=rollouts)
    res = outcome.result
    vehicle_steps = sum(round(e.duration_s * 250) for e in config.experiments) * res.n_evaluations
    return [
        BenchResult(
            "es_tune_wall_s",
            outcome.wall_s,
            target=f"<= {TARGET_WALL_S:g}",
            met=None if quick else outcome.wall_s <= TARGET_WALL_S,
            note=f"{res.n_evaluations} rollouts in {res.n_batches} batches, "
            f"{res.j_history.shape[1]} restarts, {res.j_history.shape[0] - 1} iterations, {n_workers} engine worker(s)",
        ),
        BenchResult("es_tune_rollouts", float(res.n_evaluations)),
        BenchResult("es_tune_vehicle_steps_per_s", vehicle_steps / outcome.wall_s, note="closed loop, in ES batches"),
        BenchResult("es_tune_j_ratio", res.j_best / res.j_initial, note="J_best / J at the best start (< 1: improved)"),
    ]
