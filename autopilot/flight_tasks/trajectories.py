"""Parametric reference trajectories of SPEC §6.5 (paper section 4) with velocity, acceleration and yaw.

Each trajectory is a frozen dataclass; ``sample(t_s)`` accepts a scalar or an array of times and returns a
:class:`RefSample` (NED, metres; ``down = −alt``); ``waypoints(spacing_m)`` expands it into
``(north_m, east_m, alt_m)`` points relative to home for a mission upload. ``make_trajectory(type,
**params)`` builds one by name with validated parameters (ValueError naming the parameter).

Continuous routes are a path P(s) in path time s with analytic P', P''; a smooth start ramp
(``ramp_s``) warps time so the reference starts at rest: s' rises 0 → 1 as 3τ² − 2τ³ (τ = t/ramp_s),
giving v = P'·s', a = P''·s'² + P'·s''. Yaw is ``yaw_rad`` (``yaw_mode="fixed"``) or the heading of the
horizontal velocity (``yaw_mode="tangent"``, ``yaw_rad`` while slower than 0.1 m/s).
"""

from __future__ import annotations

import itertools
import math
from abc import ABC, abstractmethod
from collections.abc import Callable
from dataclasses import dataclass, fields
from typing import Any, ClassVar

import numpy as np


@dataclass(frozen=True)
class RefSample:
    """A reference at time(s) t_s: arrays shaped t_s.shape + (3,) for vectors, t_s.shape for yaw."""

    t_s: np.ndarray
    pos_ned: np.ndarray
    vel_ned: np.ndarray
    acc_ned: np.ndarray
    yaw_rad: np.ndarray


Path = tuple[np.ndarray, np.ndarray, np.ndarray]  # P, P', P'' each (T, 3) in NED


def _check(name: str, value: float, *, positive: bool = False, nonneg: bool = False) -> None:
    try:
        ok = not isinstance(value, bool | str) and math.isfinite(float(value))
    except (TypeError, ValueError):
        ok = False
    if not ok:
        raise ValueError(f"{name} must be a finite number, got {value!r}")
    if positive and value <= 0.0:
        raise ValueError(f"{name} must be > 0, got {value!r}")
    if nonneg and value < 0.0:
        raise ValueError(f"{name} must be >= 0, got {value!r}")


def _warp(t: np.ndarray, ramp_s: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Path time s(t) ≥ 0 and its derivatives (s', s'') for a smooth start over ramp_s (0: none)."""
    t = np.maximum(t, 0.0)
    if ramp_s <= 0.0:
        return t, np.ones_like(t), np.zeros_like(t)
    tau = np.minimum(t / ramp_s, 1.0)
    s = np.where(t < ramp_s, ramp_s * (tau**3 - 0.5 * tau**4), 0.5 * ramp_s + (t - ramp_s))
    ds = 3.0 * tau**2 - 2.0 * tau**3
    dds = np.where(t < ramp_s, (6.0 * tau - 6.0 * tau**2) / ramp_s, 0.0)
    return s, ds, dds


def _stack(n: np.ndarray, e: np.ndarray, d: np.ndarray) -> np.ndarray:
    return np.stack(np.broadcast_arrays(n, e, d), axis=-1)


class Trajectory(ABC):
    """Common machinery: time warp, yaw, sampling, waypoint expansion. Subclasses define ``_path``."""

    TYPE: ClassVar[str] = ""
    duration_s: float
    ramp_s: float
    yaw_rad: float
    yaw_mode: str

    @abstractmethod
    def _path(self, s: np.ndarray) -> Path:
        """P(s), P'(s), P''(s), each (len(s), 3) NED, for path times s (1-D)."""

    def _start_s(self) -> float:
        """Time at which the route starts moving (before it, the reference holds the start point)."""
        return 0.0

    def _validate_common(self) -> None:
        _check("duration_s", self.duration_s, positive=True)
        _check("ramp_s", self.ramp_s, nonneg=True)
        _check("yaw_rad", self.yaw_rad)
        if self.yaw_mode not in ("fixed", "tangent"):
            raise ValueError(f"yaw_mode must be 'fixed' or 'tangent', got {self.yaw_mode!r}")

    def sample(self, t_s: float | np.ndarray) -> RefSample:
        """Position, velocity, acceleration (NED) and yaw at t_s (clamped to [0, duration_s])."""
        t = np.clip(np.asarray(t_s, dtype=np.float64), 0.0, self.duration_s)
        flat = t.reshape(-1)
        s, ds, dds = _warp(flat - self._start_s(), self.ramp_s)
        p, dp, ddp = self._path(s)
        moving = (flat >= self._start_s())[:, None]
        vel = np.where(moving, dp * ds[:, None], 0.0)
        acc = np.where(moving, ddp * (ds * ds)[:, None] + dp * dds[:, None], 0.0)
        yaw = np.full(flat.shape, float(self.yaw_rad))
        if self.yaw_mode == "tangent":
            speed = np.hypot(vel[:, 0], vel[:, 1])
            yaw = np.where(speed > 0.1, np.arctan2(vel[:, 1], vel[:, 0]), yaw)
        return RefSample(
            t_s=t,
            pos_ned=p.reshape(*t.shape, 3),
            vel_ned=vel.reshape(*t.shape, 3),
            acc_ned=acc.reshape(*t.shape, 3),
            yaw_rad=yaw.reshape(t.shape),
        )

    def waypoints(self, spacing_m: float, min_alt_m: float = 1.0) -> list[tuple[float, float, float]]:
        """Points (north_m, east_m, alt_m) about every ``spacing_m`` of path length, first and last included.

        Parts of the route below ``min_alt_m`` (e.g. the storm's ground start) are left out: a mission's
        takeoff item flies that part.
        """
        _check("spacing_m", spacing_m, positive=True)
        _check("min_alt_m", min_alt_m, nonneg=True)
        t = np.arange(0.0, self.duration_s + 1e-9, 0.01)
        if t[-1] < self.duration_s:
            t = np.append(t, self.duration_s)
        p = self.sample(t).pos_ned
        p = p[-p[:, 2] >= min_alt_m]
        if p.shape[0] == 0:
            raise ValueError(f"min_alt_m: the whole route is below {min_alt_m} m")
        length = np.concatenate(([0.0], np.cumsum(np.linalg.norm(np.diff(p, axis=0), axis=1))))
        marks = np.arange(0.0, length[-1], spacing_m)
        idx = np.unique(np.searchsorted(length, marks))
        if idx[-1] != len(p) - 1:
            idx = np.append(idx, len(p) - 1)
        return [(float(p[i, 0]), float(p[i, 1]), float(-p[i, 2])) for i in idx]


@dataclass(frozen=True)
class StormSpiral(Trajectory):
    """Storm route (paper Example 1): hold on the start point until ``takeoff_s``, then an arc of
    increasing radius (r_start → r_end) and height (alt_start → alt_end) over ``turns`` turns, ending at
    ``duration_s`` (paper: takeoff at 20 s, 140 s total). Starts at home (north = east = 0)."""

    TYPE: ClassVar[str] = "storm"
    duration_s: float = 140.0
    takeoff_s: float = 20.0
    r_start_m: float = 1.0
    r_end_m: float = 15.0
    alt_start_m: float = 0.0
    alt_end_m: float = 10.0
    turns: float = 3.0
    ramp_s: float = 3.0
    yaw_rad: float = 0.0
    yaw_mode: str = "fixed"

    def __post_init__(self) -> None:
        self._validate_common()
        _check("takeoff_s", self.takeoff_s, nonneg=True)
        if self.takeoff_s >= self.duration_s - self.ramp_s:
            raise ValueError("takeoff_s must leave time for the route: takeoff_s < duration_s - ramp_s")
        _check("r_start_m", self.r_start_m, nonneg=True)
        _check("r_end_m", self.r_end_m, positive=True)
        _check("alt_start_m", self.alt_start_m, nonneg=True)
        _check("alt_end_m", self.alt_end_m, nonneg=True)
        _check("turns", self.turns, positive=True)

    def _start_s(self) -> float:
        return self.takeoff_s

    def _path(self, s: np.ndarray) -> Path:
        span = _warp(np.array([self.duration_s - self.takeoff_s]), self.ramp_s)[0][0]  # path time available
        sig = np.clip(s / span, 0.0, 1.0)
        k = 1.0 / span
        r = self.r_start_m + (self.r_end_m - self.r_start_m) * sig
        dr = (self.r_end_m - self.r_start_m) * k
        th = 2.0 * math.pi * self.turns * sig
        dth = 2.0 * math.pi * self.turns * k
        c, sn = np.cos(th), np.sin(th)
        n = r * c - self.r_start_m
        e = r * sn
        dn = dr * c - r * sn * dth
        de = dr * sn + r * c * dth
        ddn = -2.0 * dr * sn * dth - r * c * dth * dth
        dde = 2.0 * dr * c * dth - r * sn * dth * dth
        d = -(self.alt_start_m + (self.alt_end_m - self.alt_start_m) * sig)
        dd = np.full_like(s, -(self.alt_end_m - self.alt_start_m) * k)
        z = np.zeros_like(s)
        return _stack(n, e, d), _stack(dn, de, dd), _stack(ddn, dde, z)


@dataclass(frozen=True)
class Lissajous3D(Trajectory):
    """3D Lissajous (paper Example 2): n = A·sin(a·ωs), e = B·sin(b·ωs), alt = alt + C·sin(c·ωs), ω = 2π/period."""

    TYPE: ClassVar[str] = "lissajous"
    duration_s: float = 40.0
    period_s: float = 40.0
    amp_north_m: float = 10.0
    amp_east_m: float = 10.0
    amp_alt_m: float = 2.0
    freq_north: float = 1.0
    freq_east: float = 2.0
    freq_alt: float = 3.0
    alt_m: float = 10.0
    ramp_s: float = 2.0
    yaw_rad: float = 0.0
    yaw_mode: str = "fixed"

    def __post_init__(self) -> None:
        self._validate_common()
        _check("period_s", self.period_s, positive=True)
        for name in ("amp_north_m", "amp_east_m", "amp_alt_m", "freq_north", "freq_east", "freq_alt"):
            _check(name, getattr(self, name), nonneg=True)
        _check("alt_m", self.alt_m, nonneg=True)
        if self.alt_m < self.amp_alt_m:
            raise ValueError("alt_m must be >= amp_alt_m (the route must stay above ground)")

    def _path(self, s: np.ndarray) -> Path:
        w = 2.0 * math.pi / self.period_s
        out = []
        for amp, f in ((self.amp_north_m, self.freq_north), (self.amp_east_m, self.freq_east)):
            out.append(
                (amp * np.sin(f * w * s), amp * f * w * np.cos(f * w * s), -amp * (f * w) ** 2 * np.sin(f * w * s))
            )
        a, f = self.amp_alt_m, self.freq_alt
        out.append(
            (
                -(self.alt_m + a * np.sin(f * w * s)),
                -a * f * w * np.cos(f * w * s),
                a * (f * w) ** 2 * np.sin(f * w * s),
            )
        )
        return tuple(_stack(out[0][k], out[1][k], out[2][k]) for k in range(3))  # type: ignore[return-value]


@dataclass(frozen=True)
class FigureEight(Trajectory):
    """Figure-8 route at constant altitude: n = A·sin(ωs), e = (B/2)·sin(2ωs), ω = 2π/period."""

    TYPE: ClassVar[str] = "figure8"
    duration_s: float = 30.0
    period_s: float = 30.0
    length_m: float = 20.0
    width_m: float = 10.0
    alt_m: float = 10.0
    ramp_s: float = 2.0
    yaw_rad: float = 0.0
    yaw_mode: str = "fixed"

    def __post_init__(self) -> None:
        self._validate_common()
        for name in ("period_s", "length_m", "width_m"):
            _check(name, getattr(self, name), positive=True)
        _check("alt_m", self.alt_m, nonneg=True)

    def _path(self, s: np.ndarray) -> Path:
        w = 2.0 * math.pi / self.period_s
        a, b = 0.5 * self.length_m, 0.5 * self.width_m
        n, dn, ddn = a * np.sin(w * s), a * w * np.cos(w * s), -a * w * w * np.sin(w * s)
        e, de, dde = b * np.sin(2 * w * s), 2 * b * w * np.cos(2 * w * s), -4 * b * w * w * np.sin(2 * w * s)
        z = np.zeros_like(s)
        return _stack(n, e, z - self.alt_m), _stack(dn, de, z), _stack(ddn, dde, z)


@dataclass(frozen=True)
class ScenicSpiral(Trajectory):
    """Scenic spiral: a constant-radius helix climbing from alt_start to alt_end over ``turns`` turns."""

    TYPE: ClassVar[str] = "scenic_spiral"
    duration_s: float = 60.0
    radius_m: float = 8.0
    alt_start_m: float = 5.0
    alt_end_m: float = 15.0
    turns: float = 2.0
    ramp_s: float = 2.0
    yaw_rad: float = 0.0
    yaw_mode: str = "fixed"

    def __post_init__(self) -> None:
        self._validate_common()
        _check("radius_m", self.radius_m, positive=True)
        _check("turns", self.turns, positive=True)
        _check("alt_start_m", self.alt_start_m, nonneg=True)
        _check("alt_end_m", self.alt_end_m, nonneg=True)

    def _path(self, s: np.ndarray) -> Path:
        span = _warp(np.array([self.duration_s]), self.ramp_s)[0][0]
        k = 1.0 / span
        th = 2.0 * math.pi * self.turns * np.clip(s * k, 0.0, 1.0)
        dth = 2.0 * math.pi * self.turns * k
        r = self.radius_m
        c, sn = np.cos(th), np.sin(th)
        climb = self.alt_end_m - self.alt_start_m
        d = -(self.alt_start_m + climb * np.clip(s * k, 0.0, 1.0))
        z = np.zeros_like(s)
        return (
            _stack(r * c - r, r * sn, d),
            _stack(-r * sn * dth, r * c * dth, z - climb * k),
            _stack(-r * c * dth * dth, -r * sn * dth * dth, z),
        )


@dataclass(frozen=True)
class SquareRoute(Trajectory):
    """Four-side route: a square of ``side_m`` at ``alt_m``, each side a minimum-jerk move (rest at corners)
    with peak speed ``speed_m_s``; starts at home, goes north, east, south, west."""

    TYPE: ClassVar[str] = "square"
    side_m: float = 10.0
    speed_m_s: float = 2.0
    alt_m: float = 10.0
    laps: float = 1.0
    ramp_s: float = 0.0
    yaw_rad: float = 0.0
    yaw_mode: str = "fixed"
    duration_s: float = 0.0  # derived: 4·laps·side time

    _CORNERS: ClassVar[np.ndarray] = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0], [0.0, 0.0]])

    def __post_init__(self) -> None:
        for name in ("side_m", "speed_m_s", "laps"):
            _check(name, getattr(self, name), positive=True)
        _check("alt_m", self.alt_m, nonneg=True)
        object.__setattr__(self, "duration_s", 4.0 * self.laps * self._side_time_s())
        self._validate_common()

    def _side_time_s(self) -> float:
        return 1.875 * self.side_m / self.speed_m_s  # min-jerk peak speed = 1.875 × mean speed

    def _path(self, s: np.ndarray) -> Path:
        ts = self._side_time_s()
        s = np.minimum(s, self.duration_s)
        leg = np.minimum(np.floor(s / ts), 4.0 * self.laps - 1e-9).astype(int)
        tau = np.clip(s / ts - leg, 0.0, 1.0)
        sig = 10 * tau**3 - 15 * tau**4 + 6 * tau**5
        dsig = (30 * tau**2 - 60 * tau**3 + 30 * tau**4) / ts
        ddsig = (60 * tau - 180 * tau**2 + 120 * tau**3) / ts**2
        a = self._CORNERS[leg % 4] * self.side_m
        b = self._CORNERS[leg % 4 + 1] * self.side_m
        dir_ne = b - a
        ne = a + dir_ne * sig[:, None]
        z = np.zeros_like(s)
        return (
            _stack(ne[:, 0], ne[:, 1], z - self.alt_m),
            _stack(dir_ne[:, 0] * dsig, dir_ne[:, 1] * dsig, z),
            _stack(dir_ne[:, 0] * ddsig, dir_ne[:, 1] * ddsig, z),
        )


@dataclass(frozen=True)
class Steps(Trajectory):
    """Setpoint steps (for step responses): ``steps`` = [[t_s, north_m, east_m, alt_m], ...], t ascending,
    first at t = 0; the reference jumps at each t (zero velocity and acceleration)."""

    TYPE: ClassVar[str] = "steps"
    steps: tuple[tuple[float, float, float, float], ...] = ((0.0, 0.0, 0.0, 10.0), (5.0, 1.0, 0.0, 10.0))
    duration_s: float = 10.0
    ramp_s: float = 0.0
    yaw_rad: float = 0.0
    yaw_mode: str = "fixed"

    def __post_init__(self) -> None:
        rows = tuple(tuple(float(v) for v in row) for row in self.steps)
        if not rows or any(len(r) != 4 for r in rows):
            raise ValueError("steps must be a non-empty list of [t_s, north_m, east_m, alt_m]")
        times = [r[0] for r in rows]
        if times[0] != 0.0 or any(b <= a for a, b in itertools.pairwise(times)):
            raise ValueError("steps: times must start at 0 and increase strictly")
        if not all(math.isfinite(v) for r in rows for v in r):
            raise ValueError("steps: every value must be finite")
        object.__setattr__(self, "steps", rows)
        self._validate_common()

    def _path(self, s: np.ndarray) -> Path:
        table = np.array(self.steps)
        idx = np.searchsorted(table[:, 0], s, side="right") - 1
        p = table[idx, 1:].copy()
        p[:, 2] = -p[:, 2]
        z = np.zeros_like(p)
        return p, z, z

    def waypoints(self, spacing_m: float, min_alt_m: float = 1.0) -> list[tuple[float, float, float]]:
        """The step setpoints at or above ``min_alt_m`` (spacing is irrelevant for steps)."""
        _check("spacing_m", spacing_m, positive=True)
        return [(r[1], r[2], r[3]) for r in self.steps if r[3] >= min_alt_m]


TRAJECTORY_TYPES: dict[str, Callable[..., Trajectory]] = {
    cls.TYPE: cls for cls in (StormSpiral, Lissajous3D, SquareRoute, FigureEight, ScenicSpiral, Steps)
}


def make_trajectory(type: str, **params: Any) -> Trajectory:
    """Build a trajectory by name ("storm", "lissajous", "square", "figure8", "scenic_spiral", "steps")."""
    cls = TRAJECTORY_TYPES.get(type)
    if cls is None:
        raise ValueError(f"type: unknown trajectory {type!r}; known: {sorted(TRAJECTORY_TYPES)}")
    allowed = {f.name for f in fields(cls) if not (cls is SquareRoute and f.name == "duration_s")}
    for name in params:
        if name not in allowed:
            raise ValueError(f"{name}: not a parameter of {type!r} (allowed: {sorted(allowed)})")
    if "steps" in params:
        params = {**params, "steps": tuple(tuple(r) for r in params["steps"])}
    try:
        return cls(**params)
    except TypeError as exc:
        raise ValueError(f"{type}: {exc}") from None
