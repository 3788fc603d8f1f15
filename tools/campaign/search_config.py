"""The ``search:`` and ``estimate:`` keys of a campaign file, validated with FILE:LINE errors (SPEC §14)::

    search:
      objective: {name: tracking, bound_m: 1.5}   # a margin from the row (tools.campaign.objectives)
      method: cmaes                               # cmaes (continuous inputs) or cem (continuous and choice)
      inputs: [world.wind.north_m_s, world.wind.gust_m_s]   # default: every uniform and choice input
      popsize: 8                                  # cmaes: flights per generation (default 4 + 3 ln n, to x4)
      sigma0: 0.3                                 # cmaes: initial step, in units of each input's range
      batch: 40                                   # cem: flights per batch
      elite_frac: 0.1                             # cem: the fraction refitted to
    estimate:                                     # quadsitl campaign estimate (cross-entropy importance sampling)
      rho: 0.1                                    # the quantile of each level
      level_batch: 100                            # flights per level
      final: 200                                  # flights of the final importance-sampling batch
      max_levels: 8
      components: 3                               # the proposal's most mixture components (failure modes)

A search flies at most ``cases`` flights (``--budget`` overrides).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from mavlink_bridge.contract.source_lines import did_you_mean
from tools.campaign.objectives import Objective, parse_objective

Fail = Callable[[tuple[str, ...], str, str], Exception]
METHODS = ("cmaes", "cem")
SEARCH_KEYS = ("objective", "method", "inputs", "popsize", "sigma0", "batch", "elite_frac")
ESTIMATE_KEYS = ("rho", "level_batch", "final", "max_levels", "components")


@dataclass(frozen=True)
class SearchConfig:
    """``search:``: the objective, the method and its options."""

    objective: Objective
    method: str
    inputs: tuple[str, ...] = ()
    popsize: int | None = None
    sigma0: float = 0.3
    batch: int = 40
    elite_frac: float = 0.1


@dataclass(frozen=True)
class EstimateConfig:
    """``estimate:``: the cross-entropy levels and the final importance-sampling batch (the fields are
    :func:`~tools.campaign.estimate.ce_is`'s keyword arguments)."""

    rho: float = 0.1
    level_batch: int = 100
    final: int = 200
    max_levels: int = 8
    components: int = 3


def parse_search(raw: Any, vary: tuple[tuple[str, Any], ...], fail: Fail) -> SearchConfig:
    """``search:`` checked against the campaign's ``vary`` entries."""
    node = ("search",)
    if not isinstance(raw, dict):
        raise fail(node, f"expected a mapping, got {raw!r}", "search: {objective: clearance, method: cmaes}")
    for key in raw:
        if key not in SEARCH_KEYS:
            raise fail((*node, str(key)), "unknown key", did_you_mean(key, SEARCH_KEYS))
    for key in ("objective", "method"):
        if key not in raw:
            raise fail(node, f"missing '{key}'", "search: {objective: clearance, method: cmaes}")
    method = raw["method"]
    if method not in METHODS:
        raise fail((*node, "method"), f"unknown method {method!r}", did_you_mean(method, METHODS))
    kinds = {key: dist.kind for key, dist in vary}
    inputs = raw.get("inputs", [])
    if not isinstance(inputs, list) or not all(isinstance(k, str) for k in inputs):
        raise fail((*node, "inputs"), f"expected a list of vary keys, got {inputs!r}", "inputs: [world.wind.gust_m_s]")
    for key in inputs:
        if key not in kinds:
            raise fail((*node, "inputs"), f"{key!r} is not a vary entry", did_you_mean(key, kinds))
        if kinds[key] == "randint":
            raise fail((*node, "inputs"), f"{key} is a randint (a seed: drawn per case)", "search uniform or choice")
    searched = [k for k in inputs] or [k for k, kind in kinds.items() if kind in ("uniform", "choice")]
    if not searched:
        raise fail(("vary",), "nothing to search (no uniform or choice input)", "vary: {world.wind.gust_m_s: ...}")
    choices = [k for k in searched if kinds[k] == "choice"]
    if method == "cmaes" and choices:
        raise fail(
            (*node, "method"),
            f"cmaes searches continuous inputs, {choices[0]} is a choice",
            "method: cem, or list the uniform ones in search.inputs",
        )
    return SearchConfig(
        objective=parse_objective(raw["objective"], fail),
        method=method,
        inputs=tuple(inputs),
        popsize=_int(raw, "popsize", None, 2, fail) if "popsize" in raw else None,
        sigma0=_num(raw, "sigma0", 0.3, 0.01, 1.0, fail),
        batch=_int(raw, "batch", 40, 4, fail) or 40,
        elite_frac=_num(raw, "elite_frac", 0.1, 0.01, 0.5, fail),
    )


def parse_estimate(raw: Any, fail: Fail) -> EstimateConfig:
    """``estimate:`` (every key optional)."""
    raw = {} if raw is None else raw
    if not isinstance(raw, dict):
        raise fail(("estimate",), f"expected a mapping, got {raw!r}", "estimate: {rho: 0.1, level_batch: 100}")
    for key in raw:
        if key not in ESTIMATE_KEYS:
            raise fail(("estimate", str(key)), "unknown key", did_you_mean(key, ESTIMATE_KEYS))
    return EstimateConfig(
        rho=_num(raw, "rho", 0.1, 0.01, 0.5, fail, where="estimate"),
        level_batch=_int(raw, "level_batch", 100, 10, fail, where="estimate") or 100,
        final=_int(raw, "final", 200, 10, fail, where="estimate") or 200,
        max_levels=_int(raw, "max_levels", 8, 1, fail, where="estimate") or 8,
        components=_int(raw, "components", 3, 1, fail, where="estimate") or 3,
    )


def _int(raw: dict, key: str, default: int | None, low: int, fail: Fail, where: str = "search") -> int | None:
    value = raw.get(key, default)
    if isinstance(value, bool) or not isinstance(value, int) or value < low:
        raise fail((where, key), f"expected an integer >= {low}, got {value!r}", f"{key}: {default or low}")
    return value


def _num(raw: dict, key: str, default: float, low: float, high: float, fail: Fail, where: str = "search") -> float:
    value = raw.get(key, default)
    ok = isinstance(value, int | float) and not isinstance(value, bool) and math.isfinite(value)
    if not ok or not low <= value <= high:
        raise fail((where, key), f"expected a number in [{low:g}, {high:g}], got {value!r}", f"{key}: {default:g}")
    return float(value)
