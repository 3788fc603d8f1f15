"""The paper's extremum seeking: central-difference gradient descent with random restarts (SPEC §6.3).

Paper section 3.2, with the misplaced factor 2 of its eq. for the derivative corrected::

    dJ/dK_j ~ (J(K + delta u_j) - J(K - delta u_j)) / (2 delta)        K <- K - alpha grad J

Implementation choices (documented because the paper leaves them open):

* Coordinates are normalised (:class:`~autopilot.tuning.gain_space.GainSpace`, log scale by default) and
  projected onto the unit box after every step, so gains stay positive and bounded.
* Step rule: normalised projected gradient, ``z <- clip(z - alpha * g / |g|)`` where components of ``g``
  that push through an active bound are dropped first, with a backtracking step size that needs
  no extra rollouts. The trial point of iteration ``i`` is evaluated together with its ``2d`` probes; if its
  cost is lower than the current estimate it is accepted and ``alpha`` grows, otherwise it is rejected and
  ``alpha`` shrinks. Each restart's accepted cost therefore never increases. ``normalize_gradient=False``
  gives the paper's plain ``alpha * g`` step (same acceptance test).
* Every iteration evaluates ``restarts * (2d + 1)`` gain vectors in ONE call of the batched cost, so a
  vectorised simulator runs all rollouts of an iteration at once.
* "Best kept": the result is the lowest-cost point evaluated anywhere (centres and probes, all restarts).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from autopilot.tuning.es_result import BatchCost, EsError, EsIteration, EsResult, IterationCallback, evaluate
from autopilot.tuning.gain_space import GainSpace


@dataclass(frozen=True, slots=True)
class CentralEsConfig:
    """Budget and step parameters; widths and steps are in normalised coordinates (unit box)."""

    iterations: int = 20
    restarts: int = 5
    probe_width: float = 0.02  # delta of the central difference
    step_initial: float = 0.15  # alpha at the first iteration
    step_grow: float = 1.5  # alpha multiplier after an accepted step
    step_shrink: float = 0.4  # alpha multiplier after a rejected step
    step_min: float = 1e-3  # stop early when every restart's alpha fell below this
    step_max: float = 0.5
    normalize_gradient: bool = True
    seed: int = 0

    def __post_init__(self) -> None:
        if self.iterations < 0 or self.restarts < 1:
            raise EsError(f"need iterations >= 0 and restarts >= 1, got {self.iterations}, {self.restarts}")
        if not (0.0 < self.probe_width < 0.5):
            raise EsError(f"probe_width {self.probe_width} must be in (0, 0.5) of the normalised box")
        if not (0.0 < self.step_shrink < 1.0 <= self.step_grow):
            raise EsError("need 0 < step_shrink < 1 <= step_grow")
        if not (0.0 < self.step_min <= self.step_initial <= self.step_max):
            raise EsError("need 0 < step_min <= step_initial <= step_max")

    def batch_size(self, dim: int) -> int:
        """Number of gain vectors in each call of the batched cost."""
        return self.restarts * (2 * dim + 1)


def _stencil(z_centre: np.ndarray, width: float) -> tuple[np.ndarray, np.ndarray]:
    """Centre and +/- probes per restart: points (R, 2d+1, d) and the actual probe spans (R, d).

    Probes are clipped to the unit box; the span ``z+ - z-`` used as the denominator accounts for that.
    """
    d = z_centre.shape[1]
    points = np.repeat(z_centre[:, None, :], 2 * d + 1, axis=1)
    idx = np.arange(d)
    plus = np.minimum(z_centre + width, 1.0)
    minus = np.maximum(z_centre - width, 0.0)
    points[:, 1 + idx, idx] = plus
    points[:, 1 + d + idx, idx] = minus
    return points, plus - minus


def _gradient(j_points: np.ndarray, span: np.ndarray) -> np.ndarray:
    """Central-difference gradient (R, d) from costs (R, 2d+1) laid out as [centre, plus..., minus...].

    Infinite costs (diverged rollouts) are capped at ten times the largest finite cost of the batch so a
    probe that diverges pushes the estimate away from it instead of producing NaN.
    """
    finite = j_points[np.isfinite(j_points)]
    cap = 10.0 * float(np.max(np.abs(finite))) + 1.0 if finite.size else 1.0
    jc = np.minimum(j_points, cap)
    d = span.shape[1]
    return (jc[:, 1 : 1 + d] - jc[:, 1 + d :]) / span


def _direction(z: np.ndarray, grad: np.ndarray, normalize: bool) -> np.ndarray:
    """Descent direction: the gradient without components that push through an active bound, normalised."""
    blocked = ((z <= 0.0) & (grad > 0.0)) | ((z >= 1.0) & (grad < 0.0))
    grad = np.where(blocked, 0.0, grad)
    if not normalize:
        return grad
    norm = np.linalg.norm(grad, axis=1, keepdims=True)
    return np.divide(grad, norm, out=np.zeros_like(grad), where=norm > 0.0)


def central_es(
    cost: BatchCost,
    space: GainSpace,
    config: CentralEsConfig = CentralEsConfig(),
    initial_gains: np.ndarray | None = None,
    on_iteration: IterationCallback | None = None,
) -> EsResult:
    """Minimise ``cost`` over ``space`` by central-difference ES with random restarts.

    ``initial_gains`` (k, d) or (d,), optional: the first ``k`` restarts start there (e.g. the paper's
    starting gains); the other restarts start at seeded uniform random points of the normalised box.
    """
    d = space.dim
    r = config.restarts
    rng = np.random.default_rng(config.seed)
    z = space.sample_unit(rng, r)
    if initial_gains is not None:
        k0 = np.atleast_2d(np.asarray(initial_gains, dtype=np.float64))
        if k0.shape[1] != d or k0.shape[0] > r:
            raise EsError(f"initial_gains of shape {k0.shape} do not fit {r} restarts of dimension {d}")
        z[: k0.shape[0]] = space.to_unit(k0)

    best_k = np.empty(d)
    best_j = np.inf
    best_restart = 0
    n_eval = 0

    def run_batch(z_centre: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        nonlocal best_j, best_restart, n_eval
        points, span = _stencil(z_centre, config.probe_width)
        gains = space.to_gains(points.reshape(-1, d))
        j = evaluate(cost, gains).reshape(r, 2 * d + 1)
        n_eval += j.size
        flat = int(np.argmin(j))
        if j.flat[flat] < best_j:
            best_j = float(j.flat[flat])
            best_k[:] = gains[flat]
            best_restart = flat // (2 * d + 1)
        return j, _gradient(j, span)

    j_pts, g_acc = run_batch(z)
    j_acc = j_pts[:, 0].copy()
    alpha = np.full(r, config.step_initial)
    j_hist = [j_acc.copy()]
    k_hist = [space.to_gains(z)]
    n_batches = 1
    if on_iteration is not None:
        on_iteration(EsIteration(0, j_acc.copy(), best_j, n_eval))

    for it in range(1, config.iterations + 1):
        if np.all(alpha < config.step_min):
            break
        z_trial = np.clip(z - alpha[:, None] * _direction(z, g_acc, config.normalize_gradient), 0.0, 1.0)
        j_pts, g_trial = run_batch(z_trial)
        n_batches += 1
        j_trial = j_pts[:, 0]
        accept = j_trial < j_acc
        z = np.where(accept[:, None], z_trial, z)
        g_acc = np.where(accept[:, None], g_trial, g_acc)
        j_acc = np.where(accept, j_trial, j_acc)
        alpha = np.where(accept, np.minimum(alpha * config.step_grow, config.step_max), alpha * config.step_shrink)
        j_hist.append(j_acc.copy())
        k_hist.append(space.to_gains(z))
        if on_iteration is not None:
            on_iteration(EsIteration(it, j_acc.copy(), best_j, n_eval))

    if not np.isfinite(best_j):
        raise EsError("every evaluated gain vector gave a non-finite cost (all rollouts diverged)")
    return EsResult(
        method="central",
        names=space.names,
        k_best=best_k.copy(),
        j_best=best_j,
        best_restart=best_restart,
        j_history=np.asarray(j_hist),
        k_history=np.asarray(k_hist),
        n_evaluations=n_eval,
        n_batches=n_batches,
    )
