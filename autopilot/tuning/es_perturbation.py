"""Classic perturbation-based extremum seeking (SPEC §6.3 second method; Killingsworth & Krstić 2006).

Discrete-time loop per parameter j, at iteration k, in normalised coordinates (unit box)::

    z_k      = zhat_k + a sin(w_j k)                     sinusoidal dither, distinct w_j in (0, pi) rad/iter
    y_k      = J(z_k) / J(z_0)                           measured cost, scaled by the loop's first cost
                                                         (log_cost=True: y_k = log(J(z_k) + eps) instead)
    l_{k+1}  = l_k + h (y_k - l_k);  eta_k = y_k - l_k   first-order high-pass filter (removes the DC part)
    xi_k     = eta_k sin(w_j k)                          demodulation: on average (a/2) dlogJ/dz_j
    zhat_{k+1} = clip(zhat_k - gamma xi_k, 0, 1)         integrator, projected onto the box

The per-iteration change of ``zhat`` is bounded by ``max_step`` (a guard against a cost jump, e.g. a
rollout that nearly diverged). Scaling by the first cost makes ``gamma`` dimensionless.

``restarts`` independent loops (different random starts) run side by side: each iteration is ONE call
of the batched cost with ``restarts`` rows. The result keeps the lowest-cost point ever evaluated.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from autopilot.tuning.es_result import BatchCost, EsError, EsIteration, EsResult, IterationCallback, evaluate
from autopilot.tuning.gain_space import GainSpace


@dataclass(frozen=True, slots=True)
class PerturbationEsConfig:
    """Dither amplitude ``a``, integrator gain ``gamma`` and high-pass coefficient ``h`` (normalised units)."""

    iterations: int = 200
    restarts: int = 5
    dither_amplitude: float = 0.05
    integrator_gain: float = 0.7
    highpass_coeff: float = 0.5
    frequencies_rad: tuple[float, ...] | None = None  # per parameter; default: see dither_frequencies
    log_cost: bool = False
    max_step: float = 0.05  # bound on |zhat_{k+1} - zhat_k| per parameter and iteration
    cost_epsilon: float = 1e-12
    seed: int = 0

    def __post_init__(self) -> None:
        if self.iterations < 0 or self.restarts < 1:
            raise EsError(f"need iterations >= 0 and restarts >= 1, got {self.iterations}, {self.restarts}")
        if not (0.0 < self.dither_amplitude < 0.5):
            raise EsError(f"dither_amplitude {self.dither_amplitude} must be in (0, 0.5)")
        if not (0.0 < self.highpass_coeff < 1.0):
            raise EsError(f"highpass_coeff {self.highpass_coeff} must be in (0, 1)")
        if self.integrator_gain <= 0.0:
            raise EsError("integrator_gain must be positive")


def _min_separation(w: np.ndarray) -> float:
    """Smallest distance (rad) between two frequencies, or a frequency and a folded w_i +/- w_j or 2 w_i."""
    if len(w) < 2:
        return np.inf
    off_diag = ~np.eye(len(w), dtype=bool)
    combos = np.concatenate([(w[:, None] + w[None, :]).ravel(), (w[:, None] - w[None, :])[off_diag]])
    folded = np.abs(np.angle(np.exp(1j * combos)))  # alias into [0, pi]
    pairwise = np.abs(w[:, None] - w[None, :])[off_diag]
    return float(min(np.min(np.abs(folded[:, None] - w[None, :])), np.min(pairwise)))


def dither_frequencies(dim: int) -> np.ndarray:
    """Default dither frequencies (rad/iteration), distinct, in (0, pi), chosen greedily on a grid.

    Each new frequency maximises the smallest distance between any frequency and any other frequency,
    any folded sum or difference of two, or any folded double, so the second-order terms of the cost
    (a^2 sin(w_i k) sin(w_j k)) do not demodulate into a first-order gradient estimate.
    """
    grid = np.pi * np.linspace(0.2, 0.95, 301)
    chosen = [grid[-1]]
    while len(chosen) < dim:
        scores = [_min_separation(np.array([*chosen, c])) for c in grid]
        chosen.append(grid[int(np.argmax(scores))])
    return np.array(chosen[:dim])


def perturbation_es(
    cost: BatchCost,
    space: GainSpace,
    config: PerturbationEsConfig = PerturbationEsConfig(),
    initial_gains: np.ndarray | None = None,
    on_iteration: IterationCallback | None = None,
) -> EsResult:
    """Minimise ``cost`` over ``space`` with dither/high-pass/demodulation/integrator ES.

    ``j_history[i, r]`` is the cost measured at iteration ``i`` (at the dithered point) for loop ``r``;
    ``k_history[i, r]`` is the estimate ``zhat`` in gain units.
    """
    d = space.dim
    r = config.restarts
    omega = np.asarray(config.frequencies_rad, float) if config.frequencies_rad is not None else dither_frequencies(d)
    if omega.shape != (d,):
        raise EsError(f"{omega.shape[0]} dither frequencies for {d} parameters")
    rng = np.random.default_rng(config.seed)
    zhat = space.sample_unit(rng, r, margin=config.dither_amplitude + 0.05)
    if initial_gains is not None:
        k0 = np.atleast_2d(np.asarray(initial_gains, dtype=np.float64))
        if k0.shape[1] != d or k0.shape[0] > r:
            raise EsError(f"initial_gains of shape {k0.shape} do not fit {r} loops of dimension {d}")
        zhat[: k0.shape[0]] = space.to_unit(k0)

    a, h, gamma = config.dither_amplitude, config.highpass_coeff, config.integrator_gain
    lowpass = np.zeros(r)
    scale = np.ones(r)
    max_step = config.max_step
    best_k = np.empty(d)
    best_j = np.inf
    best_restart = 0
    j_hist: list[np.ndarray] = []
    k_hist: list[np.ndarray] = []
    z = np.empty((r, d))
    for k in range(config.iterations + 1):
        s = np.sin(omega * k)
        np.add(zhat, a * s, out=z)
        np.clip(z, 0.0, 1.0, out=z)
        gains = space.to_gains(z)
        j = evaluate(cost, gains)
        i_min = int(np.argmin(j))
        if j[i_min] < best_j:
            best_j, best_restart = float(j[i_min]), i_min
            best_k[:] = gains[i_min]
        j_hist.append(j.copy())
        k_hist.append(space.to_gains(zhat))
        finite = np.isfinite(j)
        if k == 0:
            scale[:] = np.where(finite, np.abs(j), 1.0) + config.cost_epsilon
        y = np.log(j + config.cost_epsilon) if config.log_cost else j / scale
        if k == 0:
            lowpass[:] = np.where(finite, y, 0.0)
        eta = np.where(finite, y - lowpass, 0.0)
        lowpass += h * eta
        zhat -= np.clip(gamma * eta[:, None] * s[None, :], -max_step, max_step)
        # a diverged rollout gives no gradient information: step back towards the box centre instead
        zhat[~finite] += 0.5 * gamma * (0.5 - zhat[~finite])
        np.clip(zhat, 0.0, 1.0, out=zhat)
        if on_iteration is not None:
            on_iteration(EsIteration(k, j.copy(), best_j, (k + 1) * r))

    if not np.isfinite(best_j):
        raise EsError("every evaluated gain vector gave a non-finite cost (all rollouts diverged)")
    return EsResult(
        method="perturbation",
        names=space.names,
        k_best=best_k.copy(),
        j_best=best_j,
        best_restart=best_restart,
        j_history=np.asarray(j_hist),
        k_history=np.asarray(k_hist),
        n_evaluations=(config.iterations + 1) * r,
        n_batches=config.iterations + 1,
    )
