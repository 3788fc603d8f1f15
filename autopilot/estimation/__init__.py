"""State estimation (SPEC §5b): the estimator seam, the estimators, and ``make_estimator``.

Nothing else in the autopilot knows which estimator runs: it sees :class:`VehicleState` and
:class:`EstimatorStatus` only.
"""

from __future__ import annotations

from autopilot.estimation.ekf import EkfEstimator, EkfParams
from autopilot.estimation.state import Estimator, EstimatorStatus, FrameLike, VehicleState
from autopilot.estimation.truth import TruthEstimator

#: ``--estimator`` choices; the first is the default of ``quadsitl autopilot`` / ``up``.
ESTIMATORS = {"ekf": EkfEstimator, "truth": TruthEstimator}
#: The default estimator of the CLI, ``make run`` and the SITL tests.
DEFAULT_ESTIMATOR = "ekf"


def make_estimator(name: str) -> Estimator:
    """The estimator called ``name`` (``--estimator``); ValueError names the choices."""
    try:
        return ESTIMATORS[name]()
    except KeyError:
        raise ValueError(f"unknown estimator {name!r}; choose one of {sorted(ESTIMATORS)}") from None


__all__ = [
    "DEFAULT_ESTIMATOR",
    "ESTIMATORS",
    "EkfEstimator",
    "EkfParams",
    "Estimator",
    "EstimatorStatus",
    "FrameLike",
    "TruthEstimator",
    "VehicleState",
    "make_estimator",
]
