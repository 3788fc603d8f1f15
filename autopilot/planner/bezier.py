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

import itertools
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


Vec = tuple[float, float, float]


def _norm(x: float, y: float, z: float) -> float:
    return math.sqrt(x * x + y * y + z * z)


def _turn_speed(prev: Vec, here: Vec, nxt: Vec, v: float, a_max: float) -> tuple[float, Vec]:
    """Joint speed limited by ``v²/r <= a_max`` on the circle through three points
    (``r = chord / (2 sin turn)``), and the joint tangent (bisector of the two legs)."""
    ux, uy, uz = here[0] - prev[0], here[1] - prev[1], here[2] - prev[2]
    wx, wy, wz = nxt[0] - here[0], nxt[1] - here[1], nxt[2] - here[2]
    l1 = max(_norm(ux, uy, uz), 1e-9)
    l2 = max(_norm(wx, wy, wz), 1e-9)
    tx, ty, tz = ux / l1 + wx / l2, uy / l1 + wy / l2, uz / l1 + wz / l2
    tn = max(_norm(tx, ty, tz), 1e-9)
    tangent = (tx / tn, ty / tn, tz / tn)
    sin_turn = _norm(uy * wz - uz * wy, uz * wx - ux * wz, ux * wy - uy * wx) / (l1 * l2)
    if sin_turn < 1e-6:
        return v, tangent
    return min(v, math.sqrt(a_max * _norm(ux + wx, uy + wy, uz + wz) / (2.0 * sin_turn))), tangent


def _segment_excess(d3: Vec, m0: Vec, m1: Vec, s_max: float, inv_t: float, v_max: float, a_max: float) -> float:
    """Worst of ``v_bound/v_max`` and ``sqrt(a_bound/a_max)`` of one cubic Hermite segment (hodograph hulls).

    ``d3`` is ``3·(p1 − p0)``, ``m0``/``m1`` the end velocities, ``s_max`` the larger end speed and ``inv_t``
    ``1/T``. Velocity hull: m0, ``3(P2 − P1)/T = d3/T − m0 − m1``, m1; acceleration hull ``2(h[i+1] − h[i])/T``.
    """
    mx, my, mz = d3[0] * inv_t - m0[0] - m1[0], d3[1] * inv_t - m0[1] - m1[1], d3[2] * inv_t - m0[2] - m1[2]
    v = max(_norm(mx, my, mz), s_max)
    a0 = _norm(mx - m0[0], my - m0[1], mz - m0[2])
    a1 = _norm(m1[0] - mx, m1[1] - my, m1[2] - mz)
    return max(v / v_max, math.sqrt(2.0 * inv_t * max(a0, a1) / a_max))


#: Duration multipliers tried for the first segment (its start speed is fixed, so speeds alone cannot time it).
_FIRST_SEGMENT_STRETCH = tuple(float(x) for x in np.geomspace(0.5, 1.5, 12))


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
    the limits unreachable within ``max_iterations``. Scalar Python: chains are short (a few joints)
    and numpy's per-call overhead would dominate.
    """
    pts: list[Vec] = [(float(p[0]), float(p[1]), float(p[2])) for p in points_ned]
    k = len(pts) - 1
    v0 = (float(vel_start_ned[0]), float(vel_start_ned[1]), float(vel_start_ned[2]))
    v1 = (float(vel_end_ned[0]), float(vel_end_ned[1]), float(vel_end_ned[2]))
    v_start, v_end = _norm(*v0), _norm(*v1)
    cruise = min(v_max_m_s, max(v_end, v_start, 0.5))
    speeds = [v_start] + [0.0] * k
    tangents: list[Vec] = [(v0[0] / max(v_start, 1e-9), v0[1] / max(v_start, 1e-9), v0[2] / max(v_start, 1e-9))]
    for i in range(1, k):
        speeds[i], t = _turn_speed(pts[i - 1], pts[i], pts[i + 1], cruise, a_max_m_s2)
        tangents.append(t)
    speeds[k] = min(v_end, v_max_m_s)
    tangents.append((v1[0] / max(v_end, 1e-9), v1[1] / max(v_end, 1e-9), v1[2] / max(v_end, 1e-9)))
    d3: list[Vec] = [
        (3.0 * (b[0] - a[0]), 3.0 * (b[1] - a[1]), 3.0 * (b[2] - a[2])) for a, b in itertools.pairwise(pts)
    ]
    chords = [_norm(*d) / 3.0 for d in d3]
    durations = [0.0] * k
    for _ in range(max_iterations):
        vel = [(t[0] * s, t[1] * s, t[2] * s) for t, s in zip(tangents, speeds, strict=True)]
        excess = [0.0] * k
        for i in range(k):
            durations[i] = max(chords[i] / max(0.5 * (speeds[i] + speeds[i + 1]), 0.2), 1e-3)
            s_max = max(speeds[i], speeds[i + 1])
            excess[i] = _segment_excess(d3[i], vel[i], vel[i + 1], s_max, 1.0 / durations[i], v_max_m_s, a_max_m_s2)
        first_fits = excess[0] <= 1.0
        if not first_fits:  # the first segment: stretch its duration (its start speed cannot scale)
            s_max = max(speeds[0], speeds[1])
            for stretch in _FIRST_SEGMENT_STRETCH:
                e = _segment_excess(d3[0], vel[0], vel[1], s_max, 1.0 / (durations[0] * stretch), v_max_m_s, a_max_m_s2)
                if e <= 1.0:
                    durations[0] *= stretch
                    excess[0], first_fits = e, True
                    break
        if max(excess) <= 1.0 + LIMIT_RTOL:
            break
        factor = [min(1.0, 0.995 / max(e, 1e-9)) for e in excess]
        if not first_fits:
            factor[0] = 0.7  # the first segment cannot be timed: slow its end
        for j in range(1, k):
            speeds[j] *= min(factor[j - 1], factor[j])
        speeds[k] *= factor[k - 1]
    vel = [(t[0] * s, t[1] * s, t[2] * s) for t, s in zip(tangents, speeds, strict=True)]
    return _hermite_chain(np.asarray(points_ned, float), np.array(vel), np.array(durations), v_max_m_s, a_max_m_s2)


def _row_norms(x: np.ndarray) -> np.ndarray:
    """Euclidean norms of the rows of ``x`` (n, 3) with ufuncs only."""
    return np.sqrt(x[:, 0] * x[:, 0] + x[:, 1] * x[:, 1] + x[:, 2] * x[:, 2])


def _hermite_chain(
    pts: np.ndarray, vel: np.ndarray, durations: np.ndarray, v_max_m_s: float, a_max_m_s2: float
) -> BezierPath:
    """The cubic chain through ``pts`` with joint velocities ``vel`` and its exact hodograph-hull bounds."""
    k = len(durations)
    third = (durations / 3.0)[:, None]
    ctrl = np.empty((k, 4, 3))
    ctrl[:, 0] = pts[:-1]
    ctrl[:, 1] = pts[:-1] + vel[:-1] * third
    ctrl[:, 2] = pts[1:] - vel[1:] * third
    ctrl[:, 3] = pts[1:]
    inv_t = (1.0 / durations)[:, None]
    mid = 3.0 * (ctrl[:, 2] - ctrl[:, 1]) * inv_t
    v_bound = float(np.maximum(np.maximum(_row_norms(vel[:-1]), _row_norms(vel[1:])), _row_norms(mid)).max())
    acc0, acc1 = 2.0 * (mid - vel[:-1]) * inv_t, 2.0 * (vel[1:] - mid) * inv_t
    a_bound = float(np.maximum(_row_norms(acc0), _row_norms(acc1)).max())
    ok = v_bound <= v_max_m_s * (1 + LIMIT_RTOL) and a_bound <= a_max_m_s2 * (1 + LIMIT_RTOL)
    ctrl.setflags(write=False)
    durations.setflags(write=False)
    return BezierPath(ctrl, durations, v_bound, a_bound, ok)
