"""Failure probability by importance sampling with a cross-entropy-adapted proposal (SPEC §14): the math, no flights.

The nominal density p is the campaign's own draw over a :class:`~tools.campaign.search_space.SearchSpace` and a
proposal q a mixture of truncated normals with choice masses (:mod:`tools.campaign.proposal`). :func:`ce_is` adapts
q by the cross-entropy method (Rubinstein): each level flies ``level_batch`` points from q, the level gamma is the
rho-quantile of their margins (ties broken by a seeded draw), and q is refitted to the points at or below gamma,
weighted by p/q, with up to ``components`` mixture components (one per failure mode the elite shows); once gamma
reaches 0 (the failure level), or half the elite already fail (the widened proposal otherwise stalls a little
above it), q is refitted to the failing points and a final batch is flown from the defensive mixture
m = 0.9 q + 0.1 p and

    P = mean(1{margin < 0} p/m),   95 % interval P +- 1.96 sd/sqrt(n),   Kish ESS = (sum w)^2 / sum w^2,

with the mean weight (about 1 when m covers p's mass). ``evaluate(first_case_id, points)`` gives the margins: the
flights (:mod:`tools.campaign.search_run`) or an analytic function (the tests).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from tools.campaign.proposal import Proposal, refit
from tools.campaign.search_space import Point, SearchSpace

DEFENSIVE_NOMINAL = 0.1  # m = (1 - this) q + this p
Evaluate = Callable[[int, Sequence[Point]], Sequence[float]]


def mixture_log_pdf(q: Proposal, space: SearchSpace, points: Sequence[Point]) -> np.ndarray:
    """log m, m = (1 - DEFENSIVE_NOMINAL) q + DEFENSIVE_NOMINAL p."""
    log_q, log_p = q.log_pdf(points), np.full(len(points), space.nominal_log_pdf())
    return np.logaddexp(math.log(1.0 - DEFENSIVE_NOMINAL) + log_q, math.log(DEFENSIVE_NOMINAL) + log_p)


def sample_mixture(q: Proposal, space: SearchSpace, rng: np.random.Generator, n: int) -> list[Point]:
    """n points from the defensive mixture (each from p with probability DEFENSIVE_NOMINAL, else from q)."""
    from_p = rng.random(n) < DEFENSIVE_NOMINAL
    nominal = Proposal.nominal(space).sample(rng, n, space.dims)
    proposed = q.sample(rng, n, space.dims)
    return [nominal[i] if from_p[i] else proposed[i] for i in range(n)]


def ranked(margins: Sequence[float], rng: np.random.Generator) -> np.ndarray:
    """Indices from the lowest margin up, ties broken by a seeded draw (NaN: no verdict, last)."""
    m = np.array(margins, dtype=float)
    return np.lexsort((rng.random(len(m)), np.where(np.isnan(m), np.inf, m)))


@dataclass(frozen=True)
class Level:
    """One cross-entropy level: its points, margins, the level reached and the proposal they were drawn from."""

    index: int
    first_case: int
    points: tuple[Point, ...]
    margins: tuple[float, ...]
    gamma: float
    proposal: Proposal


@dataclass(frozen=True)
class ISEstimate:
    """The importance-sampling estimate of P(margin < 0) from one batch of weighted points."""

    p: float
    ci95: tuple[float, float]
    ess: float
    mean_weight: float
    n: int
    failures: int


def is_estimate(failed: np.ndarray, log_w: np.ndarray) -> ISEstimate:
    """P = mean(1{failed} w), its normal 95 % interval (clipped at 0), the Kish ESS and the mean weight."""
    w = np.exp(np.asarray(log_w, dtype=float))
    f = np.asarray(failed, dtype=bool)
    n = len(w)
    terms = np.where(f, w, 0.0)
    p = float(terms.mean())
    half = 1.96 * float(terms.std(ddof=1)) / math.sqrt(n) if n > 1 else math.inf
    ess = float(w.sum() ** 2 / (w**2).sum())
    return ISEstimate(p, (max(0.0, p - half), p + half), ess, float(w.mean()), n, int(f.sum()))


@dataclass(frozen=True)
class CEISResult:
    """The adaptation levels, the final batch (points, margins, log weights) and the estimate."""

    levels: tuple[Level, ...]
    reached: bool  # the levels reached the failure level (gamma <= 0)
    final_first_case: int
    final_points: tuple[Point, ...]
    final_margins: tuple[float, ...]
    final_log_w: tuple[float, ...]
    estimate: ISEstimate


def ce_is(
    space: SearchSpace,
    evaluate: Evaluate,
    *,
    seed: int,
    rho: float = 0.1,
    level_batch: int = 100,
    final: int = 200,
    max_levels: int = 8,
    components: int = 1,
    evaluate_final: Evaluate | None = None,
) -> CEISResult:
    """Adapt q by cross-entropy levels, then estimate P(margin < 0) from ``final`` points of the defensive mixture.
    A pure function of (space, evaluate, seed, options); case ids are handed out in flight order from 0.
    ``evaluate_final``: what evaluates the final batch (default ``evaluate``)."""
    rng = np.random.default_rng([seed, 29])
    log_p0 = space.nominal_log_pdf()
    q = Proposal.nominal(space)
    levels: list[Level] = []
    next_case, reached = 0, False
    n_elite = max(2, math.ceil(rho * level_batch))
    for index in range(max_levels):
        points = q.sample(rng, level_batch, space.dims)
        margins = np.array(evaluate(next_case, points), dtype=float)
        order = ranked(margins, rng)
        gamma = float(margins[order[n_elite - 1]]) if np.isfinite(margins[order[n_elite - 1]]) else math.inf
        failing = np.flatnonzero(margins < 0.0)
        reached = gamma <= 0.0 or 2 * len(failing) >= n_elite
        elite = failing if reached else order[:n_elite]
        if len(elite) < 2:  # one failure at the last level: keep the rho elite so the fit stays a distribution
            elite = order[:n_elite]
        levels.append(Level(index, next_case, tuple(points), tuple(map(float, margins)), gamma, q))
        next_case += level_batch
        chosen = [points[i] for i in elite]
        log_w = log_p0 - q.log_pdf(chosen)
        q = refit(space, q, chosen, np.exp(log_w - log_w.max()), 1.0, components)
        if reached:
            break
    points = sample_mixture(q, space, rng, final)
    margins = np.array((evaluate_final or evaluate)(next_case, points), dtype=float)
    log_w = log_p0 - mixture_log_pdf(q, space, points)
    known = np.isfinite(margins)  # a flight with no verdict is left out (the report counts them)
    est = is_estimate(margins[known] < 0.0, log_w[known])
    return CEISResult(
        tuple(levels), reached, next_case, tuple(points), tuple(map(float, margins)), tuple(map(float, log_w)), est
    )


def mc_interval(failures: int, n: int) -> tuple[float, float]:
    """The exact (Clopper-Pearson) 95 % interval of a plain Monte Carlo failure rate."""
    from tools.campaign.report import pass_interval

    low, high = pass_interval(n - failures, n)
    return (1.0 - high, 1.0 - low)
