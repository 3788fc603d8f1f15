"""The stateful avoidance planner the autopilot runner calls every control step (SPEC §7, paper §3.3).

Per ``update``: fold the detections into the obstacle map; while CLEAR, look for the largest
threat on the route / velocity direction and, if there is one, plan a detour (``detour.plan_detour``)
or, when no side is safe, brake to a hover (HOLD) and retry every ``CA_REPLAN_S``. While on a
detour, its Bézier reference is the setpoint override; when new or grown obstacles make the rest
of the detour (or the route just after its rejoin point) unsafe it is replanned from the current
reference state (continuous position and velocity). When the detour ends the route resumes
(override None).

A detour may rejoin the route past some waypoints. ``PlannerOutput.rejoin_route_index`` says how
many of the waypoints handed to ``update`` it bypassed; the caller advances its mission target by
that many (at once or when the detour ends: once advanced, later updates report 0). Until it does,
the planner itself plans on the route from the rejoined leg on (a detour that ends where the next
one starts never sends the vehicle back to a bypassed waypoint).

Each decision is an :class:`AvoidanceDecision` with a STATUSTEXT-ready ``text``; the runner sends
it (MAVLink 2 STATUSTEXT chunks long texts; ``short_text`` fits one 50-character message).
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence

import numpy as np

from mavlink_bridge.contract.wire import ObstacleDetection

from .bezier import BezierPath
from .detour import DetourLimits, DetourPlan, DetourSide, plan_detour
from .detour_checks import check_path
from .geometry import FenceZone
from .obstacle_map import ObstacleMap, TrackedObstacle
from .param_decls import PlannerParams
from .path_shapes import brake_path
from .planner_output import AvoidanceDecision, DecisionReason, DetourSetpoint, PlannerOutput, PlannerState
from .threat import Threat, assess_threat

#: The velocity-direction check reaches the stopping distance plus this many seconds of flight.
RAY_HORIZON_S = 2.0
#: ``look_ahead_ned`` is the detour reference this far ahead: yaw the nose (camera) toward it.
LOOK_AHEAD_S = 2.0


class AvoidancePlanner:
    """Obstacle map + threat + detour state machine. Pure: no clock or I/O; ``time_us`` is sim time."""

    def __init__(
        self,
        params: PlannerParams,
        fences: Iterable[FenceZone] = (),
        alt_floor_m: float = 0.0,
        alt_ceiling_m: float = math.inf,
    ) -> None:
        self.params = params
        self._fences: tuple[FenceZone, ...] = tuple(fences)
        self._alt_floor_m = alt_floor_m
        self._alt_ceiling_m = alt_ceiling_m
        self.map = ObstacleMap(params.merge_m, params.forget_s)
        self._state = PlannerState.CLEAR if params.enable else PlannerState.DISABLED
        self._path: BezierPath | None = None
        self._plan: DetourPlan | None = None
        self._t0_us = 0
        self._last_try_us = -(10**18)
        self._unchecked: set[int] = set()  # obstacles changed since the active detour was last checked
        self._rejoin_wp: tuple[float, float, float] | None = None  # waypoint the last detour resumes toward
        self._passes: list[tuple[float, float, float]] = []  # route points the last detour flies through first
        self._searches = 0  # detour searches run (plan_detour calls)
        self._route_items: tuple[bool, ...] | None = None  # this update's route rows that are mission items

    @property
    def state(self) -> PlannerState:
        return self._state

    def set_params(self, params: PlannerParams) -> None:
        """Apply new parameter values (in flight); an active detour is kept."""
        self.params = params
        self.map.merge_m, self.map.forget_s = params.merge_m, params.forget_s
        if not params.enable:
            self._clear(PlannerState.DISABLED)
        elif self._state is PlannerState.DISABLED:
            self._state = PlannerState.CLEAR

    def set_fences(self, zones: Iterable[FenceZone]) -> None:
        """Replace the geofence zones (exclusions kept out, inclusions never left)."""
        self._fences = tuple(zones)

    def set_altitude_limits(self, alt_floor_m: float, alt_ceiling_m: float) -> None:
        """Altitude band (m above home) a detour must stay in, besides CA_MIN_AGL_M / CA_CEILING_M."""
        self._alt_floor_m, self._alt_ceiling_m = alt_floor_m, alt_ceiling_m

    def reset(self) -> None:
        """Forget obstacles and any detour (e.g. on landing)."""
        self.map.clear()
        self._rejoin_wp = None
        self._clear(PlannerState.CLEAR if self.params.enable else PlannerState.DISABLED)

    def limits(self) -> DetourLimits:
        p = self.params
        return DetourLimits(
            r_safe_m=p.r_safe_m,
            margin_m=p.margin_m,
            v_max_m_s=p.v_max_m_s,
            a_max_m_s2=p.a_max_m_s2,
            rejoin_m=p.rejoin_m,
            min_agl_m=p.min_agl_m,
            alt_floor_m=self._alt_floor_m,
            alt_ceiling_m=min(self._alt_ceiling_m, p.ceiling_m),
            fences=self._fences,
            cruise_m_s=min(p.cruise_m_s, p.v_max_m_s),
            fence_margin_m=p.fence_margin_m,
        )

    def _clear(self, state: PlannerState) -> None:
        self._state = state
        self._path = None
        self._plan = None
        self._unchecked.clear()

    def update(
        self,
        time_us: int,
        pos_ned: Sequence[float],
        vel_ned: Sequence[float],
        q_ned_frd: Sequence[float],
        detections: Iterable[ObstacleDetection],
        route_target_ned: Sequence[float],
        route_next_ned: Sequence[float] | np.ndarray | None = None,
        route_items: Sequence[bool] | np.ndarray | None = None,
    ) -> PlannerOutput:
        """One planner step at sim time ``time_us`` with the vehicle state and this step's detections.

        ``route_target_ned`` is the current mission target, ``route_next_ned`` the one after it, or
        an ``(n, 3)`` array of the upcoming ones, or None. The detour rejoins the route they define
        ``ρ + CA_REJOIN_M`` past the obstacle and checks the route after that for the stopping distance
        + 2 s, so pass enough of it: at least ``CA_LOOKAHEAD_M`` plus that beyond the target (the
        benchmark passes two look-ahead lengths; with sparse delivery legs the next waypoint is enough,
        dense expanded patterns need many). A rejoin point past the route's last waypoint is clamped to
        it. The detour may rejoin past some of them: ``PlannerOutput.rejoin_route_index`` says how many
        to skip. ``route_items`` flags which of those points are mission items (None: all of them; via
        points around the fence are not): a detour rejoins *at* a reachable item, never past it, so only
        unreachable ones (inside a safety volume or the fence margin) are ever skipped.
        """
        pos = np.asarray(pos_ned, float)
        vel = np.asarray(vel_ned, float)
        changed = self.map.update(time_us, pos, np.asarray(q_ned_frd, float), detections)
        obstacles = self.map.obstacles
        route = np.asarray(route_target_ned, float)[None, :]
        if route_next_ned is not None:
            route = np.vstack((route, np.asarray(route_next_ned, float).reshape(-1, 3)))
        full_route = route
        skip = self._route_skip(route)
        route = route[skip:]
        self._route_items = (
            None if route_items is None else tuple(bool(f) for f in route_items)[skip : skip + len(route)]
        )
        decisions: list[AvoidanceDecision] = []
        threat: Threat | None = None
        searches = self._searches
        if self._state is not PlannerState.DISABLED:
            threat = self._step(time_us, pos, vel, route, obstacles, changed, decisions)
        p = pos.tolist()
        clearance = self.map.arrays.nearest_distance((p[0], p[1], p[2]))
        setpoint = None
        look = None
        if self._path is not None:
            t_s = (time_us - self._t0_us) * 1e-6
            setpoint = DetourSetpoint(*self._path.state_tuple(t_s))
            look = self._path.state_tuple(t_s + LOOK_AHEAD_S)[0]
        return PlannerOutput(
            time_us,
            self._state,
            setpoint,
            self._plan,
            self._path if self._state is PlannerState.HOLD else None,
            tuple(decisions),
            obstacles,
            threat,
            clearance,
            look,
            self._searches != searches,
            self._route_skip(full_route),  # after this update's decisions: a new detour counts at once
        )

    def idle_output(self, time_us: int, detections: Sequence[ObstacleDetection]) -> PlannerOutput | None:
        """What :meth:`update` would return at ``time_us`` when it has nothing to do, without the route or numpy;
        None when it may have something to do (then call ``update``).

        Nothing to do: no detection this step, no tracked obstacle (so nothing to forget, no threat, clearance
        inf), no detour or braking path, no pending rejoin. ``update`` then changes no state and returns this
        (``test_planner_idle.py`` checks they are equal), so the runner skips building the route.
        """
        if detections or self._path is not None or self._rejoin_wp is not None or not self.map.empty:
            return None
        return PlannerOutput(time_us, self._state, None, self._plan, None, (), self.map.obstacles, None, math.inf)

    def _route_skip(self, route: np.ndarray) -> int:
        """Index in ``route`` of the waypoint the last detour resumes toward (0 once the caller advanced)."""
        wp = self._rejoin_wp
        if wp is None:
            return 0
        rows = route.tolist()
        head = rows[0]
        if any(abs(head[0] - p[0]) + abs(head[1] - p[1]) + abs(head[2] - p[2]) < 1e-6 for p in self._passes):
            return 0  # the caller's target is one the detour flies through: reached on the way, nothing skipped yet
        for i, row in enumerate(rows):
            if abs(row[0] - wp[0]) + abs(row[1] - wp[1]) + abs(row[2] - wp[2]) < 1e-6:
                if i == 0:
                    self._rejoin_wp = None  # the caller's target is the rejoined leg's end: consumed
                return i
        self._rejoin_wp = None  # not in the route any more (the caller moved past it)
        return 0

    def _step(
        self,
        time_us: int,
        pos: np.ndarray,
        vel: np.ndarray,
        route: np.ndarray,
        obstacles: tuple[TrackedObstacle, ...],
        changed: set[int],
        decisions: list[AvoidanceDecision],
    ) -> Threat | None:
        p = self.params
        if self._state is PlannerState.DETOUR and self._path is not None:
            t_s = (time_us - self._t0_us) * 1e-6
            if t_s >= self._path.duration_s:
                self._clear(PlannerState.CLEAR)
            else:
                # every change is checked against the rest of the detour (a change seen while replans are
                # rate-limited stays pending until it is checked: it is never dropped)
                self._unchecked |= changed
                if self._unchecked:
                    return self._check_detour(time_us, t_s, route, obstacles, decisions)
                return None
        if self._state is PlannerState.HOLD and self._path is not None:
            t_s = (time_us - self._t0_us) * 1e-6
            if time_us - self._last_try_us < p.replan_s * 1e6:
                return None
            sp_pos, sp_vel, _ = self._path.state_at(t_s)
            threat = self._threat(sp_pos, sp_vel, route, obstacles)
            if threat is None:
                self._clear(PlannerState.CLEAR)
                return None
            self._plan_from(time_us, sp_pos, sp_vel, route, threat, DecisionReason.RETRY, decisions)
            return threat
        threat = self._threat(pos, vel, route, obstacles)
        if threat is not None:
            self._plan_from(time_us, pos, vel, route, threat, DecisionReason.THREAT, decisions)
        return threat

    def _check_detour(
        self,
        time_us: int,
        t_s: float,
        route: np.ndarray,
        obstacles: tuple[TrackedObstacle, ...],
        decisions: list[AvoidanceDecision],
    ) -> Threat | None:
        """Re-check the rest of the active detour after map changes; replan from the reference if unsafe."""
        sp_pos, sp_vel, _ = self._path.state_at(t_s)
        ahead = np.concatenate((self._remaining_samples(t_s), self._plan.continuation_ned))
        # only the changed obstacles: the others were checked against (a superset of) these samples before
        why = check_path(ahead, sp_pos, self.map.arrays, self.limits(), obstacle_ids=self._unchecked)
        if not why:
            self._unchecked.clear()
            return None
        if time_us - self._last_try_us < self.params.replan_s * 1e6:
            return None  # replans are rate-limited: the change stays pending
        threat = self._threat(sp_pos, sp_vel, route, obstacles) or self._blocking(why, sp_pos, obstacles)
        if threat is None:  # not an obstacle (fences or altitude limits changed in flight): keep flying it
            self._unchecked.clear()
            return None
        self._plan_from(time_us, sp_pos, sp_vel, route, threat, DecisionReason.REPLAN, decisions)
        self._unchecked.clear()
        return threat

    def _threat(
        self, pos: np.ndarray, vel: np.ndarray, route: np.ndarray, obstacles: tuple[TrackedObstacle, ...]
    ) -> Threat | None:
        p = self.params
        speed = float(np.linalg.norm(vel))
        ray_m = min(p.lookahead_m, speed * speed / (2.0 * p.a_max_m_s2) + RAY_HORIZON_S * speed)
        return assess_threat(pos, vel, route, self.map.arrays, p.r_safe_m, p.lookahead_m, ray_m)

    @staticmethod
    def _blocking(why: str, pos: np.ndarray, obstacles: tuple[TrackedObstacle, ...]) -> Threat | None:
        """The obstacle named by a failed ``check_path`` ("obstacle N") as a threat, else None."""
        if not why.startswith("obstacle "):
            return None
        oid = int(why.split()[1])
        obs = next((o for o in obstacles if o.obstacle_id == oid), None)
        if obs is None:
            return None
        d = float(obs.signed_distance(pos[None, :])[0])
        return Threat(obs, d, d, math.inf, False)

    def _remaining_samples(self, t_s: float) -> np.ndarray:
        """The detour's samples from the last one at or before ``t_s`` on (at least two)."""
        assert self._plan is not None
        samples = self._plan.samples_ned
        first = int(np.searchsorted(self._plan.sample_times_s, t_s, side="right")) - 1
        return samples[min(max(first, 0), len(samples) - 2) :]

    def _plan_from(
        self,
        time_us: int,
        pos: np.ndarray,
        vel: np.ndarray,
        route: np.ndarray,
        threat: Threat,
        reason: DecisionReason,
        decisions: list[AvoidanceDecision],
    ) -> None:
        self._last_try_us = time_us
        self._searches += 1
        result = plan_detour(pos, vel, route, threat.obstacle, self.map.arrays, self.limits(), self._route_items)
        distance = float(threat.obstacle.signed_distance(pos[None, :])[0])
        if result.plan is not None:
            self._state, self._plan, self._path = PlannerState.DETOUR, result.plan, result.plan.path
            self._t0_us = time_us
            wp = route[result.plan.rejoin_route_index]
            self._rejoin_wp = (float(wp[0]), float(wp[1]), float(wp[2]))
            passes = route[: result.plan.prefix_route_index + 1].tolist()
            self._passes = [(p[0], p[1], p[2]) for p in passes]
            side = result.plan.side
        else:
            # an abandoned detour rejoins nowhere: the items it would have flown through or past stay the caller's
            self._rejoin_wp, self._passes = None, []
            if self._state is not PlannerState.HOLD:
                self._path = brake_path(pos, vel, self.params.a_max_m_s2)
                self._t0_us = time_us
            if self._state is PlannerState.HOLD:
                return  # still no safe detour: already reported
            self._state, self._plan = PlannerState.HOLD, None
            side = DetourSide.HOLD
        decisions.append(
            AvoidanceDecision(time_us, threat.obstacle.obstacle_id, distance, side, reason, result.candidates)
        )
