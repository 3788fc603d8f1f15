"""The nonlinear variable gain k(s) of the NLVG-PID (SPEC §6.1, paper eqs. 4-9).

Default ``raised_cosine`` (SPEC §6.1, continuous and monotone from k1 to k2)::

    k(s) = k1                                           |s| <  δ1
    k(s) = k1 + A·(1 − cos(π·(|s| − δ1)/(δ2 − δ1)))     δ1 ≤ |s| ≤ δ2,   A = (k2 − k1)/2
    k(s) = k2                                           |s| >  δ2

``paper_literal`` is eq. 5 exactly as printed: ``k1 − A·cos(2π/(δ2−δ1)·|s| − δ1) + A`` inside
[δ1, δ2] and k1 + 2A above. It is ≈ k1 at δ2 and then jumps to k2 (kept to show the typo).

``gain_scalar`` is the one implementation (a numba kernel, also called from the cascade
kernel); ``variable_gain`` broadcasts it over arrays.
"""

from __future__ import annotations

import math
from enum import IntEnum

import numpy as np
from numba import njit


class GainVariant(IntEnum):
    """Shape of k(s) between δ1 and δ2."""

    RAISED_COSINE = 0
    PAPER_LITERAL = 1

    @classmethod
    def parse(cls, name: str | GainVariant) -> GainVariant:
        """``"raised_cosine"`` / ``"paper_literal"`` (or the enum) → enum; ValueError names the choices."""
        if isinstance(name, GainVariant):
            return name
        try:
            return cls[str(name).upper()]
        except KeyError:
            raise ValueError(f"variant {name!r} is not one of 'raised_cosine', 'paper_literal'") from None


@njit(cache=True, inline="always")
def gain_scalar(s: float, k1: float, k2: float, delta1: float, delta2: float, variant: int) -> float:
    """k(|s|) for one scalar (SPEC §6.1); ``variant`` is a ``GainVariant`` value."""
    a = abs(s)
    if a < delta1:
        return k1
    if a > delta2:
        return k2
    amp = 0.5 * (k2 - k1)
    if variant == 1:
        return k1 - amp * math.cos(2.0 * math.pi / (delta2 - delta1) * a - delta1) + amp
    return k1 + amp * (1.0 - math.cos(math.pi * (a - delta1) / (delta2 - delta1)))


@njit(cache=True)
def _gain_flat(s, k1, k2, d1, d2, variant, out):  # pragma: no cover - numba kernel
    for i in range(s.shape[0]):
        out[i] = gain_scalar(s[i], k1[i], k2[i], d1[i], d2[i], variant)


def variable_gain(
    s: float | np.ndarray,
    k1: float | np.ndarray,
    k2: float | np.ndarray,
    delta1: float | np.ndarray = 0.01,
    delta2: float | np.ndarray = 0.838,
    variant: str | GainVariant = GainVariant.RAISED_COSINE,
) -> np.ndarray:
    """k(s) broadcast over arrays (SPEC §6.1). Requires 0 <= δ1 < δ2 (ValueError otherwise)."""
    v = GainVariant.parse(variant)
    arrays = np.broadcast_arrays(*(np.asarray(x, dtype=np.float64) for x in (s, k1, k2, delta1, delta2)))
    if np.any(arrays[3] < 0.0) or np.any(arrays[4] <= arrays[3]):
        raise ValueError("delta1/delta2 must satisfy 0 <= delta1 < delta2")
    flat = [np.ascontiguousarray(a).ravel() for a in arrays]
    out = np.empty_like(flat[0])
    _gain_flat(*flat, int(v), out)
    return out.reshape(arrays[0].shape)
