"""Geometry for the avoidance planner (SPEC §7): intersections and signed distances in local NED.

Segments are ``a -> b`` (NED, metres); an intersection is returned as the entry and exit
fractions ``(t_in, t_out)`` of the segment (``0 <= t_in <= t_out <= 1``) or ``None``.
Signed distances are vectorised over points ``(n, 3)`` and negative inside the solid.
Vertical extents use NED ``down`` coordinates: ``top_down`` is the (more negative) upper cap,
``bottom_down`` the lower one; ``-inf``/``+inf`` mean unbounded.

Also the minimal fence zones (exclusion/inclusion circles and polygons, SPEC §8) the
planner checks a path against; any object with ``violates(pos_ned)`` and
``segment_clear(a, b, margin_m)`` (e.g. ``autopilot.geofence.fence`` zones) works too.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Protocol

import numpy as np

_EPS = 1e-12


def _clip_interval(t_in: float, t_out: float) -> tuple[float, float] | None:
    t_in, t_out = max(t_in, 0.0), min(t_out, 1.0)
    return (t_in, t_out) if t_in <= t_out else None


def segment_sphere_intersection(
    a: np.ndarray, b: np.ndarray, center_ned: np.ndarray, radius_m: float
) -> tuple[float, float] | None:
    """Fractions of segment a->b inside the sphere ``|x - c| <= r`` (solves the quadratic in t)."""
    d = np.asarray(b, float) - a
    f = np.asarray(a, float) - center_ned
    qa = float(d @ d)
    qb = 2.0 * float(f @ d)
    qc = float(f @ f) - radius_m * radius_m
    if qa < _EPS:
        return (0.0, 1.0) if qc <= 0.0 else None
    disc = qb * qb - 4.0 * qa * qc
    if disc < 0.0:
        return None
    s = math.sqrt(disc)
    return _clip_interval((-qb - s) / (2.0 * qa), (-qb + s) / (2.0 * qa))


def _slab(p0: float, dp: float, lo: float, hi: float, t_in: float, t_out: float) -> tuple[float, float]:
    """Liang-Barsky clip of one axis; returns an empty interval (1, 0) when outside."""
    if abs(dp) < _EPS:
        return (t_in, t_out) if lo <= p0 <= hi else (1.0, 0.0)
    t0, t1 = (lo - p0) / dp, (hi - p0) / dp
    if t0 > t1:
        t0, t1 = t1, t0
    return max(t_in, t0), min(t_out, t1)


def segment_box_intersection(
    a: np.ndarray, b: np.ndarray, center_ned: np.ndarray, half_size_m: np.ndarray, yaw_rad: float = 0.0
) -> tuple[float, float] | None:
    """Fractions of a->b inside a box rotated by ``yaw_rad`` about down (slab test in the box frame)."""
    c, s = math.cos(yaw_rad), math.sin(yaw_rad)
    ra = np.asarray(a, float) - center_ned
    rb = np.asarray(b, float) - center_ned
    # world -> box frame: rotate by -yaw about down
    pa = (c * ra[0] + s * ra[1], -s * ra[0] + c * ra[1], ra[2])
    pb = (c * rb[0] + s * rb[1], -s * rb[0] + c * rb[1], rb[2])
    t_in, t_out = 0.0, 1.0
    for k in range(3):
        h = float(half_size_m[k])
        t_in, t_out = _slab(pa[k], pb[k] - pa[k], -h, h, t_in, t_out)
        if t_in > t_out:
            return None
    return (t_in, t_out)


def segment_cylinder_intersection(
    a: np.ndarray,
    b: np.ndarray,
    center_ne: np.ndarray,
    radius_m: float,
    top_down: float = -math.inf,
    bottom_down: float = math.inf,
) -> tuple[float, float] | None:
    """Fractions of a->b inside a vertical cylinder (axis through ``center_ne``, caps at the downs)."""
    a = np.asarray(a, float)
    d = np.asarray(b, float) - a
    fx, fy = a[0] - center_ne[0], a[1] - center_ne[1]
    qa = d[0] * d[0] + d[1] * d[1]
    qc = fx * fx + fy * fy - radius_m * radius_m
    if qa < _EPS:
        if qc > 0.0:
            return None
        t_in, t_out = 0.0, 1.0
    else:
        qb = 2.0 * (fx * d[0] + fy * d[1])
        disc = qb * qb - 4.0 * qa * qc
        if disc < 0.0:
            return None
        sq = math.sqrt(disc)
        t_in, t_out = (-qb - sq) / (2.0 * qa), (-qb + sq) / (2.0 * qa)
    t_in, t_out = _slab(float(a[2]), float(d[2]), top_down, bottom_down, max(t_in, 0.0), min(t_out, 1.0))
    return (t_in, t_out) if t_in <= t_out else None


def sphere_signed_distance(points_ned: np.ndarray, center_ned: np.ndarray, radius_m: float) -> np.ndarray:
    """Signed distance of points ``(n, 3)`` to a sphere surface (negative inside)."""
    return np.linalg.norm(np.asarray(points_ned, float) - center_ned, axis=-1) - radius_m


def cylinder_signed_distance(
    points_ned: np.ndarray,
    center_ne: np.ndarray,
    radius_m: float,
    top_down: float = -math.inf,
    bottom_down: float = math.inf,
) -> np.ndarray:
    """Signed distance of points ``(n, 3)`` to a vertical capped cylinder (exact, negative inside)."""
    p = np.asarray(points_ned, float)
    dr = np.hypot(p[..., 0] - center_ne[0], p[..., 1] - center_ne[1]) - radius_m
    mid = 0.5 * (top_down + bottom_down) if math.isfinite(top_down + bottom_down) else None
    if mid is None:
        dz = np.maximum(top_down - p[..., 2], p[..., 2] - bottom_down)
    else:
        dz = np.abs(p[..., 2] - mid) - 0.5 * (bottom_down - top_down)
    outside = np.hypot(np.maximum(dr, 0.0), np.maximum(dz, 0.0))
    return outside + np.minimum(np.maximum(dr, dz), 0.0)


def box_signed_distance(
    points_ned: np.ndarray, center_ned: np.ndarray, half_size_m: np.ndarray, yaw_rad: float = 0.0
) -> np.ndarray:
    """Signed distance of points ``(n, 3)`` to a box rotated by ``yaw_rad`` about down (exact)."""
    p = np.asarray(points_ned, float) - center_ned
    c, s = math.cos(yaw_rad), math.sin(yaw_rad)
    q = np.stack((c * p[..., 0] + s * p[..., 1], -s * p[..., 0] + c * p[..., 1], p[..., 2]), axis=-1)
    q = np.abs(q) - half_size_m
    outside = np.linalg.norm(np.maximum(q, 0.0), axis=-1)
    return outside + np.minimum(np.max(q, axis=-1), 0.0)


def closest_point_on_segment(a: np.ndarray, b: np.ndarray, p: np.ndarray) -> tuple[np.ndarray, float]:
    """The point of segment a->b nearest to p and its fraction t in [0, 1]."""
    d = b - a
    dd = float(d @ d)
    t = 0.0 if dd < _EPS else min(max(float((p - a) @ d) / dd, 0.0), 1.0)
    return a + t * d, t


def point_segment_distance(a: np.ndarray, b: np.ndarray, p: np.ndarray) -> float:
    """Euclidean distance from p to segment a->b."""
    q, _ = closest_point_on_segment(a, b, p)
    return float(np.linalg.norm(p - q))


def polyline_length(points: np.ndarray) -> float:
    """Total length of a polyline ``(n, 3)``."""
    return float(np.linalg.norm(np.diff(points, axis=0), axis=1).sum())


# ----------------------------------------------------------------------------------------- fences


class FenceZone(Protocol):
    """What the planner needs of a geofence zone (``autopilot.geofence.fence`` zones satisfy it)."""

    def violates(self, pos_ned: np.ndarray) -> bool: ...

    def segment_clear(self, a: np.ndarray, b: np.ndarray, margin_m: float) -> bool: ...


def _segment_segment_distance_2d(p1: np.ndarray, p2: np.ndarray, q1: np.ndarray, q2: np.ndarray) -> float:
    """Distance between 2D segments p1p2 and q1q2 (0 when they cross)."""

    def cross(o: np.ndarray, u: np.ndarray, v: np.ndarray) -> float:
        return float((u[0] - o[0]) * (v[1] - o[1]) - (u[1] - o[1]) * (v[0] - o[0]))

    d1, d2 = cross(q1, q2, p1), cross(q1, q2, p2)
    d3, d4 = cross(p1, p2, q1), cross(p1, p2, q2)
    if d1 * d2 < 0.0 and d3 * d4 < 0.0:
        return 0.0
    return min(
        point_segment_distance(q1, q2, p1),
        point_segment_distance(q1, q2, p2),
        point_segment_distance(p1, p2, q1),
        point_segment_distance(p1, p2, q2),
    )


@dataclass(frozen=True, slots=True)
class CircleZone:
    """A fence circle in the horizontal plane (all altitudes): exclusion keeps out, inclusion keeps in."""

    center_ne: tuple[float, float]
    radius_m: float
    inclusion: bool = False

    def violates(self, pos_ned: np.ndarray) -> bool:
        inside = math.hypot(pos_ned[0] - self.center_ne[0], pos_ned[1] - self.center_ne[1]) <= self.radius_m
        return inside != self.inclusion

    def segment_clear(self, a: np.ndarray, b: np.ndarray, margin_m: float) -> bool:
        c = np.array(self.center_ne)
        if self.inclusion:  # the farthest point of a segment from c is an endpoint
            r_a, r_b = np.linalg.norm(a[:2] - c), np.linalg.norm(b[:2] - c)
            return max(r_a, r_b) <= self.radius_m - margin_m
        return point_segment_distance(a[:2], b[:2], c) > self.radius_m + margin_m

    def path_clear(self, points_ned: np.ndarray, margin_m: float) -> bool:
        """Vectorised ``segment_clear`` over consecutive points of a path ``(n, 3)``."""
        p = np.asarray(points_ned, float)[:, :2] - np.array(self.center_ne)
        if self.inclusion:
            return bool(np.all(np.hypot(p[:, 0], p[:, 1]) <= self.radius_m - margin_m))
        a, d = p[:-1], np.diff(p, axis=0)
        dd = np.maximum(np.einsum("ij,ij->i", d, d), _EPS)
        t = np.clip(-np.einsum("ij,ij->i", a, d) / dd, 0.0, 1.0)
        closest = a + t[:, None] * d
        return bool(np.all(np.hypot(closest[:, 0], closest[:, 1]) > self.radius_m + margin_m))


@dataclass(frozen=True, slots=True)
class PolygonZone:
    """A fence polygon of ``(north_m, east_m)`` vertices (any simple polygon), all altitudes."""

    vertices_ne: tuple[tuple[float, float], ...]
    inclusion: bool = False

    def _inside(self, p: np.ndarray) -> bool:
        inside = False
        v = self.vertices_ne
        for i in range(len(v)):
            (y1, x1), (y2, x2) = v[i], v[(i + 1) % len(v)]
            if (x1 > p[1]) != (x2 > p[1]) and p[0] < y1 + (p[1] - x1) * (y2 - y1) / (x2 - x1):
                inside = not inside
        return inside

    def violates(self, pos_ned: np.ndarray) -> bool:
        return self._inside(np.asarray(pos_ned, float)[:2]) != self.inclusion

    def segment_clear(self, a: np.ndarray, b: np.ndarray, margin_m: float) -> bool:
        a2, b2 = np.asarray(a, float)[:2], np.asarray(b, float)[:2]
        if self.violates(a) or self.violates(b):
            return False
        v = np.array(self.vertices_ne, float)
        edge_gap = min(_segment_segment_distance_2d(a2, b2, v[i], v[(i + 1) % len(v)]) for i in range(len(v)))
        return edge_gap > margin_m

    def path_clear(self, points_ned: np.ndarray, margin_m: float) -> bool:
        """``segment_clear`` over a path ``(n, 3)``, skipping it when bounding boxes are apart."""
        p = np.asarray(points_ned, float)[:, :2]
        v = np.array(self.vertices_ne, float)
        if not self.inclusion and (
            np.any(p.min(axis=0) > v.max(axis=0) + margin_m) or np.any(p.max(axis=0) < v.min(axis=0) - margin_m)
        ):
            return True
        return all(self.segment_clear(p[i], p[i + 1], margin_m) for i in range(len(p) - 1))


def path_clear_of_fences(zones: tuple[FenceZone, ...], points_ned: np.ndarray, margin_m: float) -> FenceZone | None:
    """The first zone a sampled path ``(n, 3)`` violates (within ``margin_m``), else None."""
    for zone in zones:
        fast = getattr(zone, "path_clear", None)
        if fast is not None:
            if not fast(points_ned, margin_m):
                return zone
            continue
        for i in range(len(points_ned) - 1):
            if not zone.segment_clear(points_ned[i], points_ned[i + 1], margin_m):
                return zone
    return None
