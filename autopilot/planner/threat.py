"""Threat assessment (paper §3.3): which tracked obstacle's safety volume the vehicle will enter first.

Every obstacle is inflated by the safety radius R_safe (sphere Ω of radius r + R_safe, or a
column of radius r + R_safe). Two paths are checked ahead of the vehicle, both cut at the
look-ahead distance: the route polyline (position → current target → next target) and the ray
along the velocity direction. The *largest threat* is the most imminent conflict: the obstacle
whose inflated volume is entered after the shortest distance along either path.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from mavlink_bridge.contract.frames import Vec3

from .geometry import segment_cylinder_intersection, segment_sphere_intersection
from .obstacle_map import ObstacleArrays, ObstacleKind, TrackedObstacle, row_signed_distance


@dataclass(frozen=True, slots=True)
class Threat:
    """The obstacle the vehicle meets first: distance along the path to the inflated volume's entry."""

    obstacle: TrackedObstacle
    entry_distance_m: float  # along the checked path, from the vehicle
    surface_distance_m: float  # straight-line distance from the vehicle to the obstacle surface
    time_to_contact_s: float  # entry distance over current speed (inf when hovering)
    on_route: bool  # found on the route polyline (else on the velocity ray)


Row = tuple[int, float, float, float, float, bool, float]


def _entry_fraction(row: Row, a: Vec3, b: Vec3, inflate_m: float) -> float | None:
    """Fraction of segment a->b where it enters the obstacle inflated by ``inflate_m`` (None: never).

    Sphere: roots of ``|a + t(b − a) − c|² = (r + inflate)²``; column: the same in the horizontal
    plane, then clipped to the part below its top raised by ``inflate`` (Liang–Barsky on down).
    """
    _, cx, cy, cz, r, sphere, top = row
    rr = r + inflate_m
    dx, dy, dz = b[0] - a[0], b[1] - a[1], b[2] - a[2]
    fx, fy, fz = a[0] - cx, a[1] - cy, a[2] - cz
    if sphere:
        qa, qb, qc = dx * dx + dy * dy + dz * dz, 2.0 * (fx * dx + fy * dy + fz * dz), fx * fx + fy * fy + fz * fz
    else:
        qa, qb, qc = dx * dx + dy * dy, 2.0 * (fx * dx + fy * dy), fx * fx + fy * fy
    qc -= rr * rr
    if qa < 1e-12:
        if qc > 0.0:
            return None
        t_in, t_out = 0.0, 1.0
    else:
        disc = qb * qb - 4.0 * qa * qc
        if disc < 0.0:
            return None
        sq = math.sqrt(disc)
        t_in, t_out = max((-qb - sq) / (2.0 * qa), 0.0), min((-qb + sq) / (2.0 * qa), 1.0)
    if not sphere and top - inflate_m > -math.inf:  # below the raised top: down >= top - inflate
        lo = top - inflate_m
        if abs(dz) < 1e-12:
            if a[2] < lo:
                return None
        elif dz > 0.0:
            t_in = max(t_in, (lo - a[2]) / dz)
        else:
            t_out = min(t_out, (lo - a[2]) / dz)
    return t_in if t_in <= t_out else None


def inflated_segment_hit(
    obstacle: TrackedObstacle, a: np.ndarray, b: np.ndarray, inflate_m: float
) -> tuple[float, float] | None:
    """Fractions of segment a->b inside the obstacle inflated by ``inflate_m``."""
    r = obstacle.radius_m + inflate_m
    if obstacle.kind is ObstacleKind.SPHERE:
        return segment_sphere_intersection(a, b, np.array(obstacle.center_ned), r)
    return segment_cylinder_intersection(a, b, np.array(obstacle.center_ned[:2]), r, obstacle.top_down - inflate_m)


def _truncate(points: list[Vec3], length_m: float) -> list[Vec3]:
    """The first ``length_m`` metres of a polyline."""
    out = [points[0]]
    left = length_m
    for a, b in itertools.pairwise(points):
        seg = math.dist(a, b)
        if seg >= left:
            f = left / max(seg, 1e-12)
            out.append((a[0] + (b[0] - a[0]) * f, a[1] + (b[1] - a[1]) * f, a[2] + (b[2] - a[2]) * f))
            break
        out.append(b)
        left -= seg
    return out


def truncate_polyline(points: np.ndarray, length_m: float) -> np.ndarray:
    """The first ``length_m`` metres of a polyline ``(n, 3)``."""
    return np.array(_truncate([tuple(p) for p in np.asarray(points, float).tolist()], length_m))


def _first_conflict(points: list[Vec3], rows: Sequence[Row], inflate_m: float) -> tuple[int, float] | None:
    """(row index, entry arc length) of the first inflated volume a polyline enters, else None."""
    best: tuple[int, float] | None = None
    s0 = 0.0
    for a, b in itertools.pairwise(points):
        seg = math.dist(a, b)
        for k, row in enumerate(rows):
            t = _entry_fraction(row, a, b, inflate_m)
            if t is not None and (best is None or s0 + t * seg < best[1]):
                best = (k, s0 + t * seg)
        if best is not None:
            return best
        s0 += seg
    return None


def first_conflict(
    points: np.ndarray, obstacles: Sequence[TrackedObstacle], inflate_m: float
) -> tuple[TrackedObstacle, float] | None:
    """The obstacle whose inflated volume a polyline enters first, with the arc length of the entry."""
    arrays = ObstacleArrays(tuple(obstacles))
    hit = _first_conflict([tuple(p) for p in np.asarray(points, float).tolist()], arrays.rows, inflate_m)
    return None if hit is None else (arrays.obstacles[hit[0]], hit[1])


def assess_threat(
    pos_ned: np.ndarray,
    vel_ned: np.ndarray,
    route_ned: np.ndarray,
    obstacles: Sequence[TrackedObstacle] | ObstacleArrays,
    r_safe_m: float,
    lookahead_m: float,
    ray_m: float | None = None,
) -> Threat | None:
    """The largest (most imminent) threat on the route or along the velocity, or None if both are clear.

    The route is checked for ``lookahead_m``, the velocity ray for ``ray_m`` (default the same).
    Scalar Python: a few segments against a few obstacles, every control step.
    """
    arrays = obstacles if isinstance(obstacles, ObstacleArrays) else ObstacleArrays(tuple(obstacles))
    if not len(arrays):
        return None
    p = np.asarray(pos_ned, float).tolist()
    v = np.asarray(vel_ned, float).tolist()
    pos: Vec3 = (p[0], p[1], p[2])
    route = [pos] + [(q[0], q[1], q[2]) for q in np.asarray(route_ned, float).reshape(-1, 3).tolist()]
    on_route = _first_conflict(_truncate(route, lookahead_m), arrays.rows, r_safe_m)
    speed = math.sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2])
    on_ray = None
    if speed > 0.3:
        f = (lookahead_m if ray_m is None else ray_m) / speed
        on_ray = _first_conflict(
            [pos, (pos[0] + v[0] * f, pos[1] + v[1] * f, pos[2] + v[2] * f)], arrays.rows, r_safe_m
        )
    hits = [(h, True) for h in (on_route,) if h] + [(h, False) for h in (on_ray,) if h]
    if not hits:
        return None
    (k, entry), route_hit = min(hits, key=lambda x: x[0][1])
    obs = arrays.obstacles[k]
    surface = row_signed_distance(arrays.rows[k], pos)
    ttc = entry / speed if speed > 1e-3 else math.inf
    return Threat(obs, entry, surface, ttc, route_hit)
