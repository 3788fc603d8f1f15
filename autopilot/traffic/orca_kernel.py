"""The reactive layer's solver: the admissible velocity closest to the preferred one (compiled, SPEC §13).

The admissible set is an intersection of half-spaces ``n_i · v >= b_i`` (unit ``n_i``): the ORCA planes of every
track and the vehicle's own limits. The closest point to ``pref`` is found incrementally, as RVO2-3D's
``linearProgram3`` does (Seidel's randomized LP without the shuffle, so deterministic): constraints are taken in
order; when the optimum so far violates constraint i, the new optimum lies on plane i, found by the same
procedure in that plane over constraints 0..i-1 (a 2D problem whose sub-steps are 1D problems on the line where
two planes meet). Correct for any strictly convex objective; at most ``O(m^3)`` work for ``m`` constraints (a few
dozen here), no allocation.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

#: A constraint is violated when the velocity is this far (m/s) on its wrong side.
EPS_M_S = 1e-7


@njit(cache=True, fastmath=False)
def _solve_on_line(normals: np.ndarray, offsets: np.ndarray, i: int, j: int, pref: np.ndarray, out: np.ndarray) -> bool:
    """Closest point to ``pref`` on the line where planes i and j meet, within constraints 0..j-1 (j < i)."""
    ni0, ni1, ni2 = normals[i, 0], normals[i, 1], normals[i, 2]
    nj0, nj1, nj2 = normals[j, 0], normals[j, 1], normals[j, 2]
    d0 = ni1 * nj2 - ni2 * nj1
    d1 = ni2 * nj0 - ni0 * nj2
    d2 = ni0 * nj1 - ni1 * nj0
    dd = d0 * d0 + d1 * d1 + d2 * d2
    if dd < 1e-14:  # parallel planes: the line does not exist (plane i is inside j's bound or outside it)
        return False
    # a point on both planes: x0 = (b_i (n_j x d) + b_j (d x n_i)) / |d|^2
    bi, bj = offsets[i], offsets[j]
    c0 = bi * (nj1 * d2 - nj2 * d1) + bj * (d1 * ni2 - d2 * ni1)
    c1 = bi * (nj2 * d0 - nj0 * d2) + bj * (d2 * ni0 - d0 * ni2)
    c2 = bi * (nj0 * d1 - nj1 * d0) + bj * (d0 * ni1 - d1 * ni0)
    x0, x1, x2 = c0 / dd, c1 / dd, c2 / dd
    t_lo, t_hi = -math.inf, math.inf
    for k in range(j):
        nk0, nk1, nk2 = normals[k, 0], normals[k, 1], normals[k, 2]
        num = offsets[k] - (nk0 * x0 + nk1 * x1 + nk2 * x2)  # need den * t >= num
        den = nk0 * d0 + nk1 * d1 + nk2 * d2
        if abs(den) < 1e-12:
            if num > EPS_M_S:
                return False
            continue
        t = num / den
        if den > 0.0:
            t_lo = max(t_lo, t)
        else:
            t_hi = min(t_hi, t)
        if t_lo > t_hi + 1e-12:
            return False
    t = ((pref[0] - x0) * d0 + (pref[1] - x1) * d1 + (pref[2] - x2) * d2) / dd
    t = min(max(t, t_lo), t_hi)
    out[0], out[1], out[2] = x0 + t * d0, x1 + t * d1, x2 + t * d2
    return True


@njit(cache=True, fastmath=False)
def _solve_on_plane(normals: np.ndarray, offsets: np.ndarray, i: int, pref: np.ndarray, out: np.ndarray) -> bool:
    """Closest point to ``pref`` on plane i within constraints 0..i-1."""
    n0, n1, n2 = normals[i, 0], normals[i, 1], normals[i, 2]
    s = offsets[i] - (n0 * pref[0] + n1 * pref[1] + n2 * pref[2])
    out[0], out[1], out[2] = pref[0] + s * n0, pref[1] + s * n1, pref[2] + s * n2  # pref projected on the plane
    for j in range(i):
        violated = normals[j, 0] * out[0] + normals[j, 1] * out[1] + normals[j, 2] * out[2] < offsets[j] - EPS_M_S
        if violated and not _solve_on_line(normals, offsets, i, j, pref, out):
            return False
    return True


@njit(cache=True, fastmath=False)
def closest_admissible(normals: np.ndarray, offsets: np.ndarray, m: int, pref: np.ndarray, out: np.ndarray) -> int:
    """The velocity closest to ``pref`` with ``normals[i] · v >= offsets[i]`` for i < ``m``, written to ``out``.

    Returns -1 when it exists, else the index of the first constraint that made the set empty (``out`` then holds
    the optimum over the constraints before it)."""
    out[0], out[1], out[2] = pref[0], pref[1], pref[2]
    for i in range(m):
        if normals[i, 0] * out[0] + normals[i, 1] * out[1] + normals[i, 2] * out[2] < offsets[i] - EPS_M_S:
            keep0, keep1, keep2 = out[0], out[1], out[2]
            if not _solve_on_plane(normals, offsets, i, pref, out):
                out[0], out[1], out[2] = keep0, keep1, keep2
                return i
    return -1


@njit(cache=True, fastmath=False)
def _odd_perpendicular(v0: float, v1: float, v2: float) -> tuple[float, float, float]:
    """A unit direction across the relative velocity ``v`` that flips with it (f(-v) = -f(v)): right of its
    horizontal part (NED: right of north is east), or north/south for a purely vertical one. Two vehicles on a
    collision course see opposite relative velocities, so they move apart (both turn right: ICAO)."""
    h = math.hypot(v0, v1)
    if h > 1e-9:
        return -v1 / h, v0 / h, 0.0
    return (1.0, 0.0, 0.0) if v2 >= 0.0 else (-1.0, 0.0, 0.0)


#: Columns of the track rows ``orca_planes`` reads (one row per track, about home, NED).
T_PN, T_PE, T_PD, T_VN, T_VE, T_VD, T_TS, T_RADIUS, T_SCALE, T_RESP, T_TAU = range(11)
N_TRACK_COLS = 11
#: Already inside a volume: the ORCA plane asks to move apart at the rate that leaves it within this time (s) (RVO2
#: asks to be out after one time step; a quadrotor cannot jump, and inside the grown sphere is not yet inside the
#: volume).
RECOVER_S = 3.0
#: The acceleration a track may have used since its report (m/s^2): it is extrapolated along its velocity (and
#: intent), so its age hides at most 1/2 a t^2 of manoeuvre (a multirotor's 3 m/s^2; an aircraft turning at 15 deg
#: bank and 40 m/s: 2.6 m/s^2), or the closing speed's travel when that is less.
MANOEUVRE_M_S2 = 3.0


@njit(cache=True, fastmath=False)
def orca_planes(
    t_s: float,
    own_pos: np.ndarray,
    own_vel: np.ndarray,
    tracks: np.ndarray,
    k: int,
    grow_m: float,
    normals: np.ndarray,
    offsets: np.ndarray,
    m0: int,
    index: np.ndarray,
) -> int:
    """The ORCA half-space of each of the ``k`` tracks (rows of ``tracks``, columns ``T_*``) about the vehicle at
    ``own_pos`` with velocity ``own_vel``, appended to ``normals``/``offsets`` from row ``m0``; returns the new count.

    Each track's separation cylinder is covered by a sphere in a space whose vertical axis is stretched by
    ``T_SCALE`` (radius ``T_RADIUS`` there, grown by ``grow_m`` and by what the report's age hides:
    ``min(age x closing speed, MANOEUVRE_M_S2 age^2 / 2)``); the velocity obstacle of that sphere over the horizon
    ``T_TAU`` gives the plane as RVO2-3D computes it, the vehicle taking ``T_RESP`` of the change (0.5
    reciprocal, 1 full). The plane is mapped back to velocities in metres per second. A track out of reach within
    its horizon adds no plane; ``index[row]`` is the track of each plane added."""
    m = m0
    for r in range(k):
        c = tracks[r, T_SCALE]
        dt = t_s - tracks[r, T_TS]
        p0 = tracks[r, T_PN] + tracks[r, T_VN] * dt - own_pos[0]
        p1 = tracks[r, T_PE] + tracks[r, T_VE] * dt - own_pos[1]
        p2 = (tracks[r, T_PD] + tracks[r, T_VD] * dt - own_pos[2]) * c
        v0 = own_vel[0] - tracks[r, T_VN]
        v1 = own_vel[1] - tracks[r, T_VE]
        v2 = (own_vel[2] - tracks[r, T_VD]) * c
        speed = math.sqrt(v0 * v0 + v1 * v1 + v2 * v2)
        age = max(dt, 0.0)  # what the report's age hides: the closing speed's travel, or a manoeuvre since
        radius = tracks[r, T_RADIUS] + grow_m + min(age * speed, 0.5 * MANOEUVRE_M_S2 * age * age)
        tau = tracks[r, T_TAU]
        dist2 = p0 * p0 + p1 * p1 + p2 * p2
        reach = radius + (speed + 2.0 * math.sqrt(own_vel[0] ** 2 + own_vel[1] ** 2 + own_vel[2] ** 2) + 1.0) * tau
        if dist2 > reach * reach:
            continue
        r2 = radius * radius
        if dist2 > r2:
            inv_tau = 1.0 / tau
            w0, w1, w2 = v0 - inv_tau * p0, v1 - inv_tau * p1, v2 - inv_tau * p2
            wl2 = w0 * w0 + w1 * w1 + w2 * w2
            dot = w0 * p0 + w1 * p1 + w2 * p2
            if dot < 0.0 and dot * dot > r2 * wl2:  # the cut-off sphere's side
                wl = math.sqrt(wl2)
                if wl < 1e-9:
                    continue
                n0, n1, n2 = w0 / wl, w1 / wl, w2 / wl
                s = radius * inv_tau - wl
            else:  # the cone's side
                a = dist2
                b = p0 * v0 + p1 * v1 + p2 * v2
                x0, x1, x2 = p1 * v2 - p2 * v1, p2 * v0 - p0 * v2, p0 * v1 - p1 * v0
                cc = v0 * v0 + v1 * v1 + v2 * v2 - (x0 * x0 + x1 * x1 + x2 * x2) / (dist2 - r2)
                tt = (b + math.sqrt(max(b * b - a * cc, 0.0))) / a
                w0, w1, w2 = v0 - tt * p0, v1 - tt * p1, v2 - tt * p2
                wl = math.sqrt(w0 * w0 + w1 * w1 + w2 * w2)
                if wl < 1e-6 * (1.0 + speed):  # straight at the centre: the side is a convention both keep
                    n0, n1, n2 = _odd_perpendicular(v0, v1, v2)
                    s = speed * radius / math.sqrt(dist2)  # to the cone's surface
                else:
                    n0, n1, n2 = w0 / wl, w1 / wl, w2 / wl
                    s = radius * tt - wl
        else:  # inside already: move apart along the line of centres, fast enough to be out within RECOVER_S
            # (not RVO2's "out of the sphere after one step" taken over RECOVER_S: at a closing speed above
            # radius / RECOVER_S that is met by flying on through the other, out of its far side: search case 3)
            d = math.sqrt(dist2)
            n0, n1, n2 = (-p0 / d, -p1 / d, -p2 / d) if d > 1e-9 else (0.0, 0.0, -1.0)
            s = (radius - d) / RECOVER_S - (v0 * n0 + v1 * n1 + v2 * n2)
        resp = tracks[r, T_RESP]
        # the plane in the stretched space: n . (v' - (own' + resp s n)) >= 0, with v' = (vn, ve, c vd)
        q0 = own_vel[0] + resp * s * n0
        q1 = own_vel[1] + resp * s * n1
        q2 = own_vel[2] * c + resp * s * n2
        b = n0 * q0 + n1 * q1 + n2 * q2
        u2 = n2 * c
        norm = math.sqrt(n0 * n0 + n1 * n1 + u2 * u2)
        normals[m, 0], normals[m, 1], normals[m, 2] = n0 / norm, n1 / norm, u2 / norm
        offsets[m] = b / norm
        index[m] = r
        m += 1
    return m


@njit(cache=True, fastmath=False)
def least_violating(normals: np.ndarray, offsets: np.ndarray, m_hard: int, m: int, pref: np.ndarray,
                    scratch: np.ndarray, out: np.ndarray) -> float:  # fmt: skip
    """When no velocity meets every constraint: the velocity closest to ``pref`` that meets the first ``m_hard``
    (the vehicle's own limits, always feasible together) and violates the others (rows ``m_hard..m-1``) by the
    least common amount ``d`` (RVO2's fallback: minimise the largest penetration), found by bisection on ``d``;
    returns ``d`` (m/s)."""
    lo, hi = 0.0, 0.0
    for k in range(m_hard, m):
        hi = max(hi, offsets[k])
    hi = max(hi, 0.0) + 100.0
    for k in range(m):
        scratch[k] = offsets[k] - (hi if k >= m_hard else 0.0)
    closest_admissible(normals, scratch, m, pref, out)  # feasible at the upper bound
    best0, best1, best2 = out[0], out[1], out[2]
    for _ in range(30):
        mid = 0.5 * (lo + hi)
        for k in range(m_hard, m):
            scratch[k] = offsets[k] - mid
        if closest_admissible(normals, scratch, m, pref, out) < 0:
            hi = mid
            best0, best1, best2 = out[0], out[1], out[2]
        else:
            lo = mid
        if hi - lo < 1e-3:
            break
    out[0], out[1], out[2] = best0, best1, best2
    return hi
