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


def _turn_speed(
    prev: np.ndarray, here: np.ndarray, nxt: np.ndarray, v: float, a_max: float
) -> tuple[float, np.ndarray]:
    """Joint speed limited by ``v²/r <= a_max`` on the circle through three points, and the tangent."""
    ux, uy, uz = (float(here[i] - prev[i]) for i in range(3))
    wx, wy, wz = (float(nxt[i] - here[i]) for i in range(3))
    l1 = max(math.sqrt(ux * ux + uy * uy + uz * uz), 1e-9)
    l2 = max(math.sqrt(wx * wx + wy * wy + wz * wz), 1e-9)
    tx, ty, tz = ux / l1 + wx / l2, uy / l1 + wy / l2, uz / l1 + wz / l2
    tn = max(math.sqrt(tx * tx + ty * ty + tz * tz), 1e-9)
    tangent = np.array((tx / tn, ty / tn, tz / tn))
    cx, cy, cz = uy * wz - uz * wy, uz * wx - ux * wz, ux * wy - uy * wx
    sin_turn = math.sqrt(cx * cx + cy * cy + cz * cz) / (l1 * l2)
    if sin_turn < 1e-6:
        return v, tangent
    chord = math.sqrt((ux + wx) ** 2 + (uy + wy) ** 2 + (uz + wz) ** 2)
    return min(v, math.sqrt(a_max * chord / (2.0 * sin_turn))), tangent


def fit_detour(
    points_ned: np.ndarray,
    vel_start_ned: np.ndarray,
    vel_end_ned: np.ndarray,
    v_max_m_s: float,
    a_max_m_s2: float,
    max_iterations: int = 25,
) -> BezierPath:
    """Fit a C1 cubic chain through ``points_ned`` (k+1, 3) meeting the velocity/acceleration limits.

    The start velocity is kept (continuity with the vehicle) and the end velocity keeps its direction
    (the route's); joint speeds start at the centripetal limit and are lowered, and durations re-derived, until every
    segment's hodograph bounds are within ``v_max_m_s`` and ``a_max_m_s2`` (or iterations run out,
    then ``limits_ok`` is False).
    """
    pts = np.asarray(points_ned, float)
    k = len(pts) - 1
    v_end = float(np.linalg.norm(vel_end_ned))
    cruise = min(v_max_m_s, max(v_end, float(np.linalg.norm(vel_start_ned)), 0.5))
    speeds = np.empty(k + 1)
    tangents = np.empty((k + 1, 3))
    speeds[0], speeds[k] = float(np.linalg.norm(vel_start_ned)), v_end
    tangents[0], tangents[k] = vel_start_ned, np.asarray(vel_end_ned, float) / max(v_end, 1e-9)
    for i in range(1, k):
        speeds[i], tangents[i] = _turn_speed(pts[i - 1], pts[i], pts[i + 1], cruise, a_max_m_s2)
    chords = np.linalg.norm(np.diff(pts, axis=0), axis=1)
    v_bound = a_bound = best_excess = math.inf
    stalled = 0
    for _ in range(max_iterations):
        vel = tangents.copy()
        vel[1:] *= speeds[1:, None]
        durations = np.maximum(chords / np.maximum(0.5 * (speeds[:-1] + speeds[1:]), 0.2), 1e-3)
        third = (durations / 3.0)[:, None]
        ctrl = np.stack((pts[:-1], pts[:-1] + vel[:-1] * third, pts[1:] - vel[1:] * third, pts[1:]), axis=1)
        hv = 3.0 * np.diff(ctrl, axis=1) / durations[:, None, None]
        ha = 2.0 * np.diff(hv, axis=1) / durations[:, None, None]
        vb = np.linalg.norm(hv, axis=2).max(axis=1)
        ab = np.linalg.norm(ha, axis=2).max(axis=1)
        v_bound, a_bound = float(vb.max()), float(ab.max())
        if v_bound <= v_max_m_s * (1 + LIMIT_RTOL) and a_bound <= a_max_m_s2 * (1 + LIMIT_RTOL):
            break
        excess = np.maximum(vb / v_max_m_s, np.sqrt(ab / a_max_m_s2))
        worst_now = float(excess.max())
        stalled = stalled + 1 if worst_now > 0.995 * best_excess else 0
        if stalled >= 3:
            break  # no progress: the fixed start velocity makes the limits unreachable
        best_excess = min(best_excess, worst_now)
        worst = np.maximum(np.concatenate((excess, [0.0])), np.concatenate(([0.0], excess)))
        # slow the joints next to offending segments (the start velocity stays: continuity with the vehicle)
        speeds[1:] *= np.where(worst[1:] > 1.0, np.maximum(0.6, 0.97 / np.maximum(worst[1:], 1e-9)), 1.0)
    ok = v_bound <= v_max_m_s * (1 + LIMIT_RTOL) and a_bound <= a_max_m_s2 * (1 + LIMIT_RTOL)
    ctrl.setflags(write=False)
    durations.setflags(write=False)
    return BezierPath(ctrl, durations, v_bound, a_bound, ok)
