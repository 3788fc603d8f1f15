"""Failure search: minimise a campaign's margin over its inputs, batch by batch (SPEC §14): the optimisers, no flights.

- :func:`cmaes`: CMA-ES (pycma, the reference implementation) over the continuous inputs normalised to [0, 1]
  (``bounds``), ask -> one batch -> tell, never asking a generation before the last one is told; restarted from a
  seeded uniform point (same popsize) when pycma stops before the budget;
- :func:`cem`: the cross-entropy method over mixed inputs (truncated normals and choice masses,
  :mod:`tools.campaign.estimate`'s proposal): each batch from q, q refitted to the best ``elite_frac``, smoothed.

Both are pure functions of (space, evaluate, seed, options): ties between equal margins (a plateau) are broken by
a seeded draw, pycma's normal draws come from the search's own generator, and case ids are handed out in flight
order from 0. A batch's margins come from ``evaluate(first_case_id, points)`` (NaN: the flight gave no verdict;
the optimiser ranks it last).
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass

import numpy as np

from tools.campaign.estimate import Evaluate, ranked
from tools.campaign.proposal import Proposal, refit
from tools.campaign.search_space import Point, SearchSpace

METHODS = ("cmaes", "cem")
TIE_EPS = 1e-9  # the size of the seeded tie-breaker added to the margins pycma ranks


@dataclass(frozen=True)
class Batch:
    """One generation: its points in flight order (case ids first_case...) and their margins."""

    index: int
    first_case: int
    points: tuple[Point, ...]
    margins: tuple[float, ...]


def default_popsize(dims: int) -> int:
    """pycma's default population (4 + 3 ln n) rounded up to a multiple of 4 (1, 2 or 4 workers stay busy)."""
    return 4 * math.ceil((4 + int(3 * math.log(max(dims, 1)))) / 4)


def cmaes(
    space: SearchSpace, evaluate: Evaluate, *, budget: int, popsize: int, seed: int, sigma0: float = 0.3
) -> list[Batch]:
    """CMA-ES over ``space``'s continuous inputs; ``budget // popsize`` generations."""
    import cma

    if space.categorical:
        raise ValueError("cmaes searches continuous inputs only")
    rng = np.random.default_rng([seed, 14])
    batches: list[Batch] = []
    es = _new_es(cma, [0.5] * space.dims, sigma0, popsize, rng)
    worst = 0.0
    while (len(batches) + 1) * popsize <= budget:
        if es.stop():
            es = _new_es(cma, list(rng.random(space.dims)), sigma0, popsize, rng)
        xs = es.ask()
        points = [Point(tuple(float(min(1.0, max(0.0, v))) for v in x)) for x in xs]
        margins = np.array(evaluate(len(batches) * popsize, points), dtype=float)
        finite = margins[np.isfinite(margins)]
        worst = max([worst, *finite.tolist()])
        told = np.where(np.isfinite(margins), margins, worst + 1.0) + TIE_EPS * rng.random(len(margins))
        es.tell(xs, told.tolist())
        batches.append(Batch(len(batches), len(batches) * popsize, tuple(points), tuple(map(float, margins))))
    return batches


def _new_es(cma: object, x0: list[float], sigma0: float, popsize: int, rng: np.random.Generator) -> object:
    opts = {
        "bounds": [0.0, 1.0],
        "popsize": popsize,
        "randn": lambda lam, n: rng.standard_normal((lam, n)),
        "seed": 1,  # unused for draws (randn above); set so pycma never seeds from the clock
        "verbose": -9,
        "tolflatfitness": 3,
    }
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return cma.CMAEvolutionStrategy(x0, sigma0, opts)  # type: ignore[attr-defined]


def cem(
    space: SearchSpace,
    evaluate: Evaluate,
    *,
    budget: int,
    batch: int,
    seed: int,
    elite_frac: float = 0.1,
    smoothing: float = 0.7,
) -> list[Batch]:
    """The cross-entropy method over mixed inputs; ``budget // batch`` batches, the first from the campaign's own
    draw."""
    rng = np.random.default_rng([seed, 15])
    q = Proposal.nominal(space)
    n_elite = max(2, math.ceil(elite_frac * batch))
    batches: list[Batch] = []
    while (len(batches) + 1) * batch <= budget:
        points = q.sample(rng, batch, space.dims)
        margins = np.array(evaluate(len(batches) * batch, points), dtype=float)
        elite = ranked(margins, rng)[:n_elite]
        q = refit(space, q, [points[i] for i in elite], np.ones(n_elite), smoothing)
        batches.append(Batch(len(batches), len(batches) * batch, tuple(points), tuple(map(float, margins))))
    return batches


def first_failure(batches: list[Batch]) -> int | None:
    """Flights flown up to and including the first one with a negative margin (None: no failure)."""
    for b in batches:
        for j, m in enumerate(b.margins):
            if m < 0.0:
                return b.first_case + j + 1
    return None
