"""The navigator: the mission executor, the avoidance planner and the fences, about home (SPEC §7, §8).

PX4's navigator in spirit: it owns what the vehicle is asked to fly in AUTO_MISSION, and nothing else.

- Reads: the vehicle state (about the estimator origin), the flight mode, the landed state, obstacle
  detections, the home frame (:class:`HomeFrame`) and its parameters.
- Owns: the uploaded MISSION and FENCE items, the :class:`MissionExecutor`, the :class:`Geofence`, the
  :class:`AvoidancePlanner` and the route glue between them (the route handed to the planner, waypoints a
  detour bypassed or that lie inside an obstacle's safety volume skipped, the nose along the path).
- Routes (issue 13): uploads accepted before home is known and checked once it is (:class:`UploadStore`);
  legs routed around the fence and known obstacles (:class:`LegRouting`); bypassed items reported as such;
  the commander's AUTO_RTL leg home routed the same way (:class:`ReturnRouting`, issue 22).
- Emits: one :class:`NavOutput` per step (the commander's mission target, items reached, gripper actions)
  and, while avoiding, a :class:`ReferenceOverride` for the setpoint generator; status texts.

Positions inside are about home (``*_home_ned_m``); the commander's targets and overrides are about the
estimator origin, converted by the one :class:`HomeFrame`.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import replace

import numpy as np

from autopilot.estimation import VehicleState
from autopilot.flight_tasks.setpoints import NavTarget
from autopilot.geofence.fence import Geofence
from autopilot.geofence.planner_zones import planner_fence_zones
from autopilot.mission.executor import (
    ActionKind,
    ExecutorConfig,
    ExecutorOutput,
    MissionExecutor,
    MissionRoute,
    NavKind,
    VehicleSample,
)
from autopilot.mission.feasibility import FeasibilityLimits
from autopilot.mission.uploads import UploadStore
from autopilot.mission.validation import MissionLimits
from autopilot.navigation.bypass import REJOINED_PAST, bypass_reason, first_clear_item
from autopilot.navigation.home_frame import HomeFrame
from autopilot.navigation.leg_routing import LegRouting, RoutePlanner
from autopilot.navigation.outputs import NOTHING as _NOTHING
from autopilot.navigation.outputs import NavOutput, ReferenceOverride
from autopilot.navigation.return_routing import ReturnRouting
from autopilot.navigation.targets import face_along_path, mission_nav_target
from autopilot.navigation.traffic_bypass import BlockedWaypoint
from autopilot.navigation.traffic_link import TrafficLink
from autopilot.parameters.store import ParamStore
from autopilot.planner.param_decls import PlannerParams
from autopilot.planner.planner import AvoidancePlanner
from mavlink_bridge.contract.frames import Vec3
from mavlink_bridge.contract.mav_enums import MissionState
from mavlink_bridge.contract.status_texts import bypassed_text, reached_text
from mavlink_bridge.contract.vehicle_api import (
    FlightMode,
    MissionItem,
    MissionResult,
    MissionType,
    Severity,
    StatusText,
)
from mavlink_bridge.contract.wire import ObstacleDetection

#: The planner gets the mission route this many CA_LOOKAHEAD_M past its target (the detour rejoins on it and
#: checks it after the rejoin), at most this many points.
ROUTE_AHEAD_LOOKAHEADS = 2.0
ROUTE_MAX_POINTS = 64


class Navigator:
    """Missions, fences and avoidance about home; pure (no clock or I/O), stepped by the runner."""

    def __init__(
        self,
        params: ParamStore,
        planner: RoutePlanner | None = None,
        land_speed_m_s: Callable[[], float] | None = None,
        system_id: int = 1,
    ) -> None:
        self.params = params
        self.planner = planner
        self.traffic = TrafficLink(params, system_id, lambda text: self._texts.append(text))  # SPEC §13
        #: The commander's descent speed for a mission LAND now (it changes at MPC_LAND_ALT2).
        self.land_speed_m_s = land_speed_m_s or (lambda: params.get("MPC_LAND_SPEED"))
        self.uploads = UploadStore()
        self.geofence = Geofence()  # the uploaded FENCE about home (empty until home is known)
        self.routing = LegRouting(PlannerParams.from_store(params))
        self.returns = ReturnRouting(self.routing)
        self.executor: MissionExecutor | None = None
        self.bypassed_seqs: list[int] = []
        self.frame: HomeFrame | None = None  # home about the origin (before arming: the origin itself)
        self.planner_output: object | None = None
        self._texts: list[StatusText] = []
        self._last_output: ExecutorOutput | None = None
        self._route_checked: tuple[object, object] | None = None  # (route, obstacles) last safety-checked
        self._blocked = BlockedWaypoint()  # traffic keeping the vehicle off its waypoint
        self._nav_key: tuple[object, ...] = ()
        self._nav: NavTarget | None = None
        self._nav_faces = False  # the cached mission target's yaw is the per-step heading along the path
        self._param_version = 0
        self._detections: Sequence[ObstacleDetection] = ()
        self.bypass_reasons: dict[int, str] = {}  # why each bypassed item could not be reached (the latest)
        self.apply_planner_params()
        self.apply_altitude_limits()
        self.apply_upload_limits()

    # ------------------------------------------------------------------ configuration
    def apply_planner_params(self) -> None:
        """CA_* into the planner and the router (CA_FENCE_MARG_M re-checks the mission: its routes change)."""
        params = PlannerParams.from_store(self.params)
        if isinstance(self.planner, AvoidancePlanner):
            self.planner.set_params(params)
        self.routing.set_params(params)
        self.apply_upload_limits()

    def apply_upload_limits(self) -> None:
        """GF_MAX_VER_DIST, GF_MAX_HOR_DIST, CA_FENCE_MARG_M, MIS_* into the upload checks (re-checks the mission)."""
        if not hasattr(self, "uploads"):
            return
        self.uploads.set_limits(FeasibilityLimits.from_params(self.params.get), MissionLimits.from_params(self.params))
        self._sync_uploads()

    def apply_altitude_limits(self) -> None:
        """GF_MAX_VER_DIST (when set) is a ceiling for detours too, and for the mission's items."""
        if isinstance(self.planner, AvoidancePlanner):
            ceiling = self.params.get("GF_MAX_VER_DIST")
            self.planner.set_altitude_limits(0.0, ceiling if ceiling > 0.0 else math.inf)
        self.apply_upload_limits()

    def apply_mission_params(self) -> None:
        """MIS_* into the executor and the upload checks; any parameter change invalidates the cached target."""
        if self.executor is not None:
            self.executor.configure(ExecutorConfig.from_params(self.params))
        self.apply_upload_limits()

    def params_changed(self) -> None:
        self._param_version += 1

    def drain_texts(self) -> list[StatusText]:
        for text in self.uploads.drain_texts():
            self._texts.append(StatusText(text.severity, text.text))
        out, self._texts = self._texts, []
        return out

    def _say(self, text: str, severity: Severity = Severity.INFO) -> None:
        self._texts.append(StatusText(severity, text))

    # ------------------------------------------------------------------ home
    def set_home(self, frame: HomeFrame) -> None:
        """Home moved (first fix, arming): the executor and the fence are re-anchored on it and the stored
        mission is checked against it (an infeasible one is reported and not flown)."""
        self.frame = frame
        executor = self._executor()
        if executor is not None:
            executor.set_home(frame.geo, frame.home_tol)
        self.uploads.set_home(frame.geo, frame.home_tol)
        self._sync_uploads()

    def _executor(self) -> MissionExecutor | None:
        if self.executor is None and self.frame is not None:
            self.executor = MissionExecutor(self.frame.geo, ExecutorConfig.from_params(self.params))
        return self.executor

    def _sync_uploads(self) -> None:
        """The fence (about home) into the planner, router and failsafe; the flyable mission into the executor."""
        uploads = self.uploads
        if uploads.fence is not self.geofence:
            self.geofence = uploads.fence
            if isinstance(self.planner, AvoidancePlanner):
                self.planner.set_fences(planner_fence_zones(uploads.fence))
            self.routing.set_fence(uploads.fence)
        executor = self.executor
        if executor is not None:
            flyable = uploads.mission if uploads.flyable else []
            if executor.items != flyable:
                executor.set_mission(flyable)
                self.routing.reset()

    @property
    def mission(self) -> list[MissionItem]:
        """The accepted MISSION items (flown once home is known and they are feasible)."""
        return self.uploads.mission

    @property
    def fence(self) -> list[MissionItem]:
        """The accepted FENCE items."""
        return self.uploads.fence_items

    # ------------------------------------------------------------------ uploads (GCS)
    def replace_mission(self, mission_type: MissionType, items: list[MissionItem]) -> tuple[MissionResult, str]:
        """A whole MISSION or FENCE upload, accepted whenever it arrives (before the first fix too) and kept
        only when valid; checked against home and the fence as soon as both are known. A refusal says why,
        also as a STATUSTEXT naming the item."""
        result, reason = self.uploads.upload(mission_type, items)
        if result is MissionResult.ACCEPTED:
            self._sync_uploads()
        return result, reason

    def mission_items(self, mission_type: MissionType) -> list[MissionItem]:
        if mission_type is MissionType.FENCE:
            return list(self.fence)
        return list(self.mission) if mission_type is MissionType.MISSION else []

    @property
    def mission_ready(self) -> bool:
        """A mission is stored, home is known and the mission passed the feasibility checks."""
        return self.uploads.flyable

    def set_current_mission_item(self, seq: int) -> bool:
        return self.executor is not None and self.executor.set_current(seq)

    def start_mission(self, time_us: int, seq: int | None = None) -> bool:
        if self.uploads.mission_issue:
            self._say(f"Mission not started: {self.uploads.mission_issue}", Severity.WARNING)
            return False
        return self.executor is not None and self.executor.start(time_us, seq)

    def mode_changed(self, mode: FlightMode, previous: FlightMode, time_us: int) -> None:
        """Entering AUTO_MISSION starts (or resumes) the mission; leaving it pauses the mission."""
        executor = self.executor
        self.routing.reset()
        self.returns.reset()
        if executor is None:
            return
        if mode is FlightMode.AUTO_MISSION and executor.state is not MissionState.ACTIVE:
            executor.start(time_us)
        elif previous is FlightMode.AUTO_MISSION:
            executor.pause(time_us)

    # ------------------------------------------------------------------ progress (reporting)
    @property
    def current_seq(self) -> int:
        out = self._last_output
        return out.current_seq if out is not None else 0

    @property
    def mission_state(self) -> MissionState:
        return self.executor.state if self.executor is not None else MissionState.NO_MISSION

    # ------------------------------------------------------------------ the step
    def sense(self, state: VehicleState, detections: Sequence[ObstacleDetection]) -> Sequence[ObstacleDetection]:
        """This frame's obstacle detections for the planner: those of tracked vehicles are traffic's
        (:meth:`TrafficLink.fuse`: fixes of their tracks) and leave the obstacle map."""
        kept, vehicles = self.traffic.fuse(state, self.frame, detections)
        if vehicles and isinstance(self.planner, AvoidancePlanner):
            self.planner.map.forget(vehicles)
        return kept

    def update(self, state: VehicleState, mode: FlightMode, landed: bool, detections: Sequence[ObstacleDetection],
               return_goal_ned_m: Vec3 | None = None) -> NavOutput:  # fmt: skip
        """The mission's target at this step (AUTO_MISSION; in AUTO_RTL the routed point toward ``return_goal_ned_m``,
        the commander's point above home about the origin), then traffic avoidance (its failsafe rides along)."""
        out = self._mission_update(state, mode, landed, detections, return_goal_ned_m)
        return self.traffic.step(self, state, mode, landed, out)

    def _mission_update(self, state: VehicleState, mode: FlightMode, landed: bool,
                        detections: Sequence[ObstacleDetection],
                        return_goal_ned_m: Vec3 | None) -> NavOutput:  # fmt: skip
        """The mission's target at this step (AUTO_MISSION), with skips past obstacles' safety volumes; in AUTO_RTL
        the routed point toward ``return_goal_ned_m`` (the commander's point above home, about the origin)."""
        executor, frame = self.executor, self.frame
        self._detections = detections
        if mode is FlightMode.AUTO_RTL and frame is not None:
            nav_target, failsafe = self.returns.target(state, frame, return_goal_ned_m, self.planner_output, self._say)
            return NavOutput(nav_target, failsafe=failsafe) if nav_target is not None else _NOTHING
        if executor is None or frame is None or mode is not FlightMode.AUTO_MISSION:
            return _NOTHING
        pos = frame.home_from_origin(state.pos_ned_m)
        sample = VehicleSample(state.time_us, pos, state.vel_ned_m_s, landed)
        out = self._last_output = executor.step(sample)
        if self._skip_covered_target(state.time_us) or self._skip_blocked_target(state.time_us, pos):
            then = executor.step(sample)
            out = self._last_output = replace(
                then,
                reached=out.reached + then.reached,
                actions=out.actions + then.actions,
                bypassed=out.bypassed + then.bypassed,
            )
        for seq in out.reached:
            self._say(reached_text(seq))
        for seq in out.bypassed:
            self.bypassed_seqs.append(seq)
            why = self.bypass_reasons.setdefault(seq, REJOINED_PAST)
            self._say(bypassed_text(seq, why), Severity.WARNING)
        gripper = None
        for action in out.actions:
            gripper = action.kind is ActionKind.GRIPPER_RELEASE
        target = out.target
        if target is None:
            if out.reached or out.bypassed or gripper is not None:
                return NavOutput(None, out.reached, gripper, out.bypassed)
            return _NOTHING
        target, failsafe = self.routing.route(state.time_us, pos, target, self._mission_route, self.planner_output,
                                              self._say)  # fmt: skip
        face = face_along_path(self.params, self.planner_output, pos, target, self._mission_route)
        # built once per (routed) executor target, home and parameter set (and LAND descent speed, which changes
        # at MPC_LAND_ALT2); a target that faces along the path gets this step's heading (the only field changing)
        key: tuple[object, ...] = (target, frame, self._param_version)
        land_speed_m_s = math.nan
        if target.kind is NavKind.LAND:
            land_speed_m_s = self.land_speed_m_s()
            key = (*key, land_speed_m_s)
        nav = self._nav
        if key != self._nav_key or nav is None:
            self._nav_key = key
            nav = mission_nav_target(target, frame, self.params, land_speed_m_s, face)
            self._nav_faces = math.isnan(target.yaw_deg) and target.kind in (NavKind.WAYPOINT, NavKind.RETURN)
        elif self._nav_faces:
            nav = NavTarget(nav.kind, nav.pos_ned_m, face, nav.speed_xy_m_s, nav.speed_up_m_s, nav.speed_down_m_s)
        self._nav = nav
        if out.reached or out.bypassed or gripper is not None or failsafe is not None:
            return NavOutput(nav, out.reached, gripper, out.bypassed, failsafe)
        return NavOutput(nav)

    @property
    def route_path_home_ned_m(self) -> np.ndarray | None:
        """The planned leg around the fence (and known obstacles) about home, (n, 3), for drawing; None if none."""
        return self.routing.path_home_ned_m

    def avoid(
        self, state: VehicleState, target: NavTarget, detections: Sequence[ObstacleDetection] | None = None
    ) -> ReferenceOverride | None:
        """Let the avoidance planner override the reference (a POSITION target of AUTO_MISSION or an RTL's return)
        with this frame's ``detections`` (None: the latest :meth:`update`'s). The planner gets the route from the
        target on (``route_after_target``); items a detour passed (``rejoin_route_index``: unreachable ones) are
        skipped in the executor, reported bypassed with the reason."""
        planner, frame = self.planner, self.frame
        traffic = self.traffic.override(state.time_us, ReferenceOverride)  # wins over an obstacle detour
        if planner is None or frame is None:
            return traffic
        detections = self._detections if detections is None else detections
        idle_output = getattr(planner, "idle_output", None)
        if idle_output is not None:  # nothing to avoid: the output update() would give, without the route
            idle = idle_output(state.time_us, detections)
            if idle is not None:
                self.planner_output = idle
                return traffic
        pos = frame.home_from_origin(state.pos_ned_m)
        goal = frame.home_from_origin(target.pos_ned_m)
        route = self._mission_route()
        routed = self.routing.active
        nxt, items = self.route_after_target(), self.routing.ahead_items() if routed else None  # items: mission's
        result = planner.update(state.time_us, pos, state.vel_ned_m_s, state.q_ned_frd, detections, goal, nxt,
                                route_items=items)  # fmt: skip
        self.planner_output = result
        k = int(getattr(result, "rejoin_route_index", 0))
        rejoined = self.routing.rejoin(k) if k > 0 and routed else None  # via points dropped, maybe items skipped
        if rejoined is None and not routed and route is not None and 0 < k < len(route.seqs):
            rejoined = (route.seqs[k], route.seqs[:k], route.pos_ned_m[:k])  # past waypoints: skip them now
        if rejoined is not None and self.executor is not None:
            for seq, pos_ned_m in zip(rejoined[1], rejoined[2], strict=True):
                self.bypass_reasons[seq] = bypass_reason(self.params, self.geofence, self.planner_output, pos_ned_m)
            self.executor.skip_to(rejoined[0], state.time_us)
        for decision in getattr(result, "decisions", ()):
            self._say(str(decision.text), Severity.NOTICE)
        setpoint = getattr(result, "setpoint", None)
        if setpoint is None or traffic is not None:
            return traffic
        p, v, a = setpoint.pos_ned_m, setpoint.vel_ned_m_s, setpoint.acc_ned_m_s2
        return ReferenceOverride(
            frame.origin_from_home((float(p[0]), float(p[1]), float(p[2]))),
            (float(v[0]), float(v[1]), float(v[2])),
            (float(a[0]), float(a[1]), float(a[2])),
        )

    # ------------------------------------------------------------------ route glue
    def route_after_target(self) -> object:
        """After the flown target, about home (the planner's ``next``): routed legs, the route, the next waypoint."""
        if self.routing.active:
            return self.routing.ahead()
        route = self._mission_route()
        if route is not None:
            return route.pos_ned_m[1:] if len(route.seqs) > 1 else None
        out = self._last_output
        return out.target.next_pos_ned_m if out is not None and out.target is not None else None

    def _mission_route(self) -> MissionRoute | None:
        """The executor's route when the flown target is its current positional item (None otherwise)."""
        executor, out = self.executor, self._last_output
        if executor is None or out is None or out.target is None or executor.state is not MissionState.ACTIVE:
            return None
        if out.target.kind not in (NavKind.WAYPOINT, NavKind.LOITER) or out.target.seq != executor.current_seq:
            return None
        route = executor.route_ahead(ROUTE_AHEAD_LOOKAHEADS * self.params.get("CA_LOOKAHEAD_M"), ROUTE_MAX_POINTS)
        return route if route.seqs and route.seqs[0] == out.target.seq else None

    def _skip_blocked_target(self, time_us: int, pos_home_ned_m: Vec3) -> bool:
        """Bypass the route's head when traffic keeps the vehicle off it (:class:`BlockedWaypoint`)."""
        avoid = self.traffic.avoidance
        route = self._mission_route() if avoid.table.has_tracks else None
        blocked = self._blocked.check(time_us, pos_home_ned_m, route, avoid.table.tracks, avoid.params)
        if blocked is None or self.executor is None or not self.executor.skip_to(blocked[1], time_us):
            return False
        self.bypass_reasons[blocked[0]] = blocked[2]
        return True

    def _skip_covered_target(self, time_us: int) -> bool:
        """Skip the route's head while it lies inside a tracked obstacle's safety volume (CA_RSAFE_M; obstacles
        of the planner's latest output) to the first route point outside, or the item the route stops at."""
        obstacles = getattr(self.planner_output, "obstacles", ())
        route = self._mission_route() if obstacles else None
        if route is None:
            return False
        checked = self._route_checked
        if checked is not None and checked[0] is route and checked[1] is obstacles:
            return False  # both unchanged since the last check (the executor and the map cache them)
        self._route_checked = (route, obstacles)
        seq = first_clear_item(route, obstacles, self.params.get("CA_RSAFE_M"))
        assert self.executor is not None
        if seq is None or seq < 0 or not self.executor.skip_to(seq, time_us):
            return False
        head = route.seqs[0]
        self.bypass_reasons[head] = bypass_reason(self.params, self.geofence, self.planner_output, route.pos_ned_m[0])
        self._say(f"Skipped to item {seq}: item {head} lies inside an obstacle's safety volume")
        return True
