"""Extremum seeking on the product's own closed loop (issue 22 item 1, SPEC §6.3, paper §3.2).

Every ES probe is flown by the product itself (:func:`tools.research.experiments.loop_rollout.fly_route`: the
simulator's sensor models -> the EKF -> commander, navigator and the NLVG-PID cascade, in process, seeded) on
short segments like the user's flights: ``leg`` (a delivery leg in wind with the parcel: cruise, lower,
release, climb) and ``steps`` (the paper's small position steps, 1 m and 0.5 m, as the product flies them).
Per gain set the cost, on the TRUE tracking error, averaged over the training seeds, is::

    J = Σ_route w_r · mean e_r² / mean e_r,ref²  +  λ · mean_r chatter_r² / chatter_r,ref²

normalised by the paper's fixed PID (``CascadeGains.fixed_pid()``) flown on the same segments and seeds, so
J(paper PID) = Σ w + λ and one λ means the same trade on every airframe (λ = 0.25: a 10 % cut of chatter RMS is
worth about a 2 % rise of the RMS error). What the EKF's own error adds to e (a slow GPS-like drift, about
0.5 m) is in every rollout and no gain removes it.

The position level is learned (x+y shared, z its own: k1, k2, δ1, δ2 for the NLVG-PID; k_p, k_i, k_d for the
fixed PID); the attitude loop is the base gains' for both structures, so the pair differs only in the variable
gain. The fixed PID is tuned first with at least the NLVG's rollout budget (restart 0 at the paper PID's position
gains, restart 1 at the base's k1); the NLVG's restart 0 starts at that tuned PID ("best kept": it never ends
above it on the training cost), restart 1 at the base gains.

Each ES iteration's rollouts are one ordered map over small frozen payloads (:func:`map_rollouts`).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace

import numpy as np

from autopilot.control.gains import POSITION_CHANNELS, CascadeGains
from autopilot.tuning import CentralEsConfig, EsResult, central_es
from tools.campaign.engine import TaskEngine
from tools.research.experiments.gain_vector import GainParametrisation, Structure
from tools.research.experiments.loop_rollout import LoopOutcome, LoopRollout, fly_route
from tools.research.experiments.paper_pipeline import equal_budget_iterations

#: λ of the shipped tuning (see the module docstring)
LOOP_EFFORT_WEIGHT = 0.25
POSITION_GROUPS: tuple[tuple[str, ...], ...] = (("x", "y"), ("z",))
#: k_i >= 0.1 as in position_noisy.yaml: a mission holds against steady wind longer than a segment lasts
POSITION_BOUNDS = {"kp": (0.5, 30.0), "ki": (0.1, 3.0), "kd": (0.3, 30.0)}
POSITION_DELTA_BOUNDS = {"delta1": (0.005, 0.15), "delta2": (0.2, 3.0)}

#: flies a batch of rollouts and returns their outcomes in input order
Mapper = Callable[[Sequence[LoopRollout]], list[LoopOutcome]]


def in_process(payloads: Sequence[LoopRollout]) -> list[LoopOutcome]:
    """The :data:`Mapper` of small runs and tests: every rollout in this process, one after the other."""
    return [fly_route(p) for p in payloads]


def engine_mapper(engine: TaskEngine, label: str | None = None) -> Mapper:
    """The :data:`Mapper` on an open campaign engine session (one ordered map over its worker processes)."""
    return engine.mapper(fly_route, key="loop-rollout", progress_label=label)


@dataclass(frozen=True, slots=True)
class LoopTuneConfig:
    """One structure's tune on one airframe's closed loop."""

    vehicle: str
    structure: Structure
    base: CascadeGains  # attitude loop of both structures, and the NLVG's restart-1 start
    routes: tuple[tuple[str, float], ...] = (("leg", 1.0), ("steps", 1.0))
    seeds: tuple[int, ...] = (1, 2)
    effort_weight: float = LOOP_EFFORT_WEIGHT
    es: CentralEsConfig = field(default_factory=lambda: CentralEsConfig(iterations=8, restarts=1, seed=0))
    warm_start: CascadeGains | None = None
    estimator: str = "ekf"

    def parametrisation(self) -> GainParametrisation:
        deltas = POSITION_DELTA_BOUNDS if self.structure is Structure.NLVG else None
        return GainParametrisation(self.base, POSITION_GROUPS, self.structure, POSITION_BOUNDS, deltas)

    def payloads(self, gains: Sequence[CascadeGains]) -> list[LoopRollout]:
        """Rollouts of every gain set on every route and seed (gain-set major)."""
        return [
            LoopRollout.of(self.vehicle, g, route, seed, self.estimator)
            for g in gains
            for route, _w in self.routes
            for seed in self.seeds
        ]


@dataclass(frozen=True, slots=True)
class Reference:
    """The paper PID's mean e² and chatter² per route on the training seeds (the cost's normalisers)."""

    mse_m2: tuple[float, ...]
    chatter_sq: tuple[float, ...]


def _per_route(cfg: LoopTuneConfig, outcomes: Sequence[LoopOutcome], m: int) -> tuple[np.ndarray, np.ndarray]:
    """(m, routes) seed-mean e² and chatter² from gain-set-major outcomes."""
    nr, ns = len(cfg.routes), len(cfg.seeds)
    mse = np.array([o.mean_sq_err_m2 for o in outcomes]).reshape(m, nr, ns).mean(axis=2)
    ch = np.array([o.chatter_rms_per_s**2 for o in outcomes]).reshape(m, nr, ns).mean(axis=2)
    return mse, ch


def reference(cfg: LoopTuneConfig, mapper: Mapper) -> Reference:
    """Fly the paper's fixed PID on ``cfg``'s routes and seeds."""
    mse, ch = _per_route(cfg, mapper(cfg.payloads([CascadeGains.fixed_pid()])), 1)
    if not np.all(np.isfinite(mse)):
        raise RuntimeError(f"the paper PID did not complete the tuning routes on {cfg.vehicle}")
    return Reference(tuple(mse[0]), tuple(ch[0]))


def loop_cost(cfg: LoopTuneConfig, ref: Reference, mapper: Mapper) -> Callable[[np.ndarray], np.ndarray]:
    """The batched cost J(K (m, d)) -> (m,) of the module docstring."""
    param = cfg.parametrisation()
    w = np.array([wt for _r, wt in cfg.routes])
    ref_mse, ref_ch = np.array(ref.mse_m2), np.array(ref.chatter_sq)

    def cost(k: np.ndarray) -> np.ndarray:
        gains = [param.single(row) for row in np.atleast_2d(k)]
        mse, ch = _per_route(cfg, mapper(cfg.payloads(gains)), len(gains))
        with np.errstate(invalid="ignore"):
            j = (mse / ref_mse) @ w + cfg.effort_weight * np.mean(ch / ref_ch, axis=1)
        return np.where(np.isfinite(j), j, np.inf)

    return cost


@dataclass(frozen=True, slots=True)
class LoopOutcomeOfTune:
    """A finished tune: its config, the ES result, the tuned gains and the wall time."""

    config: LoopTuneConfig
    result: EsResult
    gains: CascadeGains
    wall_s: float


def tune_loop(cfg: LoopTuneConfig, ref: Reference, mapper: Mapper, on_iteration=None) -> LoopOutcomeOfTune:
    """Central ES on :func:`loop_cost`; restart 0 at ``warm_start`` when given, the next at the base gains."""
    param = cfg.parametrisation()
    starts = ([param.vector(cfg.warm_start)] if cfg.warm_start is not None else []) + [param.vector(cfg.base)]
    initial = np.stack(starts[: cfg.es.restarts])
    t0 = time.perf_counter()
    res = central_es(
        loop_cost(cfg, ref, mapper), param.space(), cfg.es, initial_gains=initial, on_iteration=on_iteration
    )
    return LoopOutcomeOfTune(cfg, res, param.single(res.k_best), time.perf_counter() - t0)


@dataclass(frozen=True, slots=True)
class LoopPair:
    """The equally tuned fixed PID and NLVG-PID of one airframe, and the paper PID's reference."""

    pid: LoopOutcomeOfTune
    nlvg: LoopOutcomeOfTune
    reference: Reference


def tune_pair(
    vehicle: str,
    base: CascadeGains,
    mapper: Mapper,
    iterations: int = 8,
    restarts: int = 2,
    effort_weight: float = LOOP_EFFORT_WEIGHT,
    log: Callable[[str], None] = print,
) -> LoopPair:
    """Tune the fixed PID (k1 = k2), then the NLVG-PID warm-started at it, with the same cost and at least the
    same rollout budget (module docstring)."""
    es = CentralEsConfig(iterations=iterations, restarts=restarts, seed=0)
    nlvg_cfg = LoopTuneConfig(vehicle, Structure.NLVG, base, effort_weight=effort_weight, es=es)
    pid_cfg = replace(nlvg_cfg, structure=Structure.PID)
    dims = {c.structure: c.parametrisation().space().dim for c in (nlvg_cfg, pid_cfg)}
    pid_iters = equal_budget_iterations(dims[Structure.NLVG], dims[Structure.PID], restarts, iterations)
    pid_cfg = replace(pid_cfg, es=replace(es, iterations=pid_iters), warm_start=paper_position_on(base))
    ref = reference(nlvg_cfg, mapper)
    log(f"[{vehicle}] paper PID on the tuning routes: e RMS {np.sqrt(ref.mse_m2)} m, chatter {np.sqrt(ref.chatter_sq)}")

    def progress(name: str):  # type: ignore[no-untyped-def]
        def on_iteration(it) -> None:  # type: ignore[no-untyped-def]
            log(f"[{vehicle}] {name} iteration {it.iteration}: J_best {it.j_best:.4f}")

        return on_iteration

    pid = tune_loop(pid_cfg, ref, mapper, progress("pid"))
    log(f"[{vehicle}] pid J {pid.result.j_initial:.4f} -> {pid.result.j_best:.4f} ({pid.wall_s:.0f} s)")
    nlvg = tune_loop(replace(nlvg_cfg, warm_start=pid.gains), ref, mapper, progress("nlvg"))
    log(f"[{vehicle}] nlvg J {nlvg.result.j_initial:.4f} -> {nlvg.result.j_best:.4f} ({nlvg.wall_s:.0f} s)")
    return LoopPair(pid, nlvg, ref)


def paper_position_on(base: CascadeGains) -> CascadeGains:
    """``base`` with the paper's fixed-PID gains on the position channels (the PID tune's restart 0)."""
    paper = CascadeGains.fixed_pid()
    return replace(base, **{ch: getattr(paper, ch) for ch in POSITION_CHANNELS})


def rms_or_nan(values: Sequence[float]) -> float:
    """RMS of finite values (nan when none)."""
    v = np.asarray([x for x in values if math.isfinite(x)])
    return float(np.sqrt(np.mean(v * v))) if v.size else math.nan
