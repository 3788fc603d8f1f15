"""The detour's path checks: a candidate polyline or a sampled curve against the obstacles, altitudes and fences.

A polyline is checked exactly, segment by segment, against every tracked obstacle's clearance
(:func:`polyline_blocker`) and by the altitude band's rules (:func:`altitude_rule`); a sampled curve
(:func:`check_path`) against every obstacle's R_safe volume, the altitude band and the fences.
"""

from __future__ import annotations

import math
from collections.abc import Collection, Sequence

import numpy as np

from .detour_geometry import V3, seg_distance
from .detour_types import DetourLimits
from .geometry import path_clear_of_fences
from .obstacle_map import ObstacleArrays, TrackedObstacle, row_signed_distance
from .path_shapes import SAMPLE_STEP_M

#: ``ObstacleArrays.rows``: (id, north, east, down, radius, is_sphere, top_down).
Row = tuple[int, float, float, float, float, bool, float]
Obstacles = Sequence[TrackedObstacle] | ObstacleArrays


def as_arrays(obstacles: Obstacles) -> ObstacleArrays:
    """The obstacles as :class:`ObstacleArrays` (passed through when they already are)."""
    return obstacles if isinstance(obstacles, ObstacleArrays) else ObstacleArrays(tuple(obstacles))


def path_clearance(samples_ned: np.ndarray, obstacles: Obstacles) -> tuple[float, int]:
    """Smallest surface distance of the samples to any obstacle, and that obstacle's id (-1 if none)."""
    arrays = as_arrays(obstacles)
    if not len(arrays):
        return math.inf, -1
    per_obstacle = arrays.signed_distance(samples_ned).min(axis=0)
    i = int(per_obstacle.argmin())
    return float(per_obstacle[i]), int(arrays.ids[i])


def clearance_need(start: V3, arrays: ObstacleArrays, clearance_m: float) -> list[float]:
    """Clearance each obstacle must keep along a path from ``start``: ``clearance_m``, or for an obstacle already
    nearer than that at the start, not nearer than it is now (less 5 cm)."""
    return [min(clearance_m, row_signed_distance(row, start) - 0.05) for row in arrays.rows]


def check_samples(
    samples_ned: np.ndarray,
    need: list[float],
    arrays: ObstacleArrays,
    limits: DetourLimits,
    near: list[int] | None = None,
) -> tuple[str, float]:
    """``check_path``'s verdict (``need``: per-obstacle clearance) and the samples' smallest clearance (inf: none).

    ``near``: indices of the only obstacles that can come within reach (the others are not evaluated).
    """
    clearance = math.inf
    index = list(range(len(arrays))) if near is None else near
    if index:
        per_obstacle = arrays.signed_distance(samples_ned, near).min(axis=0).tolist()
        clearance = min(per_obstacle)
        short, worst = min((d - need[k], k) for d, k in zip(per_obstacle, index, strict=True))
        if short < 0.0:
            return f"obstacle {arrays.rows[worst][0]}", clearance
    down = samples_ned[:, 2]
    if -float(down.max()) < max(limits.min_agl_m, limits.alt_floor_m) - 1e-6:
        return ("ground" if limits.min_agl_m >= limits.alt_floor_m else "altitude floor"), clearance
    if -float(down.min()) > limits.alt_ceiling_m + 1e-6:
        return "ceiling", clearance
    if limits.fences and path_clear_of_fences(limits.fences, samples_ned, 0.0) is not None:
        return "fence", clearance
    return "", clearance


def near_hull(ctrl_ned: np.ndarray, rows: Sequence[Row], reach_m: Sequence[float]) -> list[int]:
    """Indices of the obstacles within ``reach_m`` of the bounding box of a Bézier chain's control points
    (the curve lies in their convex hull, so the others are farther than their reach from every point of it)."""
    pts = ctrl_ned.reshape(-1, 3)
    (x0, y0, z0), (x1, y1, z1) = pts.min(axis=0).tolist(), pts.max(axis=0).tolist()
    near = []
    for k, (_, cx, cy, cz, r, sphere, _top) in enumerate(rows):
        reach = r + reach_m[k]
        in_plane = x0 - reach <= cx <= x1 + reach and y0 - reach <= cy <= y1 + reach
        if in_plane and (not sphere or z0 - reach <= cz <= z1 + reach):
            near.append(k)
    return near


def check_path(
    samples_ned: np.ndarray,
    start_ned: np.ndarray,
    obstacles: Obstacles,
    limits: DetourLimits,
    tol_m: float = 0.5 * SAMPLE_STEP_M,
    obstacle_ids: Collection[int] | None = None,
) -> str:
    """Why a sampled path is unsafe ("" when it is safe).

    Clearance to every obstacle (or only to those in ``obstacle_ids``, e.g. the ones that changed since the
    path was last checked) must be >= R_safe + ``tol_m`` (default half the sample spacing: points between
    two samples are within that of one); an obstacle already nearer than that at the start must not get
    nearer. Altitudes stay in [max(min AGL, floor), ceiling]; fences are checked per segment.
    """
    arrays = as_arrays(obstacles)
    start = np.asarray(start_ned, float).tolist()
    need = clearance_need((start[0], start[1], start[2]), arrays, limits.r_safe_m + tol_m)
    near = None if obstacle_ids is None else [k for k, row in enumerate(arrays.rows) if row[0] in obstacle_ids]
    return check_samples(np.asarray(samples_ned, float), need, arrays, limits, near)[0]


def polyline_blocker(points: Sequence[V3], rows: Sequence[Row], need: Sequence[float]) -> int:
    """Id of the obstacle whose clearance along the polyline falls furthest below ``need`` (-1: none).

    Exact per segment (sphere: 3D segment distance; column: horizontal, skipped where the segment
    passes ``need`` above a known top); obstacles out of reach of the polyline's bounding box are skipped.
    """
    xs, ys, zs = [p[0] for p in points], [p[1] for p in points], [p[2] for p in points]
    x0, x1, y0, y1, z0, z1 = min(xs), max(xs), min(ys), max(ys), min(zs), max(zs)
    worst, worst_id = 0.0, -1
    for k, row in enumerate(rows):
        oid, cx, cy, cz, r, sphere, top = row
        reach = r + need[k]
        if cx < x0 - reach or cx > x1 + reach or cy < y0 - reach or cy > y1 + reach:
            continue
        if sphere and (cz < z0 - reach or cz > z1 + reach):
            continue
        c = (cx, cy, cz)
        for i in range(len(points) - 1):
            a, b = points[i], points[i + 1]
            if not sphere and max(a[2], b[2]) < top - need[k]:
                continue
            short = reach - seg_distance(a, b, c, not sphere)[0]
            if short > worst:
                worst, worst_id = short, oid
    return worst_id


def altitude_rule(points: Sequence[V3], limits: DetourLimits) -> str:
    """The altitude rule a polyline breaks ("ground", "altitude floor", "ceiling"; "" when none)."""
    alt_lo, alt_hi = -max(p[2] for p in points), -min(p[2] for p in points)
    if alt_lo < max(limits.min_agl_m, 0.0) - 1e-9:
        return "ground"
    if alt_lo < limits.alt_floor_m - 1e-9:
        return "altitude floor"
    if alt_hi > limits.alt_ceiling_m + 1e-9:
        return "ceiling"
    return ""
