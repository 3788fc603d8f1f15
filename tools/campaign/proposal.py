"""The sampling densities of the searches and the importance-sampling estimate (SPEC §14): the campaign's own draw p
and the proposals q fitted to the best points, with their exact densities.

Over a :class:`~tools.campaign.search_space.SearchSpace` the nominal p is uniform in [0, 1] per continuous input
and 1/K per choice. A proposal q is p itself, or a mixture of components, each independent normals truncated to
[0, 1] (so a component's density is exact: the product of its truncated normals), times independent choice masses.
One component is the classic cross-entropy family; several hold several failure modes at once (a failure region in
two corners, a headwind from either side), which one truncated normal cannot: fitted to two clusters it sits
between them or follows one, and an importance-sampling estimate drawn from it misses the other's probability
(Kurtz & Song 2013, cross-entropy importance sampling with Gaussian mixtures).

:func:`refit` is the weighted maximum-likelihood fit to the elite points: moments for one component; for up to
``components`` it runs a weighted EM from a farthest-point start for each count and keeps the count of the lowest
BIC (a count needs ``MIN_POINTS_PER_COMPONENT`` elite points a component; the components share one spread per
input). One component's normals are widened by ``SD_INFLATE``, a mixture's by ``MIXTURE_SD_INFLATE``, none narrower
than ``SD_FLOOR``; a choice's mass never below ``MASS_FLOOR / K``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy.special import logsumexp
from scipy.stats import norm

from tools.campaign.search_space import Point, SearchSpace

#: log of the standard normal density's constant, as scipy.stats.norm has it (so ``_norm_logpdf`` is its logpdf bit
#: for bit, without its per-call argument checks: the EM calls it thousands of times per fit).
_NORM_LOG_C = np.log(np.sqrt(2 * np.pi))

SD_FLOOR = 0.02  # a proposal's normals never narrower than 2 % of an input's range
#: The refitted normals widened by this: a proposal a little wider than its elite covers the failure region better
#: (a 4-D corner of P 3.4e-4, 60 flights a level, rho 0.1: the 95 % interval held P for 2 of 12 seeds at 1.0, 9 at 1.5).
SD_INFLATE = 1.5
#: A mixture component is fitted to fewer points (its own cluster): widened more (a 4-D two-sided corner of P 3e-4,
#: 100 flights a level, final 300: the median estimate 0.92 P at 1.5 and 2.0, the interval held P for 29 of 40 seeds
#: at 2.0 and 23 at 1.5).
MIXTURE_SD_INFLATE = 2.0
MASS_FLOOR = 0.02  # nor a choice's mass below 2 % / K (q must cover what p covers)
MIN_POINTS_PER_COMPONENT = 3  # a mixture of k components is fitted to at least 3k elite points
EM_ITERATIONS = 60
_UNIFORM_SD = math.sqrt(1.0 / 12.0)


@dataclass(frozen=True)
class Component:
    """One mixture component: its ``weight`` and (mean, sd) per continuous input, each truncated to [0, 1]."""

    weight: float
    normals: tuple[tuple[float, float], ...]

    def log_pdf(self, u: np.ndarray) -> np.ndarray:
        """log of the component's density at the rows of ``u`` (n x dims), its truncation included."""
        out = np.zeros(len(u))
        for j, (m, s) in enumerate(self.normals):
            mass = norm.cdf((1.0 - m) / s) - norm.cdf(-m / s)
            out += _norm_logpdf((u[:, j] - m) / s) - math.log(s) - math.log(mass)
        return out

    def sample(self, rng: np.random.Generator, n: int) -> np.ndarray:
        u = np.empty((n, len(self.normals)))
        for j, (m, s) in enumerate(self.normals):
            lo, hi = norm.cdf(-m / s), norm.cdf((1.0 - m) / s)
            u[:, j] = np.clip(m + s * norm.ppf(lo + (hi - lo) * rng.random(n)), 0.0, 1.0)
        return u


@dataclass(frozen=True)
class Proposal:
    """q: ``components`` None is the nominal p (uniform); else their mixture; ``masses`` per choice input."""

    components: tuple[Component, ...] | None
    masses: tuple[tuple[float, ...], ...]

    @staticmethod
    def nominal(space: SearchSpace) -> Proposal:
        return Proposal(None, tuple(tuple([1.0 / k] * k) for k in space.sizes))

    def sample(self, rng: np.random.Generator, n: int, dims: int) -> list[Point]:
        if self.components is None:
            u = rng.random((n, dims))
        elif len(self.components) == 1:
            u = self.components[0].sample(rng, n)
        else:
            label = rng.choice(len(self.components), size=n, p=[c.weight for c in self.components])
            u = np.empty((n, dims))
            for k, comp in enumerate(self.components):
                rows = np.flatnonzero(label == k)
                u[rows] = comp.sample(rng, len(rows))
        cats = np.array([rng.choice(len(p), size=n, p=p) for p in self.masses], dtype=int).reshape(-1, n).T
        return [Point(tuple(map(float, u[i])), tuple(map(int, cats[i]))) for i in range(n)]

    def log_pdf(self, points: Sequence[Point]) -> np.ndarray:
        out = np.zeros(len(points))
        if self.components is not None:
            u = np.array([p.u for p in points], dtype=float).reshape(len(points), -1)
            per = np.array([math.log(c.weight) + c.log_pdf(u) for c in self.components])
            out += logsumexp(per, axis=0)
        for j, masses in enumerate(self.masses):
            out += np.log([masses[p.cats[j]] for p in points])
        return out


def refit(
    space: SearchSpace,
    old: Proposal,
    points: Sequence[Point],
    weights: np.ndarray,
    smoothing: float,
    components: int = 1,
) -> Proposal:
    """The weighted maximum-likelihood fit of q to ``points`` (normals, masses). One component is smoothed with
    ``old``'s first (``smoothing``: the new fit's share); a mixture (``components`` > 1, chosen by BIC) is not."""
    w = np.asarray(weights, dtype=float)
    w = w / w.sum()
    fitted: tuple[Component, ...] | None = None
    if space.dims:
        u = np.array([p.u for p in points], dtype=float)
        most = min(components, len(points) // MIN_POINTS_PER_COMPONENT)
        if most > 1:
            fitted = _best_mixture(u, w, most)
        else:
            mean = w @ u
            sd = SD_INFLATE * np.sqrt(np.maximum(w @ (u - mean) ** 2, 0.0))
            old_n = old.components[0].normals if old.components else tuple((0.5, _UNIFORM_SD) for _ in mean)
            fitted = (Component(1.0, tuple(
                (smoothing * m + (1 - smoothing) * om, max(SD_FLOOR, smoothing * s + (1 - smoothing) * os))
                for m, s, (om, os) in zip(mean, sd, old_n, strict=True))),)  # fmt: skip
    masses = []
    for j, k in enumerate(space.sizes):
        counts = np.array([sum(w[i] for i, p in enumerate(points) if p.cats[j] == c) for c in range(k)])
        mixed = np.maximum(smoothing * counts + (1 - smoothing) * np.array(old.masses[j]), MASS_FLOOR / k)
        masses.append(tuple(float(x) for x in mixed / mixed.sum()))
    return Proposal(fitted, tuple(masses))


def _norm_logpdf(z: np.ndarray) -> np.ndarray:
    """The standard normal's log density at ``z`` (``scipy.stats.norm.logpdf``'s formula)."""
    return -(z**2) / 2.0 - _NORM_LOG_C


def _best_mixture(u: np.ndarray, w: np.ndarray, most: int) -> tuple[Component, ...]:
    """The diagonal mixture of 1..``most`` components with the lowest BIC (n: the weights' Kish size)."""
    n_eff = 1.0 / float((w**2).sum())
    best: tuple[float, tuple[Component, ...]] | None = None
    for k in range(1, most + 1):
        pi, mean, sd, loglik = _weighted_em(u, w, k)
        bic = -2.0 * n_eff * loglik + ((k + 1) * u.shape[1] + k - 1) * math.log(n_eff)
        if best is None or bic < best[0]:
            spread = tuple(max(SD_FLOOR, MIXTURE_SD_INFLATE * float(s)) for s in sd)
            comps = tuple(Component(float(pi[c]), tuple(zip(map(float, mean[c]), spread, strict=True)))
                          for c in range(k) if pi[c] > 0.0)  # fmt: skip
            best = (bic, comps)
    assert best is not None
    return best[1]


def _weighted_em(u: np.ndarray, w: np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """Weighted EM of a k-component diagonal normal mixture with one spread per input shared by the components
    (untruncated; floored at ``SD_FLOOR``), from a farthest-point start: the heaviest point, then each next the
    point of the largest weight x squared distance to the chosen. Returns (weights (k), means (k x dims), the
    spread (dims), mean log-likelihood per unit weight)."""
    centres = [int(np.argmax(w))]
    for _ in range(1, k):
        d2 = np.min(((u[:, None, :] - u[centres][None, :, :]) ** 2).sum(axis=2), axis=1)
        centres.append(int(np.argmax(w * d2)))
    mean = u[centres].copy()
    sd = np.full(u.shape[1], max(SD_FLOOR, float(np.sqrt(w @ (u - w @ u) ** 2).mean()) / k))
    pi = np.full(k, 1.0 / k)
    loglik = -math.inf
    for _ in range(EM_ITERATIONS):
        with np.errstate(divide="ignore"):  # a component that lost every point: log 0, no responsibility
            log_pi = np.log(pi)
        log_r = log_pi[None, :] + np.stack(
            [(_norm_logpdf((u - mean[c]) / sd) - np.log(sd)).sum(axis=1) for c in range(k)], axis=1
        )
        log_norm = logsumexp(log_r, axis=1)
        loglik = float(w @ log_norm)
        r = np.exp(log_r - log_norm[:, None]) * w[:, None]
        mass = r.sum(axis=0)
        live = mass > 1e-12
        pi = mass / mass.sum()
        mean = np.where(live[:, None], (r.T @ u) / np.where(live, mass, 1.0)[:, None], mean)
        pooled = sum(r[:, c] @ (u - mean[c]) ** 2 for c in range(k)) / float(w.sum())
        sd = np.maximum(np.sqrt(np.maximum(pooled, 0.0)), SD_FLOOR)
    return pi, mean, sd, loglik
