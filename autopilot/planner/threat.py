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

from .geometry import segment_cylinder_intersection, segment_sphere_intersection
from .obstacle_map import ObstacleKind, TrackedObstacle


@dataclass(frozen=True, slots=True)
class Threat:
    """The obstacle the vehicle meets first: distance along the path to the inflated volume's entry."""

    obstacle: TrackedObstacle
    entry_distance_m: float  # along the checked path, from the vehicle
    surface_distance_m: float  # straight-line distance from the vehicle to the obstacle surface
    time_to_contact_s: float  # entry distance over current speed (inf when hovering)
    on_route: bool  # found on the route polyline (else on the velocity ray)


def inflated_segment_hit(
    obstacle: TrackedObstacle, a: np.ndarray, b: np.ndarray, inflate_m: float
) -> tuple[float, float] | None:
    """Fractions of segment a->b inside the obstacle inflated by ``inflate_m``."""
    r = obstacle.radius_m + inflate_m
    if obstacle.kind is ObstacleKind.SPHERE:
        return segment_sphere_intersection(a, b, np.array(obstacle.center_ned), r)
    return segment_cylinder_intersection(a, b, np.array(obstacle.center_ned[:2]), r, obstacle.top_down - inflate_m)


def truncate_polyline(points: np.ndarray, length_m: float) -> np.ndarray:
    """The first ``length_m`` metres of a polyline ``(n, 3)``."""
    out = [points[0]]
    left = length_m
    for a, b in itertools.pairwise(points):
        seg = float(np.linalg.norm(b - a))
        if seg >= left:
            out.append(a + (b - a) * (left / max(seg, 1e-12)))
            break
        out.append(b)
        left -= seg
    return np.array(out)


def first_conflict(
    points: np.ndarray, obstacles: Sequence[TrackedObstacle], inflate_m: float
) -> tuple[TrackedObstacle, float] | None:
    """The obstacle whose inflated volume a polyline enters first, with the arc length of the entry."""
    best: tuple[TrackedObstacle, float] | None = None
    s0 = 0.0
    for a, b in itertools.pairwise(points):
        seg = float(np.linalg.norm(b - a))
        for obs in obstacles:
            hit = inflated_segment_hit(obs, a, b, inflate_m)
            if hit is not None and (best is None or s0 + hit[0] * seg < best[1]):
                best = (obs, s0 + hit[0] * seg)
        if best is not None:
            return best
        s0 += seg
    return None


def assess_threat(
    pos_ned: np.ndarray,
    vel_ned: np.ndarray,
    route_ned: np.ndarray,
    obstacles: Sequence[TrackedObstacle],
    r_safe_m: float,
    lookahead_m: float,
    ray_m: float | None = None,
) -> Threat | None:
    """The largest (most imminent) threat on the route or along the velocity, or None if both are clear.

    The route is checked for ``lookahead_m``, the velocity ray for ``ray_m`` (default the same).
    """
    if not obstacles:
        return None
    route = truncate_polyline(np.vstack((pos_ned, route_ned)), lookahead_m)
    on_route = first_conflict(route, obstacles, r_safe_m)
    speed = float(np.linalg.norm(vel_ned))
    on_ray = None
    if speed > 0.3:
        ray_len = lookahead_m if ray_m is None else ray_m
        ray = np.vstack((pos_ned, pos_ned + vel_ned * (ray_len / speed)))
        on_ray = first_conflict(ray, obstacles, r_safe_m)
    hits = [(h, True) for h in (on_route,) if h] + [(h, False) for h in (on_ray,) if h]
    if not hits:
        return None
    (obs, entry), route_hit = min(hits, key=lambda x: x[0][1])
    surface = float(obs.signed_distance(np.asarray(pos_ned, float)[None, :])[0])
    ttc = entry / speed if speed > 1e-3 else math.inf
    return Threat(obs, entry, surface, ttc, route_hit)
