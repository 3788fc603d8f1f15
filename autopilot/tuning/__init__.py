"""Extremum-seeking gain tuning as pure code over a batched cost (SPEC §6.3, paper section 3.2).

The cost is any callable ``J(K: (m, d)) -> (m,)``; the closed-loop rollouts that define it for the
NLVG-PID cascade live in ``tools/research/experiments/rollout.py`` (tools may compose sim and autopilot).
"""

from autopilot.tuning.es_central import CentralEsConfig, central_es
from autopilot.tuning.es_perturbation import PerturbationEsConfig, dither_frequencies, perturbation_es
from autopilot.tuning.es_result import BatchCost, EsError, EsIteration, EsResult
from autopilot.tuning.gain_space import GainSpace, GainSpaceError

__all__ = [
    "BatchCost",
    "CentralEsConfig",
    "EsError",
    "EsIteration",
    "EsResult",
    "GainSpace",
    "GainSpaceError",
    "PerturbationEsConfig",
    "central_es",
    "dither_frequencies",
    "perturbation_es",
]
