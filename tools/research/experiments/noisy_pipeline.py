"""The noisy, effort-aware tuning of both structures (issue 14, SPEC §6.3), shared by ``tools.research.tune_es --ship``
and ``tools.research.paper_table``.

Per level (attitude, then position on the same structure's tuned attitude loop), from one config
(``attitude_noisy.yaml``, ``position_noisy.yaml``):

1. the fixed PID (k1 = k2, no δ) is tuned by central ES with the config's cost (feedback noise on the
   training seeds, λ·chatter², μ·overshoot²), with at least the NLVG's rollout budget;
2. the NLVG-PID (k1, k2, δ1, δ2) is tuned with the same cost; restart 0 starts at the tuned PID, restart 1 at
   the base gains. "Best kept" then guarantees J_NLVG <= J at that warm start (at the attitude level, where
   both structures fly the same base, that is the PID's own J).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path

from autopilot.control.gains import CascadeGains
from tools.research.experiments.gain_vector import Structure
from tools.research.experiments.paper_pipeline import equal_budget_iterations
from tools.research.experiments.tune_config import StepExperiment, TuneConfig, load_tune_config
from tools.research.experiments.tuner import RolloutMap, TuneOutcome, in_process, tune

CONFIG_DIR = Path(__file__).resolve().parent
NOISY_LEVELS = ("attitude", "position")


def noisy_config(level: str, vehicle: str | None = None, effort_scale: float = 1.0) -> TuneConfig:
    """``<level>_noisy.yaml`` for ``vehicle`` with its λ multiplied by ``effort_scale``."""
    cfg = load_tune_config(CONFIG_DIR / f"{level}_noisy.yaml")
    return replace(cfg, vehicle=vehicle or cfg.vehicle, effort_weight=cfg.effort_weight * effort_scale)


def pid_twin(cfg: TuneConfig) -> TuneConfig:
    """The same cost with the fixed-PID structure (k1 = k2, δ not learned)."""
    return replace(cfg, name=f"{cfg.name}_pid", structure=Structure.PID, delta_bounds=None, warm_start=None)


@dataclass(frozen=True, slots=True)
class NoisyPair:
    """Both structures' cascades tuned in the noisy effort-aware setting, and the four outcomes."""

    gains: dict[str, CascadeGains]  # "pid" / "nlvg"
    outcomes: dict[tuple[str, str], TuneOutcome]  # (level, structure)
    j_warm_start: dict[str, float]  # level -> the NLVG's J at its warm start (the tuned PID's gains)


def tune_noisy_pair(
    vehicle: str | None = None,
    effort_scale: float = 1.0,
    iterations: int | None = None,
    log: Callable[[str], None] = print,
    step_scale: float = 1.0,
    rollouts: RolloutMap = in_process,
) -> NoisyPair:
    """Tune PID then NLVG (warm-started at that PID) per level, attitude first; see the module docstring.

    ``step_scale`` < 1 (smoke tests): step durations scaled, route experiments left out. ``rollouts`` flies the
    ES cost evaluations (in this process, or on the campaign engine: the same numbers)."""
    base = {s: CascadeGains.fixed_pid() for s in ("pid", "nlvg")}
    outcomes: dict[tuple[str, str], TuneOutcome] = {}
    j_warm: dict[str, float] = {}
    for level in NOISY_LEVELS:
        cfg = noisy_config(level, vehicle, effort_scale)
        if iterations is not None:
            cfg = cfg.with_budget(iterations=iterations)
        if step_scale != 1.0:
            kept = [e for e in cfg.experiments if isinstance(e, StepExperiment)]
            steps = tuple(replace(e, duration_s=e.duration_s * step_scale) for e in kept)
            cfg = replace(cfg, experiments=steps)
        pid_cfg = pid_twin(cfg)
        dims = {s: c.parametrisation().space().dim for s, c in (("nlvg", cfg), ("pid", pid_cfg))}
        pid_iters = equal_budget_iterations(dims["nlvg"], dims["pid"], cfg.es.restarts, cfg.es.iterations)
        pid = tune(replace(pid_cfg, base_gains=base["pid"]).with_budget(iterations=pid_iters), rollouts=rollouts)
        nlvg = tune(replace(cfg, base_gains=base["nlvg"], warm_start=pid.gains), rollouts=rollouts)
        j_warm[level] = float(nlvg.result.j_history[0, 0])
        for s, out in (("pid", pid), ("nlvg", nlvg)):
            outcomes[(level, s)] = out
            base[s] = out.gains
            log(
                f"noisy {level:<8} {s:<4} (λ×{effort_scale:g}, {cfg.vehicle}): J {out.result.j_initial:.5g} -> "
                f"{out.result.j_best:.5g} ({out.result.n_evaluations} rollouts, {out.wall_s:.1f} s)"
            )
    return NoisyPair(dict(base), outcomes, j_warm)
