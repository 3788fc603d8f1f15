"""Every return routed (issue 22 item 2): the commander's AUTO_RTL leg home planned like a mission leg.

PX4 climbs and flies straight home. Here the commander's RTL (GCS ``rtl``, DO_SET_MODE AUTO.RTL, the battery,
link-loss and no-route failsafes) climbs in its column to the return altitude (below the fence ceiling,
:func:`autopilot.flight_tasks.rtl.return_alt_m`), then hands the navigator the point above home; the navigator
routes the leg there with the mission legs' :class:`LegRouting` (the same :class:`MissionRouter` and known world:
exclusion and inclusion zones inflated by ``CA_FENCE_MARG_M``, and after a HOLD of the reactive planner the
tracked obstacles) and answers with the point to fly toward now: the next via point, home, or the hold point
when no route exists (then ``No route to home: ...`` and, after ``CA_NOROUTE_T``, ``CA_NOROUTE_ACT``).
The reactive Bézier detour keeps working on the routed leg (the runner lets the navigator avoid in the RETURN
phase). A mission's RETURN_TO_LAUNCH item is the executor's RETURN target and routed the same way.
"""

from __future__ import annotations

import math
from collections.abc import Callable

from autopilot.estimation import VehicleState
from autopilot.flight_tasks.setpoints import NavTarget, TargetKind
from autopilot.mission.executor import NavKind
from autopilot.mission.executor import NavTarget as MissionTarget
from autopilot.navigation.home_frame import HomeFrame
from autopilot.navigation.leg_routing import LegRouting
from autopilot.safety.failsafe import FailsafeEvent
from mavlink_bridge.contract.frames import Vec3
from mavlink_bridge.contract.vehicle_api import Severity

#: How the return's goal is named in status texts ("No route to home: ...").
RETURN_LABEL = "home"


class ReturnRouting:
    """The commander's return leg through the navigator's :class:`LegRouting` (see the module docstring)."""

    def __init__(self, routing: LegRouting) -> None:
        self.routing = routing
        self._goal: MissionTarget | None = None
        self._routed: MissionTarget | None = None
        self._nav: NavTarget | None = None

    def reset(self) -> None:
        self._goal = self._routed = self._nav = None

    @property
    def active(self) -> bool:
        """A return leg is being flown, routed or direct (the avoidance planner may detour on it)."""
        return self._goal is not None and self.routing.active

    def target(
        self,
        state: VehicleState,
        frame: HomeFrame,
        goal_origin_ned_m: Vec3 | None,
        planner_output: object | None,
        say: Callable[[str, Severity], None],
    ) -> tuple[NavTarget | None, FailsafeEvent | None]:
        """The point to fly toward now (about the origin) and, once, the no-route failsafe; (None, None) when the
        commander is not in its return leg (``goal_origin_ned_m`` None: climbing, over home, landing)."""
        if goal_origin_ned_m is None:
            if self._goal is not None:
                self.routing.reset()
                self.reset()
            return None, None
        goal_home = frame.home_from_origin(goal_origin_ned_m)
        goal = self._goal
        if goal is None or goal.pos_ned_m != goal_home:
            goal = self._goal = MissionTarget(NavKind.RETURN, -1, goal_home, math.nan, math.inf, 0.0)
        pos_home = frame.home_from_origin(state.pos_ned_m)
        routed, failsafe = self.routing.route(
            state.time_us, pos_home, goal, lambda: None, planner_output, say, RETURN_LABEL
        )
        if routed is not self._routed or self._nav is None:
            self._routed = routed
            n, e, _ = routed.pos_ned_m  # a via point at the return altitude (the router interpolates from the start)
            pos = goal_origin_ned_m if routed is goal else frame.origin_from_home((n, e, goal_home[2]))
            self._nav = NavTarget(TargetKind.POSITION, pos)
        return self._nav, failsafe
