"""Whether a mission waypoint can be reached safely (SPEC §7, issue 22): the one rule the detour and the
navigator share.

A waypoint outside every tracked obstacle's safety volume (``CA_RSAFE_M`` from its surface) and outside the
fence margin (``CA_FENCE_MARG_M`` from every fence boundary, on the allowed side) is *reachable*: a detour
rejoins the route at it and the vehicle reaches it within its acceptance radius. Only an unreachable one may
be bypassed, and the reason this module gives is the one reported (``Bypassed item 4: ...``).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from .geometry import FenceZone
from .obstacle_map import ObstacleArrays, TrackedObstacle


def unreachable_reason(
    point_ned: Sequence[float] | np.ndarray,
    obstacles: ObstacleArrays | Sequence[TrackedObstacle],
    r_safe_m: float,
    fences: Sequence[FenceZone] = (),
    fence_margin_m: float = 0.0,
) -> str:
    """Why ``point_ned`` (about home) cannot be reached safely on the tracked ``obstacles``, or "" when it can.

    e.g. ``"it lies inside obstacle 3's safety volume (1.2 m from it, CA_RSAFE_M 2.5 m)"`` or
    ``"it lies within CA_FENCE_MARG_M (3 m) of the fence"``.
    """
    p = np.asarray(point_ned, float).reshape(1, 3)
    if not isinstance(obstacles, ObstacleArrays):
        obstacles = ObstacleArrays(tuple(obstacles))
    if len(obstacles):
        per_obstacle = obstacles.signed_distance(p)[0]
        k = int(np.argmin(per_obstacle))
        d = float(per_obstacle[k])
        if d < r_safe_m:
            oid = int(obstacles.ids[k])
            where = f"{d:.1f} m from it" if d >= 0.0 else f"{-d:.1f} m inside it"
            return f"it lies inside obstacle {oid}'s safety volume ({where}, CA_RSAFE_M {r_safe_m:g} m)"
    row = p[0]
    for zone in fences:
        if not zone.segment_clear(row, row, fence_margin_m):
            return f"it lies within CA_FENCE_MARG_M ({fence_margin_m:g} m) of the fence"
    return ""
