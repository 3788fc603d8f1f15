"""The navigator's route glue around :class:`MissionRouter` (issue 13), about home.

:class:`LegRouting` turns the executor's positional target into the target the commander flies (the leg's
next via point around the fence, and after a HOLD of the avoidance planner around the tracked obstacles;
the hold point when no route exists), hands the avoidance planner the routed route ahead, and maps a
detour's rejoin index back to the mission item to skip to. Planned on events (a new target, a new fence,
a HOLD, a detour's end); the same objects come back while nothing changes.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import replace
from typing import Protocol

import numpy as np

from autopilot.geofence.fence import Geofence
from autopilot.mission.executor import MissionRoute, NavKind
from autopilot.mission.executor import NavTarget as MissionTarget
from autopilot.planner.mission_router import MissionRouter, RouteStatus, RouteStep
from autopilot.planner.param_decls import PlannerParams
from autopilot.planner.planner import PlannerState
from autopilot.safety.failsafe import FailsafeAction, FailsafeEvent, FailsafeKind
from mavlink_bridge.contract.frames import Vec3
from mavlink_bridge.contract.status_texts import failsafe_text
from mavlink_bridge.contract.vehicle_api import Severity
from mavlink_bridge.contract.wire import ObstacleDetection


class RoutePlanner(Protocol):
    """The avoidance planner seam (``autopilot.planner.planner.AvoidancePlanner.update``); positions about home."""

    def update(
        self,
        time_us: int,
        pos_ned: Sequence[float],
        vel_ned: Sequence[float],
        q_ned_frd: Sequence[float],
        detections: Sequence[ObstacleDetection],
        route_target_ned: Sequence[float],
        route_next_ned: Sequence[float] | np.ndarray | None = None,
        route_items: Sequence[bool] | np.ndarray | None = None,
    ) -> object: ...


#: Executor targets whose leg is routed around the fence (a takeoff or a landing is vertical); a commander's
#: return (AUTO_RTL) is routed as a RETURN target too (:mod:`autopilot.navigation.return_routing`).
ROUTED_KINDS = frozenset({NavKind.WAYPOINT, NavKind.LOITER, NavKind.RETURN})


class LegRouting:
    """The routed leg to the executor's current target (see the module docstring)."""

    def __init__(self, params: PlannerParams) -> None:
        self.router = MissionRouter(params)
        self._key: object = None  # the routed target (seq, kind, position)
        self._pts: np.ndarray | None = None  # the mission's route from the target on (about home)
        self._seqs: tuple[int, ...] = ()
        self._step: RouteStep | None = None
        self._src: MissionTarget | None = None  # the executor's target the routed one was made from
        self._routed: MissionTarget | None = None

    def set_params(self, params: PlannerParams) -> None:
        self.router.set_params(params)

    def set_fence(self, fence: Geofence) -> None:
        self.router.set_fence(fence)
        self._key = None

    def reset(self) -> None:
        """Forget the leg (mode change, new mission)."""
        self.router.reset()
        self._key, self._step = None, None

    @property
    def step(self) -> RouteStep | None:
        return self._step

    @property
    def active(self) -> bool:
        """The current leg is routed (or direct): the planner gets :meth:`ahead`, a rejoin goes to :meth:`rejoin`."""
        step = self._step
        return step is not None and step.status in (RouteStatus.ROUTED, RouteStatus.DIRECT)

    @property
    def path_home_ned_m(self) -> np.ndarray | None:
        """The planned leg around the fence (and known obstacles), (n, 3) about home; None when not routed."""
        step = self._step
        return step.path_ned_m if step is not None and step.status is RouteStatus.ROUTED else None

    def route(
        self,
        time_us: int,
        pos_home_ned_m: Vec3,
        target: MissionTarget,
        mission_route: Callable[[], MissionRoute | None],
        planner_output: object | None,
        say: Callable[[str, Severity], None],
        label: str = "",
    ) -> tuple[MissionTarget, FailsafeEvent | None]:
        """The target to fly now and, once, the no-route failsafe (CA_NOROUTE_ACT after CA_NOROUTE_T).
        ``label`` names the target in messages (default ``item <seq>``; a return's is ``home``)."""
        label = label or f"item {target.seq}"
        if target.kind not in ROUTED_KINDS:
            if self._key is not None:
                self.reset()
            return target, None
        key = (target.seq, target.kind, target.pos_ned_m)
        if key != self._key:
            self._key = key
            route = mission_route()
            if route is not None and route.seqs and route.seqs[0] == target.seq:
                self._pts, self._seqs = route.pos_ned_m, route.seqs
            else:
                self._pts, self._seqs = np.array((target.pos_ned_m,), float), (target.seq,)
        state = getattr(planner_output, "state", PlannerState.CLEAR)
        obstacles: Sequence[object] = getattr(planner_output, "obstacles", ())
        step = self.router.update(time_us, pos_home_ned_m, self._pts, key, obstacles, state, label)
        for text in step.texts:
            say(text, Severity.WARNING if step.status is RouteStatus.NO_ROUTE else Severity.INFO)
        failsafe = None
        if step.action is not None:
            failsafe = FailsafeEvent(FailsafeKind.NO_ROUTE, FailsafeAction(step.action),
                                     failsafe_text(f"no route to {label}", step.reason))  # fmt: skip
        if step is not self._step or target is not self._src:
            self._step, self._src = step, target
            goal = step.goal_ned_m
            self._routed = target if goal is None or goal == target.pos_ned_m else replace(target, pos_ned_m=goal)
        assert self._routed is not None
        return self._routed, failsafe

    def ahead(self) -> np.ndarray | None:
        """The route after the goal for the avoidance planner: via points, the target, the later legs."""
        step = self._step
        return step.route_ahead_ned_m if step is not None and len(step.route_ahead_ned_m) else None

    def ahead_items(self) -> np.ndarray | None:
        """Which points of [goal, *:meth:`ahead`] are mission items (a detour rejoins at a reachable one)."""
        return self.router.ahead_items if self._step is not None else None

    def rejoin(self, k: int) -> tuple[int, tuple[int, ...], np.ndarray] | None:
        """A detour rejoins the handed route at point ``k``: the mission item to skip to, the items it bypassed
        and their positions (about home); None if it bypassed no item."""
        m = self.router.consume(k)
        return (self._seqs[m], self._seqs[:m], self._pts[:m]) if 0 < m < len(self._seqs) else None
