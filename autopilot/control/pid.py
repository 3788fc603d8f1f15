"""One NLVG-PID term with anti-windup, derivative on measurement, output limit and NaN guard.

Law (SPEC §6.2, paper eq. 11 with eq. 3's K_i/K_d swap corrected), in time normalised by the
loop's time scale T (ω = 1/T, so the gains are dimensionless and one gain set fits every airframe)::

    u = ω²·k_p(s)·e + ω·k_d(s)·ė + I,      İ = ω³·k_i(s)·e     (I clamped to ±i_max, output to ±u_max)

``ė`` is *rate_sp − rate_measured* (derivative on measurement plus an optional rate feed-forward),
so a setpoint step does not kick. I integrates k_i·e (not e), so a live gain change is bumpless;
with k1 == k2 this is exactly a fixed PID. Anti-windup: conditional integration (no integration
while the output is saturated in the direction the error pushes) and clamping.
Scheduling signal ``s``: ``error`` (default) uses |e| for all three gains; ``per_term`` schedules each
gain by the signal it multiplies (k_p: |e|, k_i: |∫e dt/T|, k_d: |ė·T|), the paper's eqs. 4-9 read with
eq. 11's term order. NaN guard: a non-finite e or ė holds the last output and leaves the state as is.

Gain table row (``G_*`` columns) and state row (``S_*`` columns) are shared with the cascade kernel.
"""

from __future__ import annotations

import math
from enum import IntEnum

import numpy as np
from numba import njit

from autopilot.control.gain_schedule import gain_scalar

G_K1P, G_K1I, G_K1D, G_K2P, G_K2I, G_K2D, G_D1, G_D2, G_VARIANT, G_SCHED = range(10)
N_GAIN_COLS = 10
S_I, S_EINT, S_OUT = range(3)
N_STATE_COLS = 3


class Schedule(IntEnum):
    """Which signal schedules each gain."""

    ERROR = 0
    PER_TERM = 1

    @classmethod
    def parse(cls, name: str | Schedule) -> Schedule:
        """``"error"`` / ``"per_term"`` (or the enum) → enum; ValueError names the choices."""
        if isinstance(name, Schedule):
            return name
        try:
            return cls[str(name).upper()]
        except KeyError:
            raise ValueError(f"schedule {name!r} is not one of 'error', 'per_term'") from None


@njit(cache=True, inline="always")
def nlvg_pid_step(e, de, g, gi, w, dt_s, u_max, i_max, st, si, k_out, ki_out):  # pragma: no cover - numba kernel
    """Advance one term by dt_s; returns u.

    Flat arrays with offsets (no slicing in the hot loop): gain row ``g[gi:gi+N_GAIN_COLS]``, state row
    ``st[si:si+N_STATE_COLS]``, live gains (kp, ki, kd) written to ``k_out[ki_out:ki_out+3]``.
    """
    if not (math.isfinite(e) and math.isfinite(de)):
        return st[si + S_OUT]
    variant = int(g[gi + G_VARIANT])
    d1 = g[gi + G_D1]
    d2 = g[gi + G_D2]
    s_i = e
    s_d = e
    if g[gi + G_SCHED] == 1.0:
        s_i = st[si + S_EINT] * w
        s_d = de / w
    kp = gain_scalar(e, g[gi + G_K1P], g[gi + G_K2P], d1, d2, variant)
    ki = gain_scalar(s_i, g[gi + G_K1I], g[gi + G_K2I], d1, d2, variant)
    kd = gain_scalar(s_d, g[gi + G_K1D], g[gi + G_K2D], d1, d2, variant)
    k_out[ki_out] = kp
    k_out[ki_out + 1] = ki
    k_out[ki_out + 2] = kd
    pd = w * w * kp * e + w * kd * de
    i_term = st[si + S_I]
    u_pre = pd + i_term
    winding = (u_pre >= u_max and e > 0.0) or (u_pre <= -u_max and e < 0.0)
    if not winding:
        i_term += w * w * w * ki * e * dt_s
        i_term = min(max(i_term, -i_max), i_max)
        st[si + S_EINT] += e * dt_s
    u = min(max(pd + i_term, -u_max), u_max)
    if not math.isfinite(u):
        return st[si + S_OUT]
    st[si + S_I] = i_term
    st[si + S_OUT] = u
    return u


@njit(cache=True)
def _pid_batch(e, de, g, w, dt_s, u_max, i_max, st, k_out, out):  # pragma: no cover - numba kernel
    gf = g.reshape(-1)
    sf = st.reshape(-1)
    kf = k_out.reshape(-1)
    for j in range(e.shape[0]):
        out[j] = nlvg_pid_step(e[j], de[j], gf, j * N_GAIN_COLS, w, dt_s, u_max, i_max, sf, j * N_STATE_COLS, kf, 3 * j)


def gain_row(
    k1: tuple[float, float, float],
    k2: tuple[float, float, float],
    delta1: float = 0.01,
    delta2: float = 0.838,
    variant: int = 0,
    schedule: int = 0,
) -> np.ndarray:
    """One packed gain-table row (``G_*`` columns)."""
    return np.array([*k1, *k2, delta1, delta2, float(variant), float(schedule)], dtype=np.float64)


class NlvgPidBatch:
    """n independent NLVG-PID terms of one channel (the cascade kernel uses the same step function).

    ``u_max`` and ``i_max`` are in output units; ``time_scale_s`` is the loop's T (1 s → SI gains).
    """

    def __init__(self, n: int, dt_s: float, u_max: float, i_max: float, time_scale_s: float = 1.0) -> None:
        if n < 1 or not dt_s > 0.0 or not u_max > 0.0 or not i_max >= 0.0 or not time_scale_s > 0.0:
            raise ValueError("need n >= 1, dt_s > 0, u_max > 0, i_max >= 0, time_scale_s > 0")
        self.n = n
        self.dt_s = float(dt_s)
        self.u_max = float(u_max)
        self.i_max = float(i_max)
        self.w = 1.0 / float(time_scale_s)
        self.gains = np.zeros((n, N_GAIN_COLS))
        self.state = np.zeros((n, N_STATE_COLS))
        self.k_live = np.zeros((n, 3))
        self._out = np.zeros(n)

    def set_gains(self, rows: np.ndarray) -> None:
        """Gain table (n, N_GAIN_COLS) or one row broadcast to every term."""
        self.gains[:] = np.broadcast_to(np.asarray(rows, dtype=np.float64), self.gains.shape)

    def reset(self) -> None:
        self.state[:] = 0.0

    @property
    def integral(self) -> np.ndarray:
        """The I contribution (output units), shape (n,)."""
        return self.state[:, S_I]

    def update(self, e: np.ndarray, de: np.ndarray) -> np.ndarray:
        """Outputs (n,) for errors e and ė = rate_sp − rate_measured."""
        e = np.ascontiguousarray(np.broadcast_to(np.asarray(e, dtype=np.float64), (self.n,)))
        de = np.ascontiguousarray(np.broadcast_to(np.asarray(de, dtype=np.float64), (self.n,)))
        _pid_batch(e, de, self.gains, self.w, self.dt_s, self.u_max, self.i_max, self.state, self.k_live, self._out)
        return self._out.copy()
