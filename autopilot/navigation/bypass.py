"""Why the navigator bypassed a mission item (issue 22, SPEC §7): the reason its STATUSTEXT and summary give."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from autopilot.geofence.fence import Geofence
from autopilot.geofence.planner_zones import planner_fence_zones
from autopilot.mission.executor_types import MissionRoute
from autopilot.parameters.store import ParamStore
from autopilot.planner.param_decls import PlannerParams
from autopilot.planner.reachability import unreachable_reason

#: A bypassed item that was reachable on the planner's map (a planner that rejoined past it anyway).
REJOINED_PAST = "a detour rejoined the route past it"


def bypass_reason(params: ParamStore, geofence: Geofence, planner_output: object, pos_home_ned_m: np.ndarray) -> str:
    """Why the item at ``pos_home_ned_m`` cannot be reached safely on the planner's latest map (its tracked
    obstacles, ``CA_RSAFE_M``) and the fence (``CA_FENCE_MARG_M``); :data:`REJOINED_PAST` when it could."""
    p = PlannerParams.from_store(params)
    obstacles, fence = getattr(planner_output, "obstacles", ()), planner_fence_zones(geofence)
    return unreachable_reason(pos_home_ned_m, obstacles, p.r_safe_m, fence, p.fence_margin_m) or REJOINED_PAST


def first_clear_item(route: MissionRoute, obstacles: Sequence[object], r_safe_m: float) -> int | None:
    """The item to skip to when the route's head lies inside an obstacle's safety volume (``r_safe_m``): the first
    route point outside every one, else the item the route stops at (-1: none); None when the head is clear."""
    clear = np.full(len(route.seqs), np.inf)
    for obstacle in obstacles:
        np.minimum(clear, obstacle.signed_distance(route.pos_ned_m), out=clear)  # type: ignore[attr-defined]
    if clear[0] >= r_safe_m:
        return None
    outside = np.flatnonzero(clear >= r_safe_m)
    return route.seqs[int(outside[0])] if len(outside) else route.next_seq
