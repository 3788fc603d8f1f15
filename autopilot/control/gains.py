"""Gain and limit sets of the cascade (SPEC §6.2), batch-first: every gain may be an array (n,).

Channel order is ``CHANNELS`` = x, y, z (position loop, output m/s²) and roll, pitch, yaw (attitude
loop, output rad/s²). Gains are dimensionless in each loop's normalised time (see ``pid.py``):
position time scale 1 s (so the paper's (5, 0.2, 5) are plain SI gains), attitude time scale 0.15 s.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import asdict, dataclass, fields, replace
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from autopilot.control.gain_schedule import GainVariant
from autopilot.control.pid import N_GAIN_COLS, Schedule

CHANNELS = ("x", "y", "z", "roll", "pitch", "yaw")
POSITION_CHANNELS = CHANNELS[:3]
ATTITUDE_CHANNELS = CHANNELS[3:]
#: the paper's starting gains (K_p, K_i, K_d), section 4
PAPER_POSITION_PID = (5.0, 0.2, 5.0)
PAPER_ATTITUDE_PID = (8.0, 0.1, 5.0)
PAPER_DELTA1 = 0.01
PAPER_DELTA2 = 0.838
GAINS_FILE_FORMAT = "quadsitl.cascade_gains/1"

Gain = float | np.ndarray


def _as_triple(value: Sequence[Gain], name: str) -> tuple[Gain, Gain, Gain]:
    if len(value) != 3:
        raise ValueError(f"{name} must be (kp, ki, kd), got {len(value)} values")
    out = []
    for term, v in zip(("kp", "ki", "kd"), value, strict=True):
        a = np.asarray(v, dtype=np.float64)
        if a.ndim > 1 or not np.all(np.isfinite(a)) or np.any(a < 0.0):
            raise ValueError(f"{name} {term} must be finite, >= 0, scalar or shape (n,), got {v!r}")
        out.append(float(a) if a.ndim == 0 else a)
    return (out[0], out[1], out[2])


@dataclass(frozen=True)
class NlvgGains:
    """One channel: k(s) goes from ``k1`` (|s| < δ1) to ``k2`` (|s| > δ2) for each of (kp, ki, kd).

    Fixed PID when k1 == k2. Each gain (and δ1, δ2) is a float or an array (n,) (one value per vehicle).
    ``variant``: "raised_cosine" | "paper_literal"; ``schedule``: "error" | "per_term" (see pid.py).
    """

    k1: tuple[Gain, Gain, Gain]
    k2: tuple[Gain, Gain, Gain]
    delta1: float = PAPER_DELTA1
    delta2: float = PAPER_DELTA2
    variant: str = "raised_cosine"
    schedule: str = "error"

    def __post_init__(self) -> None:
        object.__setattr__(self, "k1", _as_triple(self.k1, "k1"))
        object.__setattr__(self, "k2", _as_triple(self.k2, "k2"))
        d1, d2 = (np.asarray(d, dtype=np.float64) for d in (self.delta1, self.delta2))
        ok = d1.ndim <= 1 and d2.ndim <= 1 and np.all(np.isfinite(d1)) and np.all(np.isfinite(d2))
        if not (ok and np.all(d1 >= 0.0) and np.all(d1 < d2)):
            raise ValueError(f"need 0 <= delta1 < delta2, got delta1={self.delta1}, delta2={self.delta2}")
        object.__setattr__(self, "delta1", float(d1) if d1.ndim == 0 else d1)
        object.__setattr__(self, "delta2", float(d2) if d2.ndim == 0 else d2)
        GainVariant.parse(self.variant)
        Schedule.parse(self.schedule)

    @classmethod
    def fixed(cls, kp: Gain, ki: Gain, kd: Gain, **kw: Any) -> NlvgGains:
        """A fixed-gain PID (k1 == k2)."""
        return cls(k1=(kp, ki, kd), k2=(kp, ki, kd), **kw)

    @property
    def n(self) -> int:
        """Batch size implied by the gain arrays (1 for scalars)."""
        shapes = (np.shape(g) for g in (*self.k1, *self.k2, self.delta1, self.delta2))
        return int(np.broadcast_shapes(*shapes, (1,))[0])

    def row(self, n: int) -> np.ndarray:
        """Packed gain-table rows (n, N_GAIN_COLS) for the kernels (pid.G_* columns)."""
        out = np.empty((n, N_GAIN_COLS))
        for j, g in enumerate((*self.k1, *self.k2)):
            out[:, j] = g
        out[:, 6] = self.delta1
        out[:, 7] = self.delta2
        out[:, 8] = float(GainVariant.parse(self.variant))
        out[:, 9] = float(Schedule.parse(self.schedule))
        return out

    def to_dict(self) -> dict[str, Any]:
        """Plain YAML-able mapping (scalar gains only)."""
        if self.n != 1 or any(np.ndim(g) for g in (*self.k1, *self.k2, self.delta1, self.delta2)):
            raise ValueError("only a single (scalar) gain set can be written to a file")
        return {
            "k1": [float(g) for g in self.k1],
            "k2": [float(g) for g in self.k2],
            "delta1": float(self.delta1),
            "delta2": float(self.delta2),
            "variant": self.variant,
            "schedule": self.schedule,
        }


@dataclass(frozen=True)
class CascadeGains:
    """The six channels' NLVG gains (position x, y, z; attitude roll, pitch, yaw)."""

    x: NlvgGains
    y: NlvgGains
    z: NlvgGains
    roll: NlvgGains
    pitch: NlvgGains
    yaw: NlvgGains

    @classmethod
    def fixed_pid(
        cls,
        position: tuple[float, float, float] = PAPER_POSITION_PID,
        attitude: tuple[float, float, float] = PAPER_ATTITUDE_PID,
        yaw: tuple[float, float, float] | None = None,
        **kw: Any,
    ) -> CascadeGains:
        """Fixed PID (k1 == k2) on every channel; ``yaw`` defaults to the attitude gains."""
        p = NlvgGains.fixed(*position, **kw)
        a = NlvgGains.fixed(*attitude, **kw)
        return cls(x=p, y=p, z=p, roll=a, pitch=a, yaw=NlvgGains.fixed(*(yaw or attitude), **kw))

    @classmethod
    def paper_default(cls, k1_scale: float = 1.0, k2_scale: float = 1.0, **kw: Any) -> CascadeGains:
        """The paper's starting point: k1 = k1_scale·K, k2 = k2_scale·K with the paper's K and δ1, δ2."""

        def ch(base: tuple[float, float, float]) -> NlvgGains:
            return NlvgGains(k1=tuple(k1_scale * b for b in base), k2=tuple(k2_scale * b for b in base), **kw)

        p, a = ch(PAPER_POSITION_PID), ch(PAPER_ATTITUDE_PID)
        return cls(x=p, y=p, z=p, roll=a, pitch=a, yaw=a)

    def channels(self) -> tuple[NlvgGains, ...]:
        return tuple(getattr(self, c) for c in CHANNELS)

    def with_channels(self, **channels: NlvgGains) -> CascadeGains:
        """A copy with some channels replaced, e.g. ``with_channels(roll=g, pitch=g)``."""
        return replace(self, **channels)

    @property
    def n(self) -> int:
        """Batch size (1 when every gain is a scalar)."""
        return max(c.n for c in self.channels())

    def table(self, n: int) -> np.ndarray:
        """Packed gain table (n, 6, N_GAIN_COLS) for the cascade kernel; ValueError if not broadcastable."""
        if self.n not in (1, n):
            raise ValueError(f"gain batch of {self.n} does not fit {n} vehicles")
        return np.ascontiguousarray(np.stack([c.row(n) for c in self.channels()], axis=1))

    @staticmethod
    def stacked(items: Sequence[CascadeGains]) -> CascadeGains:
        """One batch (gains and δ as arrays (n,)) from n single gain sets; variant and schedule must agree."""
        if not items:
            raise ValueError("stacked() needs at least one gain set")
        out = {}
        for c in CHANNELS:
            chans = [getattr(g, c) for g in items]
            first = chans[0]
            for other in chans[1:]:
                if (other.variant, other.schedule) != (first.variant, first.schedule):
                    raise ValueError(f"channel {c}: variant/schedule differ within the batch")

            def col(get, chans=chans) -> np.ndarray:
                return np.array([np.broadcast_to(get(ch), ()) for ch in chans], dtype=np.float64)

            k1 = tuple(col(lambda ch, t=t: ch.k1[t]) for t in range(3))
            k2 = tuple(col(lambda ch, t=t: ch.k2[t]) for t in range(3))
            d1, d2 = col(lambda ch: ch.delta1), col(lambda ch: ch.delta2)
            same_d = bool(np.all(d1 == d1[0]) and np.all(d2 == d2[0]))
            out[c] = replace(
                first, k1=k1, k2=k2, delta1=float(d1[0]) if same_d else d1, delta2=float(d2[0]) if same_d else d2
            )
        return CascadeGains(**out)

    def tiled(self, reps: int) -> CascadeGains:
        """The batch repeated ``reps`` times (vehicle ``b·n + i`` flies gain set ``i``), e.g. one block per seed."""
        n = self.n

        def tile(g: Gain) -> Gain:
            return g if np.ndim(g) == 0 else np.tile(np.broadcast_to(g, (n,)), reps)

        return CascadeGains(
            **{
                c: replace(
                    ch,
                    k1=tuple(tile(g) for g in ch.k1),
                    k2=tuple(tile(g) for g in ch.k2),
                    delta1=tile(ch.delta1),
                    delta2=tile(ch.delta2),
                )
                for c, ch in zip(CHANNELS, self.channels(), strict=True)
            }
        )

    def select(self, i: int) -> CascadeGains:
        """Gain set of vehicle i of a batch, as scalars."""

        def pick(g: Gain) -> float:
            return float(np.broadcast_to(g, (self.n,))[i])

        return CascadeGains(
            **{
                c: replace(
                    ch,
                    k1=tuple(pick(g) for g in ch.k1),
                    k2=tuple(pick(g) for g in ch.k2),
                    delta1=pick(ch.delta1),
                    delta2=pick(ch.delta2),
                )
                for c, ch in zip(CHANNELS, self.channels(), strict=True)
            }
        )

    def to_dict(self, provenance: dict[str, Any] | None = None) -> dict[str, Any]:
        """The gain file mapping; ``provenance`` (which command and seed wrote it) is kept beside the channels."""
        out: dict[str, Any] = {"format": GAINS_FILE_FORMAT}
        if provenance:
            out["provenance"] = dict(provenance)
        out["channels"] = {c: getattr(self, c).to_dict() for c in CHANNELS}
        return out

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> CascadeGains:
        if not isinstance(data, dict) or data.get("format") != GAINS_FILE_FORMAT:
            raise ValueError(f"not a gain set: expected format: {GAINS_FILE_FORMAT}")
        unknown = set(data) - {"format", "provenance", "channels"}
        if unknown:
            raise ValueError(f"gain set: unknown keys {sorted(unknown)} (allowed: format, provenance, channels)")
        if not isinstance(data.get("provenance", {}), dict):
            raise ValueError("gain set: provenance must be a mapping")
        chans = data.get("channels")
        if not isinstance(chans, dict) or sorted(chans) != sorted(CHANNELS):
            raise ValueError(f"gain set must have channels {list(CHANNELS)}")
        allowed = {f.name for f in fields(NlvgGains)}
        out = {}
        for c in CHANNELS:
            ch = chans[c]
            if not isinstance(ch, dict) or set(ch) - allowed or not {"k1", "k2"} <= set(ch):
                raise ValueError(f"channel {c}: expected keys k1, k2 and optionally {sorted(allowed - {'k1', 'k2'})}")
            try:
                out[c] = NlvgGains(**ch)
            except (TypeError, ValueError) as exc:
                raise ValueError(f"channel {c}: {exc}") from None
        return cls(**out)

    def to_yaml(self, path: str | Path, provenance: dict[str, Any] | None = None) -> None:
        Path(path).write_text(yaml.safe_dump(self.to_dict(provenance), sort_keys=False, allow_unicode=True))

    @classmethod
    def from_yaml(cls, path: str | Path) -> CascadeGains:
        try:
            return cls.from_dict(yaml.safe_load(Path(path).read_text()))
        except (OSError, yaml.YAMLError, ValueError) as exc:
            raise ValueError(f"{path}: {' '.join(str(exc).split())}") from None


@dataclass(frozen=True)
class CascadeLimits:
    """Limits and structure constants of the cascade (normalised: accelerations, angular accelerations).

    ``att_time_scale_s`` = 0.15 s puts the paper's attitude gains (8, 0.1, 5) at a closed-loop natural
    frequency ≈ √8/0.15 ≈ 19 rad/s, ζ ≈ 0.88, well above the position loop's (5, 0.2, 5) at 1 s scale
    (poles ≈ −1.4, −3.6 rad/s).
    """

    tilt_max_rad: float = math.radians(35.0)
    acc_xy_max_m_s2: float = 8.0
    acc_up_max_m_s2: float = 6.0
    acc_down_max_m_s2: float = 6.0
    ang_acc_max_rp_rad_s2: float = 150.0
    ang_acc_max_yaw_rad_s2: float = 40.0
    pos_i_max_m_s2: float = 5.0  # covers a ±30 % mass mismatch (0.3 g / 0.7 ≈ 4.2 m/s²)
    att_i_max_rad_s2: float = 20.0
    pos_time_scale_s: float = 1.0
    att_time_scale_s: float = 0.15
    gyroscopic: bool = True

    def __post_init__(self) -> None:
        for f in fields(self):
            if f.name == "gyroscopic":
                continue
            v = getattr(self, f.name)
            if not (math.isfinite(v) and v > 0.0):
                raise ValueError(f"{f.name} must be a finite positive number, got {v!r}")
        if self.tilt_max_rad >= math.radians(89.0):
            raise ValueError("tilt_max_rad must be below 89°")
        if self.acc_down_max_m_s2 >= 9.80665:
            raise ValueError("acc_down_max_m_s2 must be below g (thrust must stay positive)")

    def as_array(self) -> np.ndarray:
        """Packed limits (cascade.L_* order) for the kernels."""
        return np.array([float(v) for v in asdict(self).values()], dtype=np.float64)
