"""Run one ES tune from a :class:`TuneConfig`: the batched closed-loop cost and its outputs (SPEC §6.3).

The cost of a batch of parameter vectors ``K (m, d)`` flies ``m`` vehicles at once per experiment
(:func:`tools.experiments.rollout.run_step`) and sums ``weight * 1/(tf-t0) ∫ e² dt`` over the experiments.
"""

from __future__ import annotations

import csv
import json
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from autopilot.control.gains import CascadeGains
from autopilot.tuning import CentralEsConfig, EsResult, central_es, perturbation_es
from autopilot.tuning.es_result import IterationCallback
from tools.experiments.gain_vector import GainParametrisation
from tools.experiments.rollout import mean_square_cost, run_step
from tools.experiments.tune_config import TuneConfig


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


def step_cost(config: TuneConfig, param: GainParametrisation):
    """The batched cost J(K (m, d)) -> (m,) of ``config``'s step experiments."""

    def cost(k: np.ndarray) -> np.ndarray:
        gains = param.gains(k)
        total = np.zeros(k.shape[0])
        for exp in config.experiments:
            trace = run_step(config.vehicle, gains, exp.channel, exp.amplitude, exp.duration_s, m=k.shape[0])
            total += exp.weight * mean_square_cost(trace.error, trace.t_s, trace.diverged, exp.t0_s)
        return total

    return cost


def tune(config: TuneConfig, on_iteration: IterationCallback | None = None) -> TuneOutcome:
    """Run ES as configured; restart 0 starts at the base gains when ``start_from_base``."""
    param = config.parametrisation()
    space = param.space()
    cost = step_cost(config, param)
    initial = param.vector(config.base_gains) if config.start_from_base else None
    t0 = time.perf_counter()
    if isinstance(config.es, CentralEsConfig):
        result = central_es(cost, space, config.es, initial_gains=initial, on_iteration=on_iteration)
    else:
        result = perturbation_es(cost, space, config.es, initial_gains=initial, on_iteration=on_iteration)
    wall = time.perf_counter() - t0
    return TuneOutcome(config, result, param.single(result.k_best), wall)


def write_outputs(outcome: TuneOutcome, out_dir: str | Path) -> dict[str, Path]:
    """Write ``gains.yaml``, ``j_per_iteration.csv``, ``convergence.png`` and ``summary.json`` into ``out_dir``."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    res = outcome.result
    paths = {
        "gains": out / "gains.yaml",
        "csv": out / "j_per_iteration.csv",
        "plot": out / "convergence.png",
        "summary": out / "summary.json",
    }
    outcome.gains.to_yaml(paths["gains"])
    with paths["csv"].open("w", newline="") as f:
        w = csv.writer(f)
        r = res.j_history.shape[1]
        w.writerow(["iteration", *[f"J_restart{i}" for i in range(r)], "J_min_over_restarts"])
        running = np.minimum.accumulate(res.j_history.min(axis=1))
        for i, row in enumerate(res.j_history):
            w.writerow([i, *[f"{v:.9g}" for v in row], f"{running[i]:.9g}"])
    plot_convergence(res, outcome.config.name, paths["plot"])
    summary = {
        "name": outcome.config.name,
        "vehicle": outcome.config.vehicle,
        "structure": str(outcome.config.structure),
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
