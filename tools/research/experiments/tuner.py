"""Run one ES tune from a :class:`TuneConfig`: the batched closed-loop cost and its outputs (SPEC §6.3).

The cost of a batch of parameter vectors ``K (m, d)`` flies ``m`` vehicles at once per experiment and noise
seed (:func:`tools.research.experiments.rollout.run_step`; every probe meets the same seeded feedback noise) and is,
averaged over the training seeds, on the TRUE error::

    J = Σ_e w_e · 1/(tf−t0) ∫ e² dt  +  λ · mean_e chatter_e²  +  μ · Σ_e overshoot_e²

(a ``kind: track`` experiment adds w · mean |e_pos|² over its route instead, and no overshoot)

(λ = ``effort_weight``, chatter = RMS motor-command rate in 1/s, yaw mode excluded; μ = ``overshoot_weight``),
the steps flown in the config's ``wind`` if it has one.
With λ = μ = 0 and no noise this is the paper's J. Each cost evaluation is one rollout task per experiment
(:func:`fly_experiment`), mapped in order in this process or on the campaign engine (:func:`engine_rollouts`,
``tools.research.paper_table --workers/--scheduler``): the tasks are the same either way, so are the numbers.
A ``warm_start`` gain set (a tuned PID, k1 = k2) adds one restart that starts there, so the NLVG never ends
above that PID on the same cost ("best kept").
"""

from __future__ import annotations

import csv
import json
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from autopilot.control.gains import CascadeGains
from autopilot.tuning import CentralEsConfig, EsResult, central_es, perturbation_es
from autopilot.tuning.es_result import IterationCallback
from sim.world import World, empty_world
from tools.campaign.engine import TaskEngine
from tools.research.experiments.feedback_noise import FeedbackNoise
from tools.research.experiments.gain_vector import GainParametrisation
from tools.research.experiments.references import make_reference
from tools.research.experiments.rollout import mean_square_cost, run_step, run_tracking
from tools.research.experiments.tune_config import StepExperiment, TrackExperiment, TuneConfig


@dataclass(frozen=True, slots=True)
class TuneOutcome:
    """A finished tune: the ES result, the tuned gain set and the wall time."""

    config: TuneConfig
    result: EsResult
    gains: CascadeGains
    wall_s: float

    @property
    def improvement(self) -> float:
        """J_best / J at the best starting point (< 1 means ES lowered the cost)."""
        return self.result.j_best / self.result.j_initial


@dataclass(frozen=True, slots=True)
class CostTerms:
    """The cost's parts per gain set (m,), each averaged over the seeds: tracking Σ w·mean e², chatter² mean
    (1/s)², overshoot² sum, and the total J."""

    tracking: np.ndarray
    chatter_sq: np.ndarray
    overshoot_sq: np.ndarray
    total: np.ndarray


@dataclass(frozen=True, slots=True)
class ExperimentRollout:
    """One experiment of a tuning cost flown by a batch of ``m`` gain sets on every seed: a campaign-engine task."""

    vehicle: str
    gains: CascadeGains
    m: int
    experiment: StepExperiment | TrackExperiment
    noise: FeedbackNoise | None
    seeds: tuple[int, ...]
    world: World | None


@dataclass(frozen=True, slots=True)
class ExperimentTerms:
    """An experiment's raw cost parts per seed and gain set (n_seeds, m): mean e² (inf when diverged), chatter²
    ((1/s)²) and, for a step, overshoot² (None for a route)."""

    mse: np.ndarray
    chatter_sq: np.ndarray
    overshoot_sq: np.ndarray | None


#: flies experiment rollouts and returns their terms in input order (:func:`in_process` or :func:`engine_rollouts`)
RolloutMap = Callable[[Sequence[ExperimentRollout]], list[ExperimentTerms]]


def fly_experiment(task: ExperimentRollout) -> ExperimentTerms:
    """Fly one :class:`ExperimentRollout` (top level and picklable: the engine's task function)."""
    exp, ns, m = task.experiment, len(task.seeds), task.m
    if isinstance(exp, TrackExperiment):
        tt = run_tracking(task.vehicle, task.gains, make_reference(exp.route, exp.duration_s), exp.duration_s, m=m,
                          world=task.world, noise=task.noise, seeds=task.seeds)  # fmt: skip
        with np.errstate(invalid="ignore", over="ignore"):
            mse = np.mean(np.sum(tt.pos_err_ned**2, axis=2), axis=1)
        mse = np.where(tt.diverged | ~np.isfinite(mse), np.inf, mse).reshape(ns, m)
        return ExperimentTerms(mse, (tt.chatter**2).reshape(ns, m), None)
    tr = run_step(task.vehicle, task.gains, exp.channel, exp.amplitude, exp.duration_s, m=m, noise=task.noise,
                  seeds=task.seeds, world=task.world)  # fmt: skip
    mse = mean_square_cost(tr.error, tr.t_s, tr.diverged, exp.t0_s).reshape(ns, m)
    return ExperimentTerms(mse, (tr.chatter**2).reshape(ns, m), (tr.overshoot**2).reshape(ns, m))


def in_process(tasks: Sequence[ExperimentRollout]) -> list[ExperimentTerms]:
    """The :data:`RolloutMap` of small runs and tests: every rollout in this process, one after the other."""
    return [fly_experiment(t) for t in tasks]


def engine_rollouts(engine: TaskEngine) -> RolloutMap:
    """The :data:`RolloutMap` on an open campaign-engine session: one ordered map per cost evaluation (an ES
    iteration's experiments side by side on the workers); the same numbers as :func:`in_process`."""
    return engine.mapper(fly_experiment, key="es-rollout")


def cost_terms(
    config: TuneConfig, gains: CascadeGains, m: int, seeds: Sequence[int], rollouts: RolloutMap = in_process
) -> CostTerms:
    """Fly ``config``'s experiments for ``m`` gain sets on every seed of ``seeds`` (one rollout task per
    experiment, mapped by ``rollouts``); the seed-averaged terms, summed in the experiments' order."""
    tracking = np.zeros(m)
    chatter_sq = np.zeros(m)
    overshoot_sq = np.zeros(m)
    world = None if config.wind is None else replace(empty_world(), wind=config.wind)
    tasks = [ExperimentRollout(config.vehicle, gains, m, exp, config.noise, tuple(seeds), world)
             for exp in config.experiments]  # fmt: skip
    for exp, terms in zip(config.experiments, rollouts(tasks), strict=True):
        tracking += exp.weight * terms.mse.mean(axis=0)
        chatter_sq += terms.chatter_sq.mean(axis=0) / len(config.experiments)
        if terms.overshoot_sq is not None:
            overshoot_sq += terms.overshoot_sq.mean(axis=0)
    with np.errstate(invalid="ignore"):
        total = tracking + config.effort_weight * chatter_sq + config.overshoot_weight * overshoot_sq
    return CostTerms(tracking, chatter_sq, overshoot_sq, np.where(np.isfinite(total), total, np.inf))


def step_cost(config: TuneConfig, param: GainParametrisation, rollouts: RolloutMap = in_process):
    """The batched cost J(K (m, d)) -> (m,) of ``config``'s step experiments on its training seeds."""

    def cost(k: np.ndarray) -> np.ndarray:
        return cost_terms(config, param.gains(k), k.shape[0], config.seeds, rollouts).total

    return cost


def tune(
    config: TuneConfig, on_iteration: IterationCallback | None = None, rollouts: RolloutMap = in_process
) -> TuneOutcome:
    """Run ES as configured: restart 0 starts at ``warm_start`` when given, the next at the base gains when
    ``start_from_base`` (as many as there are restarts), the others at random. ``rollouts`` flies each cost
    evaluation's experiments (in this process, or on the campaign engine: the same numbers)."""
    param = config.parametrisation()
    space = param.space()
    cost = step_cost(config, param, rollouts)
    starts = []
    if config.warm_start is not None:
        starts.append(param.vector(config.warm_start))
    if config.start_from_base:
        starts.append(param.vector(config.base_gains))
    initial = np.stack(starts[: config.es.restarts]) if starts else None
    t0 = time.perf_counter()
    if isinstance(config.es, CentralEsConfig):
        result = central_es(cost, space, config.es, initial_gains=initial, on_iteration=on_iteration)
    else:
        result = perturbation_es(cost, space, config.es, initial_gains=initial, on_iteration=on_iteration)
    wall = time.perf_counter() - t0
    return TuneOutcome(config, result, param.single(result.k_best), wall)


def evaluate(
    config: TuneConfig, gains: Sequence[CascadeGains], rollouts: RolloutMap = in_process
) -> list[dict[str, float]]:
    """``config``'s cost terms of each gain set on the held-out ``eval_seeds`` (one batch)."""
    terms = cost_terms(config, CascadeGains.stacked(list(gains)), len(gains), config.eval_seeds, rollouts)
    return [
        {
            "J": float(terms.total[i]),
            "tracking": float(terms.tracking[i]),
            "chatter_rms_per_s": float(np.sqrt(terms.chatter_sq[i])),
            "overshoot_rms": float(np.sqrt(terms.overshoot_sq[i] / len(config.experiments))),
        }
        for i in range(len(gains))
    ]


def provenance(config: TuneConfig, command: str, outcome: TuneOutcome, **extra: Any) -> dict[str, Any]:
    """What a gains file records about its origin: the command, the config's name, vehicle, seeds and J."""
    return {
        "command": command,
        "config": config.name,
        "vehicle": config.vehicle,
        "es_seed": int(config.es.seed),
        "noise_scale": config.noise_scale,
        "train_seeds": list(config.seeds),
        "effort_weight": config.effort_weight,
        "overshoot_weight": config.overshoot_weight,
        "j_initial": float(outcome.result.j_initial),
        "j_best": float(outcome.result.j_best),
        **extra,
    }


def write_outputs(outcome: TuneOutcome, out_dir: str | Path, command: str = "") -> dict[str, Path]:
    """Write ``gains.yaml`` (with its provenance), ``j_per_iteration.csv``, ``convergence.png``, ``k_of_s.png``
    (k_p, k_i, k_d of every channel against |e|) and ``summary.json`` into ``out_dir``."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    res = outcome.result
    paths = {
        "gains": out / "gains.yaml",
        "csv": out / "j_per_iteration.csv",
        "plot": out / "convergence.png",
        "summary": out / "summary.json",
        "k_of_s": out / "k_of_s.png",
    }
    outcome.gains.to_yaml(paths["gains"], provenance(outcome.config, command, outcome))
    with paths["csv"].open("w", newline="") as f:
        w = csv.writer(f)
        r = res.j_history.shape[1]
        w.writerow(["iteration", *[f"J_restart{i}" for i in range(r)], "J_min_over_restarts"])
        running = np.minimum.accumulate(res.j_history.min(axis=1))
        for i, row in enumerate(res.j_history):
            w.writerow([i, *[f"{v:.9g}" for v in row], f"{running[i]:.9g}"])
    plot_convergence(res, outcome.config.name, paths["plot"])
    from tools.research.plot_gain_schedule import plot_gain_set

    cfg = outcome.config
    plot_gain_set(outcome.gains, paths["k_of_s"], f"{cfg.name} ({cfg.vehicle}): k(|e|) per channel and term")
    summary = {
        "name": outcome.config.name,
        "vehicle": outcome.config.vehicle,
        "structure": str(outcome.config.structure),
        "noise_scale": outcome.config.noise_scale,
        "effort_weight": outcome.config.effort_weight,
        "overshoot_weight": outcome.config.overshoot_weight,
        "method": res.method,
        "parameters": list(res.names),
        "k_best": res.k_best.tolist(),
        "j_initial": res.j_initial,
        "j_best": res.j_best,
        "iterations": int(res.j_history.shape[0] - 1),
        "restarts": int(res.j_history.shape[1]),
        "rollouts": res.n_evaluations,
        "batches": res.n_batches,
        "wall_s": outcome.wall_s,
    }
    paths["summary"].write_text(json.dumps(summary, indent=2) + "\n")
    return paths


def plot_convergence(res: EsResult, title: str, path: Path) -> None:
    """The paper's convergence plot: J per iteration for every restart (log scale), best restart bold."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6.0, 3.6), dpi=120)
    it = np.arange(res.j_history.shape[0])
    for r in range(res.j_history.shape[1]):
        j = np.where(np.isfinite(res.j_history[:, r]), res.j_history[:, r], np.nan)
        bold = r == res.best_restart
        ax.plot(it, j, lw=2.2 if bold else 1.0, alpha=1.0 if bold else 0.6, label=f"restart {r}" + (" (best)" * bold))
    ax.set_yscale("log")
    ax.set_xlabel("iteration")
    ax.set_ylabel("J = mean e²")
    ax.set_title(f"ES convergence: {title} ({res.method})")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)
