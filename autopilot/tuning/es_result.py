"""What an extremum-seeking run returns and reports per iteration (SPEC §6.3 outputs)."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

#: A batched cost: gains ``K`` of shape ``(m, d)`` to costs ``J`` of shape ``(m,)`` (one rollout per row).
#: Non-finite costs are treated as +inf (a diverged rollout never wins).
BatchCost = Callable[[np.ndarray], np.ndarray]


class EsError(RuntimeError):
    """An extremum-seeking run could not proceed (bad configuration or a cost of the wrong shape)."""


@dataclass(frozen=True, slots=True)
class EsIteration:
    """Progress after one iteration: the accepted cost of every restart and the best cost seen so far."""

    iteration: int
    j_restarts: np.ndarray  # (restarts,)
    j_best: float
    n_evaluations: int


IterationCallback = Callable[[EsIteration], None]


@dataclass(frozen=True, slots=True)
class EsResult:
    """Outcome of one ES run.

    ``j_history[i, r]`` is the cost of restart ``r``'s current estimate after iteration ``i`` (row 0 is the
    start): this is the paper's convergence plot. ``k_history[i, r]`` holds the matching gains.
    ``k_best`` / ``j_best`` are the best evaluated point over all restarts and probes ("best kept").
    """

    method: str
    names: tuple[str, ...]
    k_best: np.ndarray  # (d,)
    j_best: float
    best_restart: int
    j_history: np.ndarray  # (iterations + 1, restarts)
    k_history: np.ndarray  # (iterations + 1, restarts, d)
    n_evaluations: int
    n_batches: int

    @property
    def j_initial(self) -> float:
        """Best cost among the starting points."""
        return float(np.min(self.j_history[0]))

    def best_curve(self) -> np.ndarray:
        """Per iteration, the accepted cost of the restart that found the best point (``(iterations + 1,)``)."""
        return self.j_history[:, self.best_restart].copy()


def evaluate(cost: BatchCost, gains: np.ndarray) -> np.ndarray:
    """Call ``cost`` on ``gains`` (m, d), check the shape, and map NaN/inf to +inf."""
    j = np.asarray(cost(gains), dtype=np.float64).reshape(-1)
    if j.shape != (gains.shape[0],):
        raise EsError(f"cost returned shape {j.shape} for {gains.shape[0]} gain vectors")
    return np.where(np.isfinite(j), j, np.inf)
