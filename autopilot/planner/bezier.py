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
from dataclasses import dataclass, field

import numpy as np

#: Relative tolerance on the limit check (the joint-speed iteration approaches a limit asymptotically).
LIMIT_RTOL = 1e-4

Vec = tuple[float, float, float]

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
    # per segment (duration, P0, P1, P2, P3) as floats: evaluated every control step, numpy per call costs more
    _segments: tuple[tuple[float, Vec, Vec, Vec, Vec], ...] = field(init=False, repr=False, compare=False)
    _duration_s: float = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        ctrl, durations = self.ctrl_ned.tolist(), self.durations_s.tolist()
        segments = tuple((T, *(tuple(p) for p in c)) for T, c in zip(durations, ctrl, strict=True))
        object.__setattr__(self, "_segments", segments)
        object.__setattr__(self, "_duration_s", float(sum(durations)))

    @property
    def duration_s(self) -> float:
        return self._duration_s

    @property
    def end_ned(self) -> np.ndarray:
        return self.ctrl_ned[-1, 3]

    def state_at(self, t_s: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(pos_ned, vel_ned, acc_ned) at time ``t_s`` after the start (clamped to the ends)."""
        p, v, a = self.state_tuple(t_s)
        return np.array(p), np.array(v), np.array(a)

    def state_tuple(self, t_s: float) -> tuple[Vec, Vec, Vec]:
        """``state_at`` as plain float tuples: Bernstein form of the position, hodographs
        ``3(P[i+1] − P[i])/T`` and ``2(h[i+1] − h[i])/T`` for velocity and acceleration (zero past the end)."""
        t = min(max(t_s, 0.0), self._duration_s)
        segments = self._segments
        last = len(segments) - 1
        for k, seg in enumerate(segments):
            T = seg[0]
            if t <= T or k == last:
                break
            t -= T
        T, (x0, y0, z0), (x1, y1, z1), (x2, y2, z2), (x3, y3, z3) = seg
        u = min(t / T, 1.0)
        w = 1.0 - u
        b0, b1, b2, b3 = w * w * w, 3.0 * w * w * u, 3.0 * w * u * u, u * u * u
        pos = (
            b0 * x0 + b1 * x1 + b2 * x2 + b3 * x3,
            b0 * y0 + b1 * y1 + b2 * y2 + b3 * y3,
            b0 * z0 + b1 * z1 + b2 * z2 + b3 * z3,
        )
        k = 3.0 / T  # hodograph control points h0, h1, h2 = 3(P[i+1] - P[i]) / T
        h0x, h0y, h0z = k * (x1 - x0), k * (y1 - y0), k * (z1 - z0)
        h1x, h1y, h1z = k * (x2 - x1), k * (y2 - y1), k * (z2 - z1)
        h2x, h2y, h2z = k * (x3 - x2), k * (y3 - y2), k * (z3 - z2)
        c0, c1, c2 = w * w, 2.0 * w * u, u * u
        vel = (c0 * h0x + c1 * h1x + c2 * h2x, c0 * h0y + c1 * h1y + c2 * h2y, c0 * h0z + c1 * h1z + c2 * h2z)
        if t_s >= self._duration_s:
            return pos, vel, (0.0, 0.0, 0.0)
        a0, a1 = 2.0 * w / T, 2.0 * u / T
        acc = (
            a0 * (h1x - h0x) + a1 * (h2x - h1x),
            a0 * (h1y - h0y) + a1 * (h2y - h1y),
            a0 * (h1z - h0z) + a1 * (h2z - h1z),
        )
        return pos, vel, acc

    def sample(self, max_step_m: float) -> np.ndarray:
        """Points ``(m, 3)`` along the whole chain, consecutive samples at most ``max_step_m`` apart.

        Per segment, from the hodograph hull: ``|dP/du| <= 3·max|P[i+1] − P[i]|``, so
        ``n = ceil(3·max|ΔP| / max_step)`` equal parameter steps are at most ``max_step`` long each
        (short segments get few samples, long ones many).
        """
        return self.sample_with_times(max_step_m)[0]

    def sample_with_times(self, max_step_m: float) -> tuple[np.ndarray, np.ndarray]:
        """``sample`` and the time (s from the start) of each sample, ``(m,)`` increasing."""
        counts = [
            max(2, math.ceil(3.0 * max(math.dist(p0, p1), math.dist(p1, p2), math.dist(p2, p3)) / max_step_m))
            for _, p0, p1, p2, p3 in self._segments
        ]
        n = np.array(counts)
        seg = np.repeat(np.arange(len(counts)), n)  # segment of each sample after the start point
        first = np.repeat(np.cumsum(n) - n, n)
        u = (np.arange(1, len(seg) + 1) - first) / n[seg]  # k/n_seg, k = 1..n_seg
        w = 1.0 - u
        basis = np.stack((w * w * w, 3.0 * w * w * u, 3.0 * w * u * u, u * u * u), axis=1)
        body = np.einsum("mj,mjd->md", basis, self.ctrl_ned[seg])
        starts = np.cumsum(self.durations_s) - self.durations_s
        times = starts[seg] + u * self.durations_s[seg]
        return np.concatenate((self.ctrl_ned[0, :1], body)), np.concatenate(((0.0,), times))


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
    m0x, m0y, m0z = m0
    m1x, m1y, m1z = m1
    mx, my, mz = d3[0] * inv_t - m0x - m1x, d3[1] * inv_t - m0y - m1y, d3[2] * inv_t - m0z - m1z
    v2 = max(mx * mx + my * my + mz * mz, s_max * s_max)
    ax, ay, az = mx - m0x, my - m0y, mz - m0z
    bx, by, bz = m1x - mx, m1y - my, m1z - mz
    a2 = max(ax * ax + ay * ay + az * az, bx * bx + by * by + bz * bz)
    return max(math.sqrt(v2) / v_max, math.sqrt(2.0 * inv_t * math.sqrt(a2) / a_max))


#: Duration multipliers tried for the first segment (its start speed is fixed, so speeds alone cannot time it).
_FIRST_SEGMENT_STRETCH = tuple(float(x) for x in np.geomspace(0.5, 1.5, 12))


def _first_fitting_stretch(
    d3: Vec, m0: Vec, m1: Vec, s_max: float, t_nominal: float, v_max: float, a_max: float
) -> float | None:
    """The first of ``_FIRST_SEGMENT_STRETCH`` (times ``t_nominal``) whose duration meets both limits, or None.

    Same hulls as :func:`_segment_excess`, expanded in ``s = 1/T``: with ``D = d3``, the middle hull point
    ``D·s − (m0 + m1)`` and the acceleration hull ``2s·(D·s − (2m0 + m1))``, ``2s·((m0 + 2m1) − D·s)`` are
    quadratics in ``s`` of a few precomputed dot products (a dozen float operations per stretch).
    """
    if s_max > v_max:
        return None
    dx, dy, dz = d3
    mx, my, mz = m0[0] + m1[0], m0[1] + m1[1], m0[2] + m1[2]
    ex, ey, ez = mx + m0[0], my + m0[1], mz + m0[2]  # 2 m0 + m1
    fx, fy, fz = mx + m1[0], my + m1[1], mz + m1[2]  # m0 + 2 m1
    dd = dx * dx + dy * dy + dz * dz
    dm, mm = dx * mx + dy * my + dz * mz, mx * mx + my * my + mz * mz
    de, ee = dx * ex + dy * ey + dz * ez, ex * ex + ey * ey + ez * ez
    df, ff = dx * fx + dy * fy + dz * fz, fx * fx + fy * fy + fz * fz
    v2_max, a2_max = v_max * v_max, 0.25 * a_max * a_max
    for stretch in _FIRST_SEGMENT_STRETCH:
        s = 1.0 / (t_nominal * stretch)
        ds = dd * s
        if ds * s - 2.0 * dm * s + mm > v2_max:
            continue
        a2 = max(ds * s - 2.0 * de * s + ee, ds * s - 2.0 * df * s + ff)
        if s * s * a2 <= a2_max:
            return stretch
    return None


def _first_segment_hopeless(d3: Vec, v0: Vec, v_start: float, chord: float, v_max: float, a_max: float) -> bool:
    """Whether the first segment meets the limits at none of the stretched durations even when it ends at rest.

    Slowing the first joint toward rest is ``fit_detour``'s only remedy for a first segment its start
    velocity makes untimeable; when even rest does not help, the fit is given up at once (a heuristic:
    measured on the benchmark's fits, it never gave up one that the remaining iterations would have met).
    """
    t_nominal = max(chord / max(0.5 * v_start, 0.2), 1e-3)
    return _first_fitting_stretch(d3, v0, (0.0, 0.0, 0.0), v_start, t_nominal, v_max, a_max) is None


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
    for iteration in range(max_iterations):
        vel = [(t[0] * s, t[1] * s, t[2] * s) for t, s in zip(tangents, speeds, strict=True)]
        excess = [0.0] * k
        for i in range(k):
            durations[i] = max(chords[i] / max(0.5 * (speeds[i] + speeds[i + 1]), 0.2), 1e-3)
            s_max = max(speeds[i], speeds[i + 1])
            excess[i] = _segment_excess(d3[i], vel[i], vel[i + 1], s_max, 1.0 / durations[i], v_max_m_s, a_max_m_s2)
        first_fits = excess[0] <= 1.0
        if not first_fits:  # the first segment: stretch its duration (its start speed cannot scale)
            s_max = max(speeds[0], speeds[1])
            stretch = _first_fitting_stretch(d3[0], vel[0], vel[1], s_max, durations[0], v_max_m_s, a_max_m_s2)
            if stretch is not None:
                durations[0] *= stretch
                excess[0] = _segment_excess(d3[0], vel[0], vel[1], s_max, 1.0 / durations[0], v_max_m_s, a_max_m_s2)
                first_fits = True
        if max(excess) <= 1.0 + LIMIT_RTOL:
            break
        if (
            not first_fits
            and not iteration
            and _first_segment_hopeless(d3[0], v0, v_start, chords[0], v_max_m_s, a_max_m_s2)
        ):
            break  # not even a stop at the first joint can be timed: give up at once
        factor = [min(1.0, 0.995 / max(e, 1e-9)) for e in excess]
        if not first_fits:
            factor[0] = 0.7  # the first segment cannot be timed: slow its end
        for j in range(1, k):
            speeds[j] *= min(factor[j - 1], factor[j])
        speeds[k] *= factor[k - 1]
    vel = [(t[0] * s, t[1] * s, t[2] * s) for t, s in zip(tangents, speeds, strict=True)]
    return _hermite_chain(pts, vel, durations, v_max_m_s, a_max_m_s2)


def _hermite_chain(
    pts: list[Vec], vel: list[Vec], durations: list[float], v_max_m_s: float, a_max_m_s2: float
) -> BezierPath:
    """The cubic chain through ``pts`` with joint velocities ``vel`` and its exact hodograph-hull bounds."""
    ctrl = []
    v2_max = max(v[0] * v[0] + v[1] * v[1] + v[2] * v[2] for v in vel)
    a2_max = 0.0
    for i, T in enumerate(durations):
        p0, p3, m0, m1 = pts[i], pts[i + 1], vel[i], vel[i + 1]
        k = T / 3.0
        p1 = (p0[0] + m0[0] * k, p0[1] + m0[1] * k, p0[2] + m0[2] * k)
        p2 = (p3[0] - m1[0] * k, p3[1] - m1[1] * k, p3[2] - m1[2] * k)
        ctrl.append((p0, p1, p2, p3))
        mid = tuple((p2[j] - p1[j]) / k for j in range(3))  # 3 (P2 - P1) / T
        v2_max = max(v2_max, mid[0] * mid[0] + mid[1] * mid[1] + mid[2] * mid[2])
        inv2 = 2.0 / T
        for d in ((mid[0] - m0[0], mid[1] - m0[1], mid[2] - m0[2]), (m1[0] - mid[0], m1[1] - mid[1], m1[2] - mid[2])):
            a2_max = max(a2_max, (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]) * inv2 * inv2)
    v_bound, a_bound = math.sqrt(v2_max), math.sqrt(a2_max)
    ok = v_bound <= v_max_m_s * (1 + LIMIT_RTOL) and a_bound <= a_max_m_s2 * (1 + LIMIT_RTOL)
    ctrl_ned = np.array(ctrl, float)
    ctrl_ned.setflags(write=False)
    durations_s = np.array(durations, float)
    durations_s.setflags(write=False)
    return BezierPath(ctrl_ned, durations_s, v_bound, a_bound, ok)
