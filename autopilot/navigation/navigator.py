"""The navigator: the mission executor, the avoidance planner and the fences, about home (SPEC §7, §8).

PX4's navigator in spirit: it owns what the vehicle is asked to fly in AUTO_MISSION, and nothing else.

- Reads: the vehicle state (about the estimator origin), the flight mode, the landed state, obstacle
  detections, the home frame (:class:`HomeFrame`) and its parameters.
- Owns: the uploaded MISSION and FENCE items, the :class:`MissionExecutor`, the :class:`Geofence`, the
  :class:`AvoidancePlanner` and the route glue between them (the route handed to the planner, waypoints a
  detour bypassed or that lie inside an obstacle's safety volume skipped, the nose along the path).
- Emits: one :class:`NavOutput` per step (the commander's mission target, items reached, gripper actions)
  and, while avoiding, a :class:`ReferenceOverride` for the setpoint generator; status texts.

Positions inside are about home (``*_home_ned_m``); the commander's targets and overrides are about the
estimator origin, converted by the one :class:`HomeFrame`.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from typing import Protocol

import numpy as np

from autopilot.estimation import VehicleState
from autopilot.fence_zones import planner_fence_zones
from autopilot.mission.executor import (
    ActionKind,
    ExecutorConfig,
    ExecutorOutput,
    MissionExecutor,
    MissionRoute,
    NavKind,
    VehicleSample,
)
from autopilot.mission.executor import NavTarget as MissionTarget
from autopilot.mission.fence import FenceError, Geofence, geofence_from_items
from autopilot.mission.validation import MissionLimits, validate_mission
from autopilot.navigation.home_frame import HomeFrame
from autopilot.params import ParamStore
from autopilot.planner.param_decls import PlannerParams
from autopilot.planner.planner import AvoidancePlanner
from autopilot.setpoints import NavTarget, TargetKind
from mavlink_bridge.contract.frames import Vec3
from mavlink_bridge.contract.mav_enums import MissionState
from mavlink_bridge.contract.vehicle_api import (
    FlightMode,
    MissionItem,
    MissionResult,
    MissionType,
    Severity,
    StatusText,
)
from mavlink_bridge.contract.wire import ObstacleDetection, fast_frozen_init

#: The planner gets the mission route this many CA_LOOKAHEAD_M past its target (the detour rejoins on it and
#: checks it after the rejoin), at most this many points.
ROUTE_AHEAD_LOOKAHEADS = 2.0
ROUTE_MAX_POINTS = 64
#: In AUTO_MISSION the nose (forward camera) faces a route point at least this far ahead (m), none closer than
#: FACE_MIN_M (closer, the heading is kept: no spinning over a waypoint).
FACE_AHEAD_M = 6.0
FACE_MIN_M = 2.0


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
    ) -> object: ...


@fast_frozen_init
@dataclass(frozen=True, slots=True)
class NavOutput:
    """What the navigator asks for at one step (targets about the estimator origin)."""

    mission_target: NavTarget | None  # None: the mission flies nothing now (or the mode is not AUTO_MISSION)
    reached: tuple[int, ...] = ()  # items reached at this step
    gripper_release: bool | None = None  # a DO_GRIPPER action at this step: True release, False grab


@fast_frozen_init
@dataclass(frozen=True, slots=True)
class ReferenceOverride:
    """The avoidance planner's reference for this step (about the estimator origin), replacing the route's."""

    pos_ned_m: Vec3
    vel_ned_m_s: Vec3
    acc_ned_m_s2: Vec3


_NOTHING = NavOutput(None)


def mission_nav_target(target: MissionTarget, frame: HomeFrame, params: ParamStore, land_speed_m_s: float,
                       face_yaw_rad: float = math.nan) -> NavTarget:  # fmt: skip
    """The executor's target (about home) as a commander target (about the origin); a waypoint or return
    without a yaw of its own gets ``face_yaw_rad`` (MPC_YAW_MODE 0: the nose, and the camera, along the path)."""
    p = params.get
    n, e, d = frame.origin_from_home(target.pos_ned_m)
    speed = min(target.speed_m_s, p("MPC_XY_VEL_MAX"))
    up, down = p("MPC_Z_VEL_MAX_UP"), p("MPC_Z_VEL_MAX_DN")
    yaw = math.nan if math.isnan(target.yaw_deg) else math.radians(target.yaw_deg)
    if math.isnan(yaw) and target.kind in (NavKind.WAYPOINT, NavKind.RETURN):
        yaw = face_yaw_rad
    kind = target.kind
    if kind is NavKind.IDLE:
        return NavTarget(TargetKind.IDLE, (n, e, d))
    if kind is NavKind.LAND:
        return NavTarget(TargetKind.LAND, (n, e, d), yaw, speed, up, land_speed_m_s)
    if kind is NavKind.TAKEOFF:
        up = p("MPC_TKO_SPEED")
    return NavTarget(TargetKind.POSITION, (n, e, d), yaw, speed, up, down)


class Navigator:
    """Missions, fences and avoidance about home; pure (no clock or I/O), stepped by the runner."""

    def __init__(
        self,
        params: ParamStore,
        planner: RoutePlanner | None = None,
        land_speed_m_s: Callable[[], float] | None = None,
    ) -> None:
        self.params = params
        self.planner = planner
        #: The commander's descent speed for a mission LAND now (it changes at MPC_LAND_ALT2).
        self.land_speed_m_s = land_speed_m_s or (lambda: params.get("MPC_LAND_SPEED"))
        self.geofence = Geofence()
        self.executor: MissionExecutor | None = None
        self.mission: list[MissionItem] = []
        self.fence: list[MissionItem] = []
        self.frame: HomeFrame | None = None  # home about the origin (before arming: the origin itself)
        self.planner_output: object | None = None
        self._texts: list[StatusText] = []
        self._last_output: ExecutorOutput | None = None
        self._route_checked: tuple[object, object] | None = None  # (route, obstacles) last safety-checked
        self._nav_key: tuple[object, ...] = ()
        self._nav: NavTarget | None = None
        self._nav_faces = False  # the cached mission target's yaw is the per-step heading along the path
        self._param_version = 0
        self._detections: Sequence[ObstacleDetection] = ()
        self.apply_planner_params()
        self.apply_altitude_limits()

    # ------------------------------------------------------------------ configuration
    def apply_planner_params(self) -> None:
        """CA_* into the planner."""
        if isinstance(self.planner, AvoidancePlanner):
            self.planner.set_params(PlannerParams.from_store(self.params))

    def apply_altitude_limits(self) -> None:
        """GF_MAX_VER_DIST (when set) is a ceiling for detours too."""
        if isinstance(self.planner, AvoidancePlanner):
            ceiling = self.params.get("GF_MAX_VER_DIST")
            self.planner.set_altitude_limits(0.0, ceiling if ceiling > 0.0 else math.inf)

    def apply_mission_params(self) -> None:
        """MIS_* into the executor; any parameter change invalidates the cached mission target."""
        if self.executor is not None:
            self.executor.configure(ExecutorConfig.from_params(self.params))

    def params_changed(self) -> None:
        self._param_version += 1

    def drain_texts(self) -> list[StatusText]:
        out, self._texts = self._texts, []
        return out

    def _say(self, text: str, severity: Severity = Severity.INFO) -> None:
        self._texts.append(StatusText(severity, text))

    # ------------------------------------------------------------------ home
    def set_home(self, frame: HomeFrame) -> None:
        """Home moved (first fix, arming): the executor and the fence are re-anchored on it."""
        self.frame = frame
        executor = self._executor()
        if executor is not None:
            executor.set_home(frame.geo)
        if self.fence:
            self._set_geofence(geofence_from_items(self.fence, frame.geo))

    def _executor(self) -> MissionExecutor | None:
        if self.executor is None and self.frame is not None:
            self.executor = MissionExecutor(self.frame.geo, ExecutorConfig.from_params(self.params))
        return self.executor

    def _set_geofence(self, fence: Geofence) -> None:
        self.geofence = fence
        if isinstance(self.planner, AvoidancePlanner):
            self.planner.set_fences(planner_fence_zones(fence))

    # ------------------------------------------------------------------ uploads (GCS)
    def replace_mission(self, mission_type: MissionType, items: list[MissionItem]) -> tuple[MissionResult, str]:
        """A whole MISSION or FENCE upload: validated about home, kept only when accepted."""
        if mission_type not in (MissionType.MISSION, MissionType.FENCE):
            return MissionResult.UNSUPPORTED, f"mission type {mission_type.name} is not supported"
        frame = self.frame
        if frame is None:
            return MissionResult.ERROR, "no position fix yet: upload again once the vehicle has a position"
        if mission_type is MissionType.FENCE:
            try:
                fence = geofence_from_items(items, frame.geo)
            except FenceError as exc:
                return MissionResult.INVALID, str(exc)
            self.fence = list(items)
            self._set_geofence(fence)
            self._say(f"Geofence: {len(items)} items")
            return MissionResult.ACCEPTED, ""
        result, reason = validate_mission(items, frame.geo, MissionLimits.from_params(self.params))
        if result is not MissionResult.ACCEPTED:
            return result, reason
        executor = self._executor()
        if executor is None:
            return MissionResult.ERROR, "no position fix yet"
        executor.set_mission(items)
        self.mission = list(items)
        self._say(f"Mission: {len(items)} items")
        return MissionResult.ACCEPTED, ""

    def mission_items(self, mission_type: MissionType) -> list[MissionItem]:
        if mission_type is MissionType.FENCE:
            return list(self.fence)
        return list(self.mission) if mission_type is MissionType.MISSION else []

    @property
    def mission_ready(self) -> bool:
        return bool(self.mission)

    def set_current_mission_item(self, seq: int) -> bool:
        return self.executor is not None and self.executor.set_current(seq)

    def start_mission(self, time_us: int, seq: int | None = None) -> bool:
        return self.executor is not None and self.executor.start(time_us, seq)

    def mode_changed(self, mode: FlightMode, previous: FlightMode, time_us: int) -> None:
        """Entering AUTO_MISSION starts (or resumes) the mission; leaving it pauses the mission."""
        executor = self.executor
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
    def update(
        self,
        state: VehicleState,
        mode: FlightMode,
        landed: bool,
        detections: Sequence[ObstacleDetection],
    ) -> NavOutput:
        """The mission's target at this step (AUTO_MISSION only), with skips past obstacles' safety volumes."""
        executor, frame = self.executor, self.frame
        self._detections = detections
        if executor is None or frame is None or mode is not FlightMode.AUTO_MISSION:
            return _NOTHING
        pos = frame.home_from_origin(state.pos_ned_m)
        sample = VehicleSample(state.time_us, pos, state.vel_ned_m_s, landed)
        out = self._last_output = executor.step(sample)
        if self._skip_covered_target(state.time_us):  # never fly toward a waypoint inside an obstacle
            then = executor.step(sample)
            out = self._last_output = replace(
                then, reached=out.reached + then.reached, actions=out.actions + then.actions
            )
        for seq in out.reached:
            self._say(f"Reached item {seq}")
        gripper = None
        for action in out.actions:
            gripper = action.kind is ActionKind.GRIPPER_RELEASE
        target = out.target
        if target is None:
            return NavOutput(None, out.reached, gripper) if out.reached or gripper is not None else _NOTHING
        face = self._face_along_path(pos, target)
        # built once per executor target, home and parameter set (and LAND descent speed, which changes at
        # MPC_LAND_ALT2); a target that faces along the path gets this step's heading (the only field that changes)
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
        return NavOutput(nav, out.reached, gripper)

    def avoid(self, state: VehicleState, target: NavTarget) -> ReferenceOverride | None:
        """Let the avoidance planner override the reference (AUTO_MISSION, POSITION target).

        The planner gets the mission route from the target on (``MissionExecutor.route_ahead``, two
        CA_LOOKAHEAD_M lengths); waypoints a detour bypassed (``rejoin_route_index``) are skipped in the
        executor (reported reached, DO items still run).
        """
        planner, frame = self.planner, self.frame
        if planner is None or frame is None:
            return None
        detections = self._detections
        idle_output = getattr(planner, "idle_output", None)
        if idle_output is not None:  # nothing to avoid: the output update() would give, without the route
            idle = idle_output(state.time_us, detections)
            if idle is not None:
                self.planner_output = idle
                return None
        pos = frame.home_from_origin(state.pos_ned_m)
        goal = frame.home_from_origin(target.pos_ned_m)
        route = self._mission_route()
        nxt: Sequence[float] | np.ndarray | None = None
        if route is not None:
            nxt = route.pos_ned_m[1:] if len(route.seqs) > 1 else None
        else:
            out = self._last_output
            if out is not None and out.target is not None and out.target.next_pos_ned_m is not None:
                nxt = out.target.next_pos_ned_m
        result = planner.update(state.time_us, pos, state.vel_ned_m_s, state.q_ned_frd, detections, goal, nxt)
        self.planner_output = result
        k = int(getattr(result, "rejoin_route_index", 0))
        if route is not None and 0 < k < len(route.seqs):  # the detour rejoins past waypoints: skip them now
            assert self.executor is not None
            self.executor.skip_to(route.seqs[k], state.time_us)
        for decision in getattr(result, "decisions", ()):
            self._say(str(decision.text), Severity.NOTICE)
        setpoint = getattr(result, "setpoint", None)
        if setpoint is None:
            return None
        p, v, a = setpoint.pos_ned_m, setpoint.vel_ned_m_s, setpoint.acc_ned_m_s2
        return ReferenceOverride(
            frame.origin_from_home((float(p[0]), float(p[1]), float(p[2]))),
            (float(v[0]), float(v[1]), float(v[2])),
            (float(a[0]), float(a[1]), float(a[2])),
        )

    # ------------------------------------------------------------------ route glue
    def _mission_route(self) -> MissionRoute | None:
        """The executor's route when the flown target is its current positional item (None otherwise)."""
        executor, out = self.executor, self._last_output
        if executor is None or out is None or out.target is None or executor.state is not MissionState.ACTIVE:
            return None
        if out.target.kind not in (NavKind.WAYPOINT, NavKind.LOITER) or out.target.seq != executor.current_seq:
            return None
        route = executor.route_ahead(ROUTE_AHEAD_LOOKAHEADS * self.params.get("CA_LOOKAHEAD_M"), ROUTE_MAX_POINTS)
        return route if route.seqs and route.seqs[0] == out.target.seq else None

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
        r_safe = self.params.get("CA_RSAFE_M")
        clear = np.full(len(route.seqs), np.inf)
        for obstacle in obstacles:
            np.minimum(clear, obstacle.signed_distance(route.pos_ned_m), out=clear)
        if clear[0] >= r_safe:
            return False
        outside = np.flatnonzero(clear >= r_safe)
        seq = route.seqs[int(outside[0])] if len(outside) else route.next_seq
        assert self.executor is not None
        if seq < 0 or not self.executor.skip_to(seq, time_us):
            return False
        self._say(f"Skipped to item {seq}: item {route.seqs[0]} lies inside an obstacle's safety volume")
        return True

    def _face_along_path(self, pos_home_ned_m: Vec3, target: MissionTarget) -> float:
        """Heading (rad) toward where the vehicle is going, about home: the detour's look-ahead point while
        avoiding, else the first route point at least FACE_AHEAD_M away (dense patterns), else the target.
        NaN (keep the heading) with MPC_YAW_MODE 1 or nothing far enough away."""
        if self.params.get("MPC_YAW_MODE") >= 0.5:
            return math.nan
        pos = pos_home_ned_m
        look = getattr(self.planner_output, "look_ahead_ned", None)
        if look is None or getattr(self.planner_output, "setpoint", None) is None:
            look = target.pos_ned_m
            if target.kind is NavKind.WAYPOINT and math.hypot(look[0] - pos[0], look[1] - pos[1]) < FACE_AHEAD_M:
                route = self._mission_route()
                if route is not None:
                    for row in route.pos_ned_m.tolist()[1:]:
                        look = row
                        if math.hypot(row[0] - pos[0], row[1] - pos[1]) >= FACE_AHEAD_M:
                            break
        dn, de = look[0] - pos[0], look[1] - pos[1]
        return math.atan2(de, dn) if math.hypot(dn, de) >= FACE_MIN_M else math.nan
