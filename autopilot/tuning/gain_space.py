"""The box of admissible gains and its normalised coordinates (SPEC §6.3: "positive and bounded gains").

Extremum seeking works in normalised coordinates ``z`` in ``[0, 1]^d`` so that one step size and one
probe width fit gains of very different magnitude (k_i ~ 0.1 beside k_p ~ 8). With ``log_scale`` the map
is logarithmic, ``K = lower * (upper / lower) ** z``, which suits strictly positive gains spanning decades;
otherwise it is affine, ``K = lower + z * (upper - lower)``. Projection is clipping ``z`` to the unit box,
so every gain handed to a cost function lies in ``[lower, upper]``.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np


class GainSpaceError(ValueError):
    """The bounds of a gain space are inconsistent; the message names the offending entry."""


@dataclass(frozen=True, slots=True)
class GainSpace:
    """Named gains with inclusive bounds ``lower[j] <= K[j] <= upper[j]``.

    ``names`` label the parameter vector (e.g. ``"roll.k1.kp"``); arrays are float64 of shape ``(d,)``.
    """

    names: tuple[str, ...]
    lower: np.ndarray
    upper: np.ndarray
    log_scale: bool = True
    _span: np.ndarray = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        lower = np.asarray(self.lower, dtype=np.float64).reshape(-1).copy()
        upper = np.asarray(self.upper, dtype=np.float64).reshape(-1).copy()
        d = len(self.names)
        if lower.shape != (d,) or upper.shape != (d,):
            raise GainSpaceError(f"{d} names but bounds of shape {lower.shape} and {upper.shape}")
        for j, name in enumerate(self.names):
            lo, hi = lower[j], upper[j]
            if not (np.isfinite(lo) and np.isfinite(hi) and lo < hi):
                raise GainSpaceError(f"{name}: bounds [{lo}, {hi}] must be finite with lower < upper")
            if self.log_scale and lo <= 0.0:
                raise GainSpaceError(f"{name}: log-scaled gains need a positive lower bound, got {lo}")
        lower.flags.writeable = False
        upper.flags.writeable = False
        span = np.log(upper / lower) if self.log_scale else upper - lower
        span.flags.writeable = False
        object.__setattr__(self, "lower", lower)
        object.__setattr__(self, "upper", upper)
        object.__setattr__(self, "_span", span)

    @classmethod
    def from_bounds(
        cls, names: Sequence[str], lower: Sequence[float], upper: Sequence[float], log_scale: bool = True
    ) -> GainSpace:
        return cls(tuple(names), np.asarray(lower, float), np.asarray(upper, float), log_scale)

    @property
    def dim(self) -> int:
        return len(self.names)

    def to_gains(self, z: np.ndarray) -> np.ndarray:
        """Gains ``K`` (..., d) for normalised coordinates ``z`` (..., d), after projection onto the box."""
        zc = np.clip(z, 0.0, 1.0)
        gains = self.lower * np.exp(zc * self._span) if self.log_scale else self.lower + zc * self._span
        return np.clip(gains, self.lower, self.upper, out=gains)  # rounding at z = 1 must not leave the box

    def to_unit(self, gains: np.ndarray) -> np.ndarray:
        """Normalised coordinates ``z`` (..., d) of gains (..., d), projected onto ``[0, 1]^d``."""
        k = np.clip(np.asarray(gains, dtype=np.float64), self.lower, self.upper)
        z = np.log(k / self.lower) / self._span if self.log_scale else (k - self.lower) / self._span
        return np.clip(z, 0.0, 1.0)

    def project(self, gains: np.ndarray) -> np.ndarray:
        """The nearest admissible gains (component-wise clip to the bounds)."""
        return np.clip(np.asarray(gains, dtype=np.float64), self.lower, self.upper)

    def sample_unit(self, rng: np.random.Generator, m: int, margin: float = 0.1) -> np.ndarray:
        """``m`` random starting points in normalised coordinates, uniform in ``[margin, 1 - margin]^d``."""
        return rng.uniform(margin, 1.0 - margin, size=(m, self.dim))

    def as_dict(self, gains: np.ndarray) -> dict[str, float]:
        """``{name: value}`` for one gain vector of shape (d,)."""
        return {name: float(v) for name, v in zip(self.names, np.asarray(gains).reshape(-1), strict=True)}
