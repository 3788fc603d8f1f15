"""The leg to the current mission target, routed around the known world (SPEC §7, issue 13).

:class:`MissionRouter` sits between the mission (its current target) and the reactive avoidance planner:

- On an event only (a new target, a new fence, a HOLD of the reactive planner, a via point covered by a
  tracked obstacle) it plans the leg from the vehicle to the target on the known world
  (:class:`autopilot.planner.route_graph.KnownWorld`: the fence inflated by ``CA_FENCE_MARG_M``; after a
  HOLD also the tracked obstacles inflated by ``CA_RSAFE_M`` + ``CA_MARGIN_M``). A straight leg that is
  clear has no via points; otherwise the vehicle flies the via points, then the target.
- The reactive Bézier detour (``AvoidancePlanner``) still handles what is newly sensed; it gets the route
  from :attr:`RouteStep.route_ahead_ned_m` (via points first) and reports bypassed points, which
  :meth:`MissionRouter.consume` takes off the via points first (the rest are mission items to skip).
- No route at all: the vehicle holds where it is (``RouteStatus.NO_ROUTE``, with the reason), the route is
  retried every ``NO_ROUTE_RETRY_S``, and after ``CA_NOROUTE_T`` the step carries ``CA_NOROUTE_ACT`` once.

Pure: no clock or I/O; positions are NED about home (m), times sim µs.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, replace
from enum import Enum

import numpy as np

from autopilot.geofence.fence import Geofence
from autopilot.planner.param_decls import PlannerParams
from autopilot.planner.planner import PlannerState
from autopilot.planner.route_graph import KnownWorld, RouteResult, obstacle_discs
from mavlink_bridge.contract.wire import Vec3

#: A via point is passed within this horizontal distance (m), or once the vehicle is past it along the route.
VIA_ACCEPT_M = 2.0
#: With no route, planning is retried this often (s of sim time).
NO_ROUTE_RETRY_S = 1.0
#: After a HOLD of the reactive planner, the known world is replanned at most this often (s).
HOLD_REPLAN_S = 1.0
#: Obstacles on the known world are inflated by R_safe plus at least this (m; CA_MARGIN_M when larger).
OBSTACLE_EXTRA_M = 1.0


class RouteStatus(Enum):
    """How the current leg is flown."""

    IDLE = "idle"  # no target
    DIRECT = "direct"  # the straight leg is clear of the known world
    ROUTED = "routed"  # via points around fences / known obstacles
    NO_ROUTE = "no_route"  # holding: no route exists (``RouteStep.reason``)


@dataclass(frozen=True, slots=True)
class RouteStep:
    """What the router says for this step (the same object until something changes)."""

    status: RouteStatus
    goal_ned_m: Vec3 | None  # fly here now: the next via point, the target, or the hold point (NO_ROUTE)
    route_ahead_ned_m: np.ndarray  # (k, 3): the via points after the goal, the target, then the later legs
    vias_left: int  # via points not yet passed, the goal included when it is one
    path_ned_m: np.ndarray | None  # the whole planned leg from where it was planned (for drawing)
    reason: str = ""  # NO_ROUTE: why
    texts: tuple[str, ...] = ()  # STATUSTEXTs to send (only on the step that produced them)
    action: int | None = None  # CA_NOROUTE_ACT, once, when the no-route timeout expires
    planned: bool = False  # a route search ran in this step
    known_world: bool = False  # ... and it included the tracked obstacles (a replan after a HOLD)


_NO_POINTS = np.zeros((0, 3))
_IDLE = RouteStep(RouteStatus.IDLE, None, _NO_POINTS, 0, None)


class MissionRouter:
    """Plans the leg to the current target around the known world; see the module docstring."""

    def __init__(self, params: PlannerParams | None = None, fence: Geofence | None = None) -> None:
        self.params = params or PlannerParams()
        self._fence = fence or Geofence()
        self._fence_world: KnownWorld | None = None
        self._target_key: object = None
        self._label = ""  # the target in messages (e.g. "item 3")
        self._target: Vec3 | None = None
        self._vias: list[Vec3] = []
        self._path: np.ndarray | None = None
        self._step = _IDLE
        self._status = RouteStatus.IDLE
        self._no_route_since_us: int | None = None
        self._action_sent = False
        self._last_try_us = -(10**18)
        self._hold_point: Vec3 | None = None
        self._reason = ""
        self._checked_obstacles: Sequence[object] | None = None
        self._use_known = False  # the reactive planner held on this leg: route around the tracked obstacles too
        self._planner_state = PlannerState.CLEAR
        self._route = _NO_POINTS  # the mission's route from the target on
        self._later = _NO_POINTS  # the route after the target: later legs' via points and mission points
        self._later_is_mission = np.zeros(0, bool)
        self.searches = 0  # route searches run

    # ------------------------------------------------------------------ events
    def set_fence(self, fence: Geofence) -> None:
        """A new fence (about home): the leg is planned again at the next update."""
        self._fence = fence
        self._fence_world = None
        self._target_key = None

    def set_params(self, params: PlannerParams) -> None:
        if params.fence_margin_m != self.params.fence_margin_m:
            self._fence_world = None
            self._target_key = None
        self.params = params

    def reset(self) -> None:
        """Forget the leg (mission replaced, landed, mode change)."""
        self._target_key = None
        self._target = None
        self._vias = []
        self._step = _IDLE
        self._status = RouteStatus.IDLE
        self._no_route_since_us = None
        self._action_sent = False

    @property
    def fence_world(self) -> KnownWorld:
        """The fence inflated by CA_FENCE_MARG_M (built once per fence and margin)."""
        if self._fence_world is None:
            self._fence_world = KnownWorld(self._fence, self.params.fence_margin_m)
        return self._fence_world

    # ------------------------------------------------------------------ per step
    def update(
        self,
        time_us: int,
        pos_ned_m: Sequence[float],
        route_ned_m: np.ndarray | None,
        target_key: object,
        obstacles: Sequence[object] = (),
        planner_state: PlannerState = PlannerState.CLEAR,
        label: str = "",
    ) -> RouteStep:
        """The route for this step. ``route_ned_m`` (k, 3) is the mission's route from the target on (row 0 the
        target, then the points after it, e.g. ``MissionExecutor.route_ahead``); ``target_key`` identifies it
        (e.g. the item seq): a new key plans a new leg, and the legs between the later points around the fence.
        ``obstacles`` are the avoidance map's tracked obstacles (routed around once the reactive planner held on
        this leg, and checked against the next via point); ``planner_state`` is the reactive planner's: a HOLD
        replans on the known world, and the leg is replanned from where a detour or a hold ended."""
        if route_ned_m is None or len(route_ned_m) == 0:
            if self._status is not RouteStatus.IDLE:
                self.reset()
            return self._step
        if target_key != self._target_key:
            self._target_key = target_key
            self._label = label or str(target_key)
            t = route_ned_m[0]
            self._target = (float(t[0]), float(t[1]), float(t[2]))
            self._route = np.asarray(route_ned_m, float)
            self._plan_later_legs(self._route, self.fence_world)
            self._no_route_since_us = None
            self._action_sent = False
            self._use_known = False
            self._planner_state = planner_state
            return self._plan(time_us, pos_ned_m, (), f"new target {self._label}")
        step = self._step
        if step.texts or step.planned or step.action is not None:  # one-shot fields: this step only
            self._step = replace(step, texts=(), planned=False, known_world=False, action=None)
        status = self._status
        if status is RouteStatus.NO_ROUTE:
            return self._no_route_step(time_us, pos_ned_m, obstacles)
        previous, self._planner_state = self._planner_state, planner_state
        holding = planner_state is PlannerState.HOLD
        if holding and time_us - self._last_try_us >= HOLD_REPLAN_S * 1e6:
            self._use_known = True
            return self._plan(time_us, pos_ned_m, obstacles, "no safe local detour")
        if planner_state is PlannerState.CLEAR and previous is not PlannerState.CLEAR:
            # the detour (or hold) ended: it may have rejoined past via points, so go on from here
            return self._plan(time_us, pos_ned_m, obstacles if self._use_known else (), "detour ended")
        if self._vias:
            if obstacles and obstacles is not self._checked_obstacles and self._via_covered(obstacles):
                return self._plan(time_us, pos_ned_m, obstacles, "a via point lies in an obstacle's safety volume")
            if self._via_passed(pos_ned_m):
                self._vias.pop(0)
                self._step = self._make_step(())
        return self._step

    @property
    def ahead_items(self) -> np.ndarray:
        """Which points of [goal, *route_ahead] are mission points (the via points around the fence are not)."""
        vias = self._step.vias_left
        return np.concatenate((np.zeros(vias, bool), (True,), self._later_is_mission))

    def consume(self, n: int) -> int:
        """The reactive planner's detour rejoins the route [goal, *route_ahead] at point ``n`` (its
        ``rejoin_route_index``): the via points before it are dropped; returns how many points of the mission's
        route (the target first) it bypassed, which the caller skips (0: only via points)."""
        if n <= 0 or self._status not in (RouteStatus.ROUTED, RouteStatus.DIRECT):
            return 0
        drop = min(n, len(self._vias))
        skipped = int(np.count_nonzero(self._later_is_mission[: max(0, n - drop - 1)])) + (1 if n > drop else 0)
        if drop:
            del self._vias[:drop]
            self._step = self._make_step(())
        return skipped

    # ------------------------------------------------------------------ internals
    def _plan(self, time_us: int, pos: Sequence[float], obstacles: Sequence[object], why: str) -> RouteStep:
        assert self._target is not None
        self._last_try_us = time_us
        self.searches += 1
        known = bool(obstacles)
        world = self._world(obstacles)
        if known:  # the blocker may sit on a later leg (the reactive planner checks the route past the target)
            self._plan_later_legs(self._route, world)
        start = (float(pos[0]), float(pos[1]), float(pos[2]))
        result = world.route(start, self._target, self.params.r_safe_m) if not world.empty else None
        texts: tuple[str, ...] = ()
        if result is None or result.ok:
            was_routed = self._status is RouteStatus.ROUTED
            self._apply(result, start)
            if self._vias and not was_routed:
                texts = (f"Route: {len(self._vias)} via points around the {self._around(known)} ({why})",)
            self._no_route_since_us = None
            self._step = self._make_step(texts, planned=True, known=known)
            return self._step
        return self._no_route(time_us, start, result, known)

    def _around(self, known: bool) -> str:
        return "fence and known obstacles" if known else "fence"

    def _world(self, obstacles: Sequence[object]) -> KnownWorld:
        if not obstacles:
            return self.fence_world
        p = self.params
        discs = obstacle_discs(obstacles, p.r_safe_m, max(p.margin_m, OBSTACLE_EXTRA_M))
        return KnownWorld(self._fence, p.fence_margin_m, discs)

    def _apply(self, result: RouteResult | None, start: Vec3) -> None:
        assert self._target is not None
        if result is None or len(result.path_ned_m) <= 2:
            self._vias, self._status = [], RouteStatus.DIRECT
            self._path = np.array((start, self._target))
        else:
            self._vias = [tuple(float(x) for x in row) for row in result.vias_ned_m]  # type: ignore[misc]
            self._status = RouteStatus.ROUTED
            self._path = result.path_ned_m

    def _no_route(self, time_us: int, start: Vec3, result: RouteResult, known: bool) -> RouteStep:
        first = self._status is not RouteStatus.NO_ROUTE
        self._status = RouteStatus.NO_ROUTE
        self._vias = []
        self._reason = result.reason
        if first:
            self._hold_point = start
            self._no_route_since_us = time_us
        texts: tuple[str, ...] = ()
        if first:
            texts = (
                f"No route to {self._label}: {result.reason}; holding, "
                f"action {self.params.noroute_action} (CA_NOROUTE_ACT) in {self.params.noroute_t_s:g} s",
            )
        self._step = RouteStep(
            RouteStatus.NO_ROUTE, self._hold_point, _NO_POINTS, 0, None, self._reason, texts, None, True, known
        )
        return self._step

    def _no_route_step(self, time_us: int, pos: Sequence[float], obstacles: Sequence[object]) -> RouteStep:
        since = self._no_route_since_us if self._no_route_since_us is not None else time_us
        if not self._action_sent and time_us - since >= self.params.noroute_t_s * 1e6:
            self._action_sent = True
            self._step = RouteStep(
                RouteStatus.NO_ROUTE,
                self._hold_point,
                _NO_POINTS,
                0,
                None,
                self._reason,
                (self._action_text(),),
                self.params.noroute_action,
            )
            return self._step
        if time_us - self._last_try_us >= NO_ROUTE_RETRY_S * 1e6:
            step = self._plan(time_us, pos, obstacles, "retry")
            if step.status is not RouteStatus.NO_ROUTE:
                self._step = self._make_step((f"Route found to {self._label} after holding",), planned=True)
        return self._step

    def _action_text(self) -> str:
        p = self.params
        return f"No route to {self._label} for {p.noroute_t_s:g} s: action {p.noroute_action} (CA_NOROUTE_ACT)"

    def _plan_later_legs(self, route: np.ndarray, world: KnownWorld) -> None:
        """The legs after the target, each routed around ``world`` (their via points and the mission points)."""
        pts: list[np.ndarray] = []
        flags: list[bool] = []
        for i in range(1, len(route)):
            r = world.route(route[i - 1], route[i]) if not world.empty else None
            if r is not None and r.ok and len(r.path_ned_m) > 2:
                pts.extend(r.vias_ned_m)
                flags.extend([False] * len(r.vias_ned_m))
            pts.append(route[i])
            flags.append(True)
        self._later = np.array(pts, float).reshape(-1, 3)
        self._later_is_mission = np.array(flags, bool)

    def _make_step(self, texts: tuple[str, ...], planned: bool = False, known: bool = False) -> RouteStep:
        assert self._target is not None
        if self._vias:
            goal = self._vias[0]
            ahead = np.vstack((np.array([*self._vias[1:], self._target], float).reshape(-1, 3), self._later))
        else:
            goal, ahead = self._target, self._later
        return RouteStep(self._status, goal, ahead, len(self._vias), self._path, "", texts, None, planned, known)

    def _via_passed(self, pos: Sequence[float]) -> bool:
        via = self._vias[0]
        dn, de = pos[0] - via[0], pos[1] - via[1]
        if dn * dn + de * de <= VIA_ACCEPT_M * VIA_ACCEPT_M:
            return True
        nxt = self._vias[1] if len(self._vias) > 1 else self._target
        assert nxt is not None
        # past the via: on the far side of the line through it, square to the next leg
        ln, le = nxt[0] - via[0], nxt[1] - via[1]
        return dn * ln + de * le > 0.0 and math.hypot(dn, de) < 4.0 * VIA_ACCEPT_M

    def _via_covered(self, obstacles: Sequence[object]) -> bool:
        """The next via point lies within R_safe of a tracked obstacle (checked when the map's tuple changes)."""
        self._checked_obstacles = obstacles
        via = np.array(self._vias[:1], float)
        r_safe = self.params.r_safe_m
        return any(float(o.signed_distance(via)[0]) < r_safe for o in obstacles)  # type: ignore[attr-defined]
