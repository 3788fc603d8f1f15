"""Why the navigator bypassed a mission item (issue 22, SPEC §7): the reason its STATUSTEXT and summary give."""

from __future__ import annotations

import numpy as np

from autopilot.geofence.fence import Geofence
from autopilot.geofence.planner_zones import planner_fence_zones
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
