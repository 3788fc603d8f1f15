"""Wind: mean plus seeded gusts, one deterministic random stream per vehicle (SPEC §5).

Gusts are a first-order Gauss–Markov (Ornstein–Uhlenbeck) process per NED axis, the
first-order core of the Dryden model, stepped once per physics step with the exact discretisation
``g_{k+1} = a g_k + σ √(1 − a²) n_k``, ``a = exp(−dt/τ)``, ``n_k ~ N(0, 1)``; its stationary
standard deviation is ``σ = gust_m_s``. The wind is held constant within one RK4 step.

Each vehicle owns a SplitMix64 stream (a ``uint64`` state), so vehicle i of a batch and a single
vehicle seeded alike draw the same numbers: batch and single runs agree exactly.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

_GOLDEN = np.uint64(0x9E3779B97F4A7C15)
_MIX1 = np.uint64(0xBF58476D1CE4E5B9)
_MIX2 = np.uint64(0x94D049BB133111EB)
_S30 = np.uint64(30)
_S27 = np.uint64(27)
_S31 = np.uint64(31)
_S11 = np.uint64(11)
_TWO_M53 = 1.0 / 9007199254740992.0


@njit(cache=True, error_model="numpy")
def splitmix64_next(rng_state: np.ndarray, i: int) -> np.uint64:
    """Advance stream ``i`` and return 64 random bits (SplitMix64, Steele et al. 2014)."""
    s = rng_state[i] + _GOLDEN
    rng_state[i] = s
    z = (s ^ (s >> _S30)) * _MIX1
    z = (z ^ (z >> _S27)) * _MIX2
    return z ^ (z >> _S31)


@njit(cache=True, error_model="numpy")
def uniform_open01(rng_state: np.ndarray, i: int) -> float:
    """Uniform in (0, 1) from stream ``i`` (53-bit resolution, never exactly 0)."""
    return (float(splitmix64_next(rng_state, i) >> _S11) + 0.5) * _TWO_M53


@njit(cache=True, error_model="numpy")
def standard_normal(rng_state: np.ndarray, i: int) -> float:
    """N(0, 1) from stream ``i`` (Box–Muller, one sample per two uniforms)."""
    u1 = uniform_open01(rng_state, i)
    u2 = uniform_open01(rng_state, i)
    return math.sqrt(-2.0 * math.log(u1)) * math.cos(2.0 * math.pi * u2)


@njit(cache=True, error_model="numpy")
def gust_step(gust_ned: np.ndarray, rng_state: np.ndarray, i: int, sigma_m_s: float, decay: float) -> None:
    """One Ornstein–Uhlenbeck step of vehicle ``i``'s gust (m/s, NED) in place; ``decay = exp(−dt/τ)``."""
    if sigma_m_s <= 0.0:
        return
    k = sigma_m_s * math.sqrt(1.0 - decay * decay)
    for axis in range(3):
        gust_ned[i, axis] = decay * gust_ned[i, axis] + k * standard_normal(rng_state, i)


def vehicle_stream_seed(seed: int, wind_seed: int) -> np.uint64:
    """Initial SplitMix64 state of one vehicle's stream from the sim seed and the world's wind seed."""
    s = np.array([(int(seed) * 0x2545F4914F6CDD1D + int(wind_seed)) & 0xFFFFFFFFFFFFFFFF], dtype=np.uint64)
    splitmix64_next(s, 0)
    return np.uint64(splitmix64_next(s, 0))
