"""Bézier detour curves and their dynamic limits (paper §3.3: "Bessel curve fitting ... that meets
the dynamic constraints").

A detour is a C1 chain of cubic Bézier segments through via points (cubic Hermite form:
``P1 = P0 + m0·T/3``, ``P2 = P3 − m1·T/3`` with joint velocities ``m`` in m/s and segment
duration ``T``). Limits are checked on the hodographs: the velocity of a degree-n curve over
duration T is a degree-(n−1) Bézier with control points ``n·(P[i+1] − P[i]) / T`` and its
acceleration a degree-(n−2) Bézier with ``n(n−1)·(P[i+2] − 2P[i+1] + P[i]) / T²``; by the
convex-hull property the largest control-point norm bounds |v| and |a| over the whole segment.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

#: Relative tolerance on the limit check (the joint-speed iteration approaches a limit asymptotically).
LIMIT_RTOL = 1e-4

_BINOM = tuple(tuple(math.comb(n, k) for k in range(n + 1)) for n in range(12))


def bernstein_matrix(degree: int, t: np.ndarray) -> np.ndarray:
    """Bernstein basis ``B[j, i] = C(n,i) t_j^i (1 − t_j)^(n−i)`` for ``t`` in [0, 1], shape (m, n+1)."""
    t = np.asarray(t, float)[:, None]
    i = np.arange(degree + 1)
    return np.array(_BINOM[degree], float) * t**i * (1.0 - t) ** (degree - i)


def bezier_eval(ctrl: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Points of a Bézier curve with control points ``(n+1, 3)`` at parameters ``t`` (m,)."""
    return bernstein_matrix(len(ctrl) - 1, t) @ ctrl


def hodograph(ctrl: np.ndarray, duration_s: float = 1.0) -> np.ndarray:
    """Control points of the time derivative ``d/dt`` of a curve traversed in ``duration_s``."""
    n = len(ctrl) - 1
    return n * np.diff(ctrl, axis=0) / duration_s


def derivative_bounds(ctrl: np.ndarray, duration_s: float) -> tuple[float, float]:
    """Upper bounds (max |v| in m/s, max |a| in m/s²) over the segment from the hodograph hulls."""
    vel = hodograph(ctrl, duration_s)
    acc = hodograph(vel, duration_s)
    return float(np.linalg.norm(vel, axis=1).max()), float(np.linalg.norm(acc, axis=1).max())


def hermite_ctrl(p0: np.ndarray, p1: np.ndarray, m0: np.ndarray, m1: np.ndarray, duration_s: float) -> np.ndarray:
    """Cubic Bézier control points ``(4, 3)`` of the Hermite segment p0 -> p1 with end velocities m0, m1."""
    k = duration_s / 3.0
    return np.stack((p0, p0 + m0 * k, p1 - m1 * k, p1))


@dataclass(frozen=True, slots=True)
class BezierPath:
    """A C1 chain of cubic segments: ``ctrl_ned`` (k, 4, 3), ``durations_s`` (k,), starting at t = 0.

    ``v_bound_m_s``/``a_bound_m_s2`` are the hodograph bounds over the whole chain; ``limits_ok``
    says whether they are within the limits it was fitted for.
    """

    ctrl_ned: np.ndarray
    durations_s: np.ndarray
    v_bound_m_s: float
    a_bound_m_s2: float
    limits_ok: bool

    @property
    def duration_s(self) -> float:
        return float(self.durations_s.sum())

    @property
    def end_ned(self) -> np.ndarray:
        return self.ctrl_ned[-1, 3]

    def state_at(self, t_s: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(pos_ned, vel_ned, acc_ned) at time ``t_s`` after the start (clamped to the ends)."""
        k, u = self._locate(t_s)
        c, T = self.ctrl_ned[k], float(self.durations_s[k])
        w = 1.0 - u
        pos = w**3 * c[0] + 3 * w * w * u * c[1] + 3 * w * u * u * c[2] + u**3 * c[3]
        d = 3.0 * np.diff(c, axis=0) / T
        vel = w * w * d[0] + 2 * w * u * d[1] + u * u * d[2]
        dd = 2.0 * np.diff(d, axis=0) / T
        acc = w * dd[0] + u * dd[1]
        if t_s >= self.duration_s:
            acc = np.zeros(3)
        return pos, vel, acc

    def _locate(self, t_s: float) -> tuple[int, float]:
        t = min(max(t_s, 0.0), self.duration_s)
        for k, T in enumerate(self.durations_s):
            if t <= T or k == len(self.durations_s) - 1:
                return k, min(t / float(T), 1.0)
            t -= float(T)
        raise AssertionError("unreachable: durations are positive")

    def sample(self, max_step_m: float) -> np.ndarray:
        """Points ``(m, 3)`` along the whole chain, consecutive samples at most ``max_step_m`` apart.

        The spacing bound uses the velocity hull: a segment of duration T moves at most
        ``v_bound·T`` along its arc, so ``ceil(v_bound·T_max / max_step)`` steps per segment suffice.
        """
        n = max(2, math.ceil(self.v_bound_m_s * float(self.durations_s.max()) / max_step_m))
        basis = bernstein_matrix(3, np.linspace(0.0, 1.0, n + 1)[1:])
        body = np.einsum("mj,kjd->kmd", basis, self.ctrl_ned).reshape(-1, 3)
        return np.concatenate((self.ctrl_ned[0, :1], body))


def _turn_speeds(pts: np.ndarray, v: float, a_max: float) -> tuple[np.ndarray, np.ndarray]:
    """Interior joint speeds limited by ``v²/r <= a_max`` on the circle through each three consecutive
    points (``r = chord / (2 sin turn)``), and the joint tangents (bisector of the two legs)."""
    u = pts[1:-1] - pts[:-2]
    w = pts[2:] - pts[1:-1]
    l1 = np.maximum(np.sqrt(np.einsum("ij,ij->i", u, u)), 1e-9)[:, None]
    l2 = np.maximum(np.sqrt(np.einsum("ij,ij->i", w, w)), 1e-9)[:, None]
    t = u / l1 + w / l2
    tangents = t / np.maximum(np.sqrt(np.einsum("ij,ij->i", t, t)), 1e-9)[:, None]
    c = np.cross(u, w)
    sin_turn = np.sqrt(np.einsum("ij,ij->i", c, c)) / (l1 * l2)[:, 0]
    chord = np.sqrt(np.einsum("ij,ij->i", u + w, u + w))
    limit = np.sqrt(a_max * chord / (2.0 * np.maximum(sin_turn, 1e-12)))
    return np.where(sin_turn < 1e-6, v, np.minimum(v, limit)), tangents


#: Duration multipliers tried for the first segment (its start speed is fixed, so speeds alone cannot time it).
_FIRST_SEGMENT_STRETCH = np.geomspace(0.5, 6.0, 24)


def _segment_excess(
    d3: np.ndarray, m0: np.ndarray, m1: np.ndarray, s_max: np.ndarray, inv_t: np.ndarray, v_max: float, a_max: float
) -> np.ndarray:
    """Worst of ``v_bound/v_max`` and ``sqrt(a_bound/a_max)`` per cubic Hermite segment (hodograph hulls).

    ``d3`` is ``3·(p1 − p0)``, ``m0``/``m1`` the end velocities (n, 3), ``s_max`` the larger end speed
    and ``inv_t`` ``1/T`` (n, 1). Velocity hull: m0, ``3(P2 − P1)/T = d3/T − m0 − m1``, m1; acceleration
    hull: ``2(hull[i+1] − hull[i])/T``.
    """
    mid = d3 * inv_t - m0 - m1
    acc0 = mid - m0
    acc1 = m1 - mid
    v2 = np.maximum((mid * mid).sum(axis=1), s_max * s_max)
    a = 2.0 * inv_t[:, 0] * np.sqrt(np.maximum((acc0 * acc0).sum(axis=1), (acc1 * acc1).sum(axis=1)))
    return np.maximum(np.sqrt(v2) / v_max, np.sqrt(a / a_max))


def fit_detour(
    points_ned: np.ndarray,
    vel_start_ned: np.ndarray,
    vel_end_ned: np.ndarray,
    v_max_m_s: float,
    a_max_m_s2: float,
    max_iterations: int = 8,
) -> BezierPath:
    """Fit a C1 cubic chain through ``points_ned`` (k+1, 3) meeting the velocity/acceleration limits.

    The start velocity is kept (continuity with the vehicle) and the end velocity keeps its direction
    (the route's). Joint speeds start at the centripetal limit ``v²/r <= a_max`` and a segment lasts
    ``chord / mean(end speeds)``. Timing is closed-form: scaling both end speeds of a segment by ``f``
    scales its duration by ``1/f``, its hodograph velocity hull by ``f`` and its acceleration hull by
    ``f²``, so ``f = min(v_max/v_bound, sqrt(a_max/a_bound))`` meets both limits exactly; each joint
    takes the smaller factor of its two segments. The first segment, whose start speed is fixed,
    is timed apart: the shortest duration of ``_FIRST_SEGMENT_STRETCH`` (times nominal) that meets the
    limits, its end speed lowered when none does. ``limits_ok`` is False when the start velocity makes
    the limits unreachable within ``max_iterations``.
    """
    pts = np.asarray(points_ned, float)
    k = len(pts) - 1
    v_end = float(np.linalg.norm(vel_end_ned))
    v_start = float(np.linalg.norm(vel_start_ned))
    cruise = min(v_max_m_s, max(v_end, v_start, 0.5))
    speeds = np.empty(k + 1)
    tangents = np.empty((k + 1, 3))
    speeds[0], speeds[k] = v_start, min(v_end, v_max_m_s)
    tangents[0] = np.asarray(vel_start_ned, float) / max(v_start, 1e-9)
    tangents[k] = np.asarray(vel_end_ned, float) / max(v_end, 1e-9)
    if k > 1:
        speeds[1:k], tangents[1:k] = _turn_speeds(pts, cruise, a_max_m_s2)
    chords = np.linalg.norm(np.diff(pts, axis=0), axis=1)
    d3 = 3.0 * np.diff(pts, axis=0)
    m_start = tangents[:1] * v_start
    stretch = _FIRST_SEGMENT_STRETCH[:, None]
    durations = np.empty(k)
    for _ in range(max_iterations):
        vel = tangents * speeds[:, None]
        durations[:] = np.maximum(chords / np.maximum(0.5 * (speeds[:-1] + speeds[1:]), 0.2), 1e-3)
        s_max = np.maximum(speeds[:-1], speeds[1:])
        excess = _segment_excess(d3, vel[:-1], vel[1:], s_max, (1.0 / durations)[:, None], v_max_m_s, a_max_m_s2)
        # the first segment: stretch its duration (its start speed cannot scale)
        first = _segment_excess(
            d3[:1], m_start, vel[1:2], s_max[:1], 1.0 / (durations[0] * stretch), v_max_m_s, a_max_m_s2
        )
        fits = np.flatnonzero(first <= 1.0)
        if len(fits):
            durations[0] *= float(_FIRST_SEGMENT_STRETCH[fits[0]])
            excess[0] = first[fits[0]]
        if float(excess.max()) <= 1.0 + LIMIT_RTOL:
            break
        factor = np.minimum(1.0, 0.995 / np.maximum(excess, 1e-9))
        if not len(fits):
            factor[0] = 0.7  # the first segment cannot be timed: slow its end
        joint = np.minimum(np.concatenate((factor, [1.0])), np.concatenate(([1.0], factor)))
        speeds[1:] *= joint[1:]
    return _hermite_chain(pts, tangents * speeds[:, None], durations, v_max_m_s, a_max_m_s2)


def _hermite_chain(
    pts: np.ndarray, vel: np.ndarray, durations: np.ndarray, v_max_m_s: float, a_max_m_s2: float
) -> BezierPath:
    """The cubic chain through ``pts`` with joint velocities ``vel`` and its exact hodograph-hull bounds."""
    third = (durations / 3.0)[:, None]
    ctrl = np.stack((pts[:-1], pts[:-1] + vel[:-1] * third, pts[1:] - vel[1:] * third, pts[1:]), axis=1)
    hv = 3.0 * np.diff(ctrl, axis=1) / durations[:, None, None]
    ha = 2.0 * np.diff(hv, axis=1) / durations[:, None, None]
    v_bound = float(np.linalg.norm(hv, axis=2).max())
    a_bound = float(np.linalg.norm(ha, axis=2).max())
    ok = v_bound <= v_max_m_s * (1 + LIMIT_RTOL) and a_bound <= a_max_m_s2 * (1 + LIMIT_RTOL)
    ctrl.setflags(write=False)
    durations.setflags(write=False)
    return BezierPath(ctrl, durations, v_bound, a_bound, ok)
