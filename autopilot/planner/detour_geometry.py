"""Plain-Python geometry of the detour search (numpy's per-call overhead dominates on a handful of points).

The route ahead as a polyline by arc length, the distance from a point to a segment, and a side's
tangent–arc–tangent polyline: in the plane through the obstacle centre spanned by the horizontal route
direction ``e1`` and the side direction ``e2`` (up/down for over/under, right/left for the sides), the shortest
path from the vehicle to the rejoin point around the circle of radius ``ρ``, with the third coordinate
interpolated linearly from the vehicle to the rejoin point.
"""

from __future__ import annotations

import itertools
import math

from .detour_types import DetourSide

_ARC_STEP_RAD = math.radians(30.0)

V3 = tuple[float, float, float]


def seg_distance(a: V3, b: V3, c: V3, planar: bool) -> tuple[float, float]:
    """Distance from point c to segment a->b (horizontal only when ``planar``) and the closest fraction t."""
    dx, dy = b[0] - a[0], b[1] - a[1]
    fx, fy = c[0] - a[0], c[1] - a[1]
    if planar:
        dd = dx * dx + dy * dy
        t = 0.0 if dd < 1e-12 else min(max((fx * dx + fy * dy) / dd, 0.0), 1.0)
        return math.hypot(fx - t * dx, fy - t * dy), t
    dz, fz = b[2] - a[2], c[2] - a[2]
    dd = dx * dx + dy * dy + dz * dz
    t = 0.0 if dd < 1e-12 else min(max((fx * dx + fy * dy + fz * dz) / dd, 0.0), 1.0)
    ex, ey, ez = fx - t * dx, fy - t * dy, fz - t * dz
    return math.sqrt(ex * ex + ey * ey + ez * ez), t


class RoutePolyline:
    """The route ahead as a polyline (vehicle first) with cumulative arc lengths."""

    def __init__(self, points: list[V3]) -> None:
        self.points = points
        self.cum = [0.0]
        for a, b in itertools.pairwise(points):
            self.cum.append(self.cum[-1] + math.dist(a, b))

    def first_pass(self, center: V3, planar: bool, rho: float) -> float:
        """Arc length of the point nearest ``center`` on the route's first pass within ``rho`` of it.

        A pass is a run of consecutive segments within ``rho``; the nearest point over the whole
        route is the fallback when no segment comes that close.
        """
        best_d, best_s = math.inf, 0.0
        pass_d, pass_s = math.inf, -1.0
        pts, cum = self.points, self.cum
        for i in range(len(pts) - 1):
            d, t = seg_distance(pts[i], pts[i + 1], center, planar)
            s = cum[i] + t * (cum[i + 1] - cum[i])
            if d < best_d:
                best_d, best_s = d, s
            if d <= rho:
                if d < pass_d:
                    pass_d, pass_s = d, s
            elif pass_s >= 0.0:
                break
        return pass_s if pass_s >= 0.0 else best_s

    def at(self, s_m: float) -> tuple[V3, V3, int]:
        """Point at arc length ``s_m`` (clamped to the ends), the unit direction there and the segment index."""
        pts, cum = self.points, self.cum
        s_m = max(s_m, 0.0)
        direction, index = (1.0, 0.0, 0.0), 0
        for i in range(len(pts) - 1):
            seg = cum[i + 1] - cum[i]
            if seg < 1e-9:
                continue
            a, b = pts[i], pts[i + 1]
            direction, index = ((b[0] - a[0]) / seg, (b[1] - a[1]) / seg, (b[2] - a[2]) / seg), i
            if s_m <= cum[i + 1]:
                t = (s_m - cum[i]) / seg
                return (a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1]), a[2] + t * (b[2] - a[2])), direction, i
        return pts[-1], direction, index

    def stretch(self, s_from: float, length_m: float) -> list[V3]:
        """The route polyline from arc length ``s_from`` for ``length_m`` (clamped to its end)."""
        start, _, i = self.at(s_from)
        out = [start]
        s_end = s_from + length_m
        for j in range(i + 1, len(self.points)):
            if self.cum[j] >= s_end:
                out.append(self.at(s_end)[0])
                return out
            out.append(self.points[j])
        return out


def _tangent_angle(pu: float, pw: float, rho: float) -> float:
    """Angle of the tangent point from p to the circle |x| = ρ on the +w side (radial if inside)."""
    d = math.hypot(pu, pw)
    alpha = math.atan2(pw, pu)
    if d <= rho:
        return alpha
    beta = math.acos(rho / d)
    a1, a2 = alpha + beta, alpha - beta
    return a1 if math.sin(a1) >= math.sin(a2) else a2


def _arc_polyline_uw(
    p: tuple[float, float], j: tuple[float, float], rho: float
) -> tuple[list[tuple[float, float]], float]:
    """Tangent–arc–tangent from p to j passing the circle on the +w side: via points (u, w) and length."""
    two_pi = 2.0 * math.pi
    th_p = _tangent_angle(p[0], p[1], rho) % two_pi
    th_j = _tangent_angle(j[0], j[1], rho) % two_pi
    # angles measured so that moving from p (behind, u < 0) to j (ahead) decreases θ through π/2
    if th_j > th_p:
        th_j -= two_pi
    sweep = th_p - th_j
    if sweep > math.pi * 1.5 or (p[1] >= rho and j[1] >= rho):
        return [], math.dist(p, j)  # the straight line already clears
    n = max(1, math.ceil(sweep / _ARC_STEP_RAD))
    step = sweep / n
    r_via = rho / math.cos(step / 2.0)  # circumscribed polygon: its chords stay outside ρ
    via = [(r_via * math.cos(th_p - step * i), r_via * math.sin(th_p - step * i)) for i in range(n + 1)]
    chord = 2.0 * r_via * math.sin(step / 2.0)
    return via, math.dist(p, via[0]) + n * chord + math.dist(via[-1], j)


def _side_axes(side: DetourSide, e1: V3) -> tuple[V3, V3]:
    """The side direction e2 and the normal e3 = e1 × e2 of a candidate's plane (e1 horizontal)."""
    ex, ey = e1[0], e1[1]
    if side is DetourSide.OVER:
        return (0.0, 0.0, -1.0), (-ey, ex, 0.0)
    if side is DetourSide.UNDER:
        return (0.0, 0.0, 1.0), (ey, -ex, 0.0)
    if side is DetourSide.RIGHT:
        return (-ey, ex, 0.0), (0.0, 0.0, 1.0)
    return (ey, -ex, 0.0), (0.0, 0.0, -1.0)


def side_polyline(side: DetourSide, pos: V3, rejoin: V3, center_ned: V3, e1: V3, rho: float) -> tuple[list[V3], float]:
    """The tangent–arc–tangent polyline from ``pos`` to ``rejoin`` past ``center_ned`` on one side, and its length."""
    e2, e3 = _side_axes(side, e1)
    c = center_ned
    rp = (pos[0] - c[0], pos[1] - c[1], pos[2] - c[2])
    rj = (rejoin[0] - c[0], rejoin[1] - c[1], rejoin[2] - c[2])
    p_l = tuple(e[0] * rp[0] + e[1] * rp[1] + e[2] * rp[2] for e in (e1, e2, e3))
    j_l = tuple(e[0] * rj[0] + e[1] * rj[1] + e[2] * rj[2] for e in (e1, e2, e3))
    via_uw, length = _arc_polyline_uw((p_l[0], p_l[1]), (j_l[0], j_l[1]), rho)
    du = j_l[0] - p_l[0]
    points = [pos]
    for u, w in via_uw:
        frac = min(max((u - p_l[0]) / du, 0.0), 1.0) if abs(du) > 1e-9 else 0.5
        t3 = p_l[2] + frac * (j_l[2] - p_l[2])
        points.append(tuple(c[k] + u * e1[k] + w * e2[k] + t3 * e3[k] for k in range(3)))
    points.append(rejoin)
    return points, length
