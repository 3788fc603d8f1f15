"""AUTO_RTL: climb to the return altitude above home (``MIS_RTL_ALT`` if lower, never above the fence ceiling),
fly home, wait ``RTL_LAND_DELAY``, land (PX4's RTL navigator mode). The LAND phase is the land task's, over home.

The return leg is routed (issue 22): with ``await_route`` set (the runner sets it: its navigator plans every
return around the fences and known obstacles with the mission legs' router), the RETURN phase flies the point
the navigator hands in (a via point, home, or the hold point when no route exists) and holds the climb column
until the first one arrives; without it (a bare commander) it flies straight home, as PX4 does.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from enum import Enum

from autopilot.estimation import VehicleState
from autopilot.flight_tasks.hold import HoldTask
from autopilot.flight_tasks.land import LandTask
from autopilot.flight_tasks.setpoints import NavTarget, TargetKind
from autopilot.flight_tasks.targets import face_yaw
from autopilot.parameters.store import ParamStore
from mavlink_bridge.contract.wire import Vec3

#: The return altitude stays this far below the fence ceiling (GF_MAX_VER_DIST), m: room for the climb's
#: overshoot and the altitude acceptance.
CEILING_CLEARANCE_M = 2.0
#: A routed goal this close to the point above home (m) is that point (the frames' round trip).
_SAME_POINT_M = 1e-6


def return_alt_m(get: Callable[[str], float]) -> float:
    """The altitude above home a return climbs to when lower: ``MIS_RTL_ALT``, capped ``CEILING_CLEARANCE_M``
    below the fence ceiling ``GF_MAX_VER_DIST`` when one is set (at least 1 m)."""
    alt = get("MIS_RTL_ALT")
    ceiling = get("GF_MAX_VER_DIST")
    if ceiling > 0.0:
        alt = min(alt, max(1.0, ceiling - CEILING_CLEARANCE_M))
    return alt


def return_down_m(get: Callable[[str], float], down_m: float, home_down_m: float) -> float:
    """The local down a return flies at from ``down_m``: its own altitude or :func:`return_alt_m`, whichever is
    higher, but never above the capped altitude when a fence ceiling is set (a vehicle above it descends)."""
    down = min(down_m, home_down_m - return_alt_m(get))
    if get("GF_MAX_VER_DIST") > 0.0:
        down = max(down, home_down_m - return_alt_m(get))
    return down


class RtlPhase(Enum):
    """Where an RTL is."""

    CLIMB = "climb"
    RETURN = "return"
    LOITER = "loiter"
    LAND = "land"


class RtlTask:
    """The phase, the return altitude (local down), the point flown toward and when the loiter over home ends."""

    def __init__(self) -> None:
        self.phase = RtlPhase.CLIMB
        self.down_m = 0.0
        self.loiter_until_us = 0
        self.goto_ned: Vec3 = (0.0, 0.0, 0.0)
        self.goto_yaw = math.nan
        self.home_goal_ned_m: Vec3 = (0.0, 0.0, 0.0)  # the point above home at the return altitude
        self.await_route = False  # the RETURN phase flies the navigator's routed point (see the module docstring)

    def start(self, state: VehicleState, home_down_m: float, params: ParamStore) -> None:
        self.phase = RtlPhase.CLIMB
        self.down_m = return_down_m(params.get, state.pos_ned_m[2], home_down_m)

    @property
    def return_goal_ned_m(self) -> Vec3 | None:
        """The point above home the RETURN phase flies to (about the origin); None in the other phases."""
        return self.home_goal_ned_m if self.phase is RtlPhase.RETURN else None

    def target(
        self,
        state: VehicleState,
        home_ned_m: Vec3,
        params: ParamStore,
        speeds: tuple[float, float, float],
        hold: HoldTask,
        land: LandTask,
        routed_ned_m: Vec3 | None = None,
    ) -> NavTarget | None:
        """The target of the phase; None in the LAND phase (fly the land task, whose spot is now home).
        ``routed_ned_m``: the navigator's routed point for the RETURN phase (about the origin), if any."""
        p = params.get
        n, e, d = state.pos_ned_m
        if self.phase is RtlPhase.CLIMB:
            if d - self.down_m < p("MIS_ALT_ACC_RAD"):
                self.phase = RtlPhase.RETURN
                self.home_goal_ned_m = (home_ned_m[0], home_ned_m[1], self.down_m)
                self.goto_ned = self.home_goal_ned_m
                self.goto_yaw = face_yaw(params, state, self.goto_ned)
                if self.await_route:
                    self.goto_ned, self.goto_yaw = (n, e, self.down_m), math.nan  # until the navigator's route arrives
            else:
                hold.pos_ned_m = (n, e, self.down_m)
                return NavTarget(TargetKind.POSITION, hold.pos_ned_m, math.nan, *speeds)
        if self.phase is RtlPhase.RETURN:
            if math.hypot(n - home_ned_m[0], e - home_ned_m[1]) < p("MIS_ACC_RAD"):
                self.phase = RtlPhase.LOITER
                self.goto_ned = self.home_goal_ned_m
                self.loiter_until_us = state.time_us + int(p("RTL_LAND_DELAY") * 1e6)
            else:
                if routed_ned_m is not None and math.dist(routed_ned_m, self.goto_ned) > _SAME_POINT_M:
                    self.goto_ned = routed_ned_m
                    self.goto_yaw = face_yaw(params, state, routed_ned_m)
                return NavTarget(TargetKind.POSITION, self.goto_ned, self.goto_yaw, *speeds)
        if self.phase is RtlPhase.LOITER:
            if state.time_us >= self.loiter_until_us:
                self.phase = RtlPhase.LAND
                land.ne = (home_ned_m[0], home_ned_m[1])
            else:
                return NavTarget(TargetKind.POSITION, self.goto_ned, math.nan, *speeds)
        return None
