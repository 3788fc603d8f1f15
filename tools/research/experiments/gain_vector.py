"""Map an ES parameter vector to cascade gains: which channels, k1/k2 or fixed PID (SPEC §6.3).

An NLVG level learns 6 numbers per tuned gain set, ``(k1_p, k1_i, k1_d, k2_p, k2_i, k2_d)``, plus
``(δ1, δ2)`` of eqs. 4-9 when ``delta_bounds`` is given; the fixed-PID baseline learns 3, ``(k_p, k_i, k_d)``
with ``k1 == k2``. One gain set may be shared by several channels (e.g. x and y) or each channel may get
its own. All other channels keep the base gains. δ bounds must not overlap (δ1's upper < δ2's lower), so
every point of the box is a valid schedule.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace
from enum import StrEnum

import numpy as np

from autopilot.control.gains import CHANNELS, CascadeGains, NlvgGains
from autopilot.tuning import GainSpace

TERMS = ("kp", "ki", "kd")


class Structure(StrEnum):
    """What ES learns per gain set: both NLVG bounds, or one fixed PID (the paper's baseline)."""

    NLVG = "nlvg"
    PID = "pid"


@dataclass(frozen=True, slots=True)
class GainParametrisation:
    """ES vector layout: for each group of channels sharing gains, the learned terms in a fixed order.

    ``bounds[term] = (lower, upper)`` applies to k1 and k2 alike (positive, so the space is log-scaled).
    ``delta_bounds``: ``{"delta1": (lo, hi), "delta2": (lo, hi)}`` (m or rad) to learn δ1, δ2 (NLVG only).
    """

    base: CascadeGains
    groups: tuple[tuple[str, ...], ...]
    structure: Structure
    bounds: dict[str, tuple[float, float]]
    delta_bounds: dict[str, tuple[float, float]] | None = None

    def __post_init__(self) -> None:
        for group in self.groups:
            for ch in group:
                if ch not in CHANNELS:
                    raise ValueError(f"unknown channel {ch!r}; channels are {CHANNELS}")
        if sorted(self.bounds) != sorted(TERMS):
            raise ValueError(f"bounds need exactly the terms {TERMS}")
        if self.delta_bounds is not None:
            if self.structure is not Structure.NLVG:
                raise ValueError("learning delta1/delta2 needs the nlvg structure")
            if sorted(self.delta_bounds) != ["delta1", "delta2"]:
                raise ValueError("delta_bounds needs exactly delta1: [lo, hi] and delta2: [lo, hi]")
            (l1, h1), (l2, h2) = self.delta_bounds["delta1"], self.delta_bounds["delta2"]
            if not (0.0 < l1 < h1 < l2 < h2):
                raise ValueError(
                    f"delta_bounds must satisfy 0 < delta1 lo < hi < delta2 lo < hi, got {self.delta_bounds}"
                )

    @property
    def learns_deltas(self) -> bool:
        return self.delta_bounds is not None

    @property
    def per_group(self) -> int:
        return (6 if self.structure is Structure.NLVG else 3) + (2 if self.learns_deltas else 0)

    @property
    def names(self) -> tuple[str, ...]:
        out = []
        for group in self.groups:
            label = "+".join(group)
            levels = ("k1", "k2") if self.structure is Structure.NLVG else ("k",)
            out += [f"{label}.{lvl}.{t}" for lvl in levels for t in TERMS]
            if self.learns_deltas:
                out += [f"{label}.delta1", f"{label}.delta2"]
        return tuple(out)

    def space(self) -> GainSpace:
        lower: list[float] = []
        upper: list[float] = []
        for _ in self.groups:
            for _lvl in range(2 if self.structure is Structure.NLVG else 1):
                lower += [self.bounds[t][0] for t in TERMS]
                upper += [self.bounds[t][1] for t in TERMS]
            if self.delta_bounds is not None:
                lower += [self.delta_bounds["delta1"][0], self.delta_bounds["delta2"][0]]
                upper += [self.delta_bounds["delta1"][1], self.delta_bounds["delta2"][1]]
        return GainSpace.from_bounds(self.names, lower, upper, log_scale=True)

    def vector(self, gains: CascadeGains) -> np.ndarray:
        """The parameter vector (d,) of a single gain set (first channel of each group; PID uses k1)."""
        out: list[float] = []
        for group in self.groups:
            ch: NlvgGains = getattr(gains, group[0])
            out += [float(v) for v in ch.k1]
            if self.structure is Structure.NLVG:
                out += [float(v) for v in ch.k2]
            if self.delta_bounds is not None:  # clipped into the box (e.g. a PID's paper δ as a warm start)
                for key, d in (("delta1", ch.delta1), ("delta2", ch.delta2)):
                    lo, hi = self.delta_bounds[key]
                    out.append(min(max(float(np.broadcast_to(d, ())), lo), hi))
        return np.asarray(out)

    def gains(self, k: np.ndarray) -> CascadeGains:
        """Batched cascade gains for parameter vectors ``k`` (m, d) (gain arrays of shape (m,))."""
        k = np.atleast_2d(np.asarray(k, dtype=np.float64))
        m = k.shape[0]
        channels: dict[str, NlvgGains] = {}
        for c in CHANNELS:
            base: NlvgGains = getattr(self.base, c)
            channels[c] = replace(
                base,
                k1=tuple(np.full(m, float(np.broadcast_to(g, ()))) for g in base.k1),
                k2=tuple(np.full(m, float(np.broadcast_to(g, ()))) for g in base.k2),
            )
        for i, group in enumerate(self.groups):
            cols = k[:, i * self.per_group : (i + 1) * self.per_group]
            k1 = tuple(cols[:, j].copy() for j in range(3))
            k2 = tuple(cols[:, 3 + j].copy() for j in range(3)) if self.structure is Structure.NLVG else k1
            deltas = {}
            if self.learns_deltas:
                deltas = {"delta1": cols[:, -2].copy(), "delta2": cols[:, -1].copy()}
            for c in group:
                channels[c] = replace(channels[c], k1=k1, k2=k2, **deltas)
        return CascadeGains(**channels)

    def single(self, k: Sequence[float] | np.ndarray) -> CascadeGains:
        """Scalar cascade gains for one parameter vector (d,), e.g. to write the gain file."""
        return self.gains(np.asarray(k, dtype=np.float64)[None, :]).select(0)
