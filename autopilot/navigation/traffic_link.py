"""The navigator's side of traffic avoidance (SPEC §13): what :class:`TrafficAvoidance` needs, what it gives back.

- Reads: received :class:`TrafficReport` objects (``receive``; the runner hands over each frame's), the obstacle
  sensor's detections (``fuse``: those of tracked vehicles become fixes of their tracks), the vehicle
  state (about the estimator origin), the flight mode, whether it is landed, the mission target and the route after
  it, the home frame, the fence, the obstacles the planner tracks, and the CA_*/GF_*/NAV_TRAFF_* parameters.
- Emits: the :class:`TrafficDecision` of the step; the detour's reference about the origin while one is flown (the
  navigator turns it into its :class:`ReferenceOverride`, as for obstacle detours); a failsafe event for
  NAV_TRAFF_AVOID 2/3/4; status texts (through ``say``).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Sequence
from dataclasses import replace
from typing import Protocol, TypeVar

import numpy as np

from autopilot.estimation import VehicleState
from autopilot.flight_tasks.setpoints import NavTarget, Reference, TargetKind
from autopilot.geofence.fence import Geofence
from autopilot.geofence.planner_zones import planner_fence_zones
from autopilot.navigation.home_frame import HomeFrame
from autopilot.navigation.outputs import ReferenceOverride
from autopilot.navigation.traffic_guard import TrafficGuard
from autopilot.parameters.store import ParamStore
from autopilot.planner.obstacle_map import ObstacleKind, detection_volumes
from autopilot.safety.failsafe import FailsafeEvent
from autopilot.traffic import AvoidLimits, OwnShip, TrafficAvoidance, TrafficDecision, TrafficParams
from autopilot.traffic.param_decls import TrafficAction
from autopilot.traffic.sensor_fusion import associate, fix_sigma_m
from autopilot.traffic.tracks import TrackKey
from mavlink_bridge.contract.frames import Vec3
from mavlink_bridge.contract.vehicle_api import FlightMode, LandedState, StatusText
from mavlink_bridge.contract.wire import ObstacleDetection

#: The modes the reactive layer avoids in (manual modes only warn).
REACTIVE_MODES = frozenset((FlightMode.AUTO_TAKEOFF, FlightMode.AUTO_MISSION, FlightMode.AUTO_LOITER,
                            FlightMode.AUTO_RTL, FlightMode.AUTO_LAND))  # fmt: skip
#: Without a new report, traffic avoidance is re-run at most this often (µs of sim time).
UPDATE_PERIOD_US = 200_000


class StepOutput(Protocol):
    """What :meth:`TrafficLink.step` reads of the navigator's step output (a frozen NavOutput)."""

    @property
    def mission_target(self) -> NavTarget | None: ...
    @property
    def failsafe(self) -> FailsafeEvent | None: ...


O = TypeVar("O", bound=StepOutput)
R = TypeVar("R")


class ControlLike(Protocol):
    """What :meth:`TrafficLink.bound` uses of the flight control: this step's reference, and its override."""

    @property
    def reference(self) -> Reference: ...
    def override(self, override: ReferenceOverride) -> Reference: ...


class NavigatorLike(Protocol):
    """What :meth:`TrafficLink.step` reads of the navigator."""

    frame: HomeFrame | None
    geofence: Geofence
    planner_output: object | None

    def route_after_target(self) -> object: ...


class TrafficLink:
    """Runs the vehicle's :class:`TrafficAvoidance` once per navigator step; pure (no clock or I/O)."""

    def __init__(self, params: ParamStore, system_id: int = 1, say: Callable[[StatusText], None] | None = None) -> None:
        self.params = params
        self.say = say or (lambda _text: None)
        self.avoidance = TrafficAvoidance(TrafficParams.from_store(params), system_id)
        self.decision: TrafficDecision | None = None
        self._pending: list[object] = []
        self._param_version = params.version
        self._frame: HomeFrame | None = None
        self._last_update_us = -UPDATE_PERIOD_US
        self.guard = TrafficGuard(params, system_id)
        self._held: dict[int, TrackKey] = {}  # obstacle sensor id -> the track it was last associated with

    def receive(self, reports: Iterable[object]) -> None:
        """Reports received since the last step (any number; checked at the next step)."""
        self._pending.extend(reports)

    def fuse(
        self, state: VehicleState, frame: HomeFrame | None, detections: Sequence[ObstacleDetection]
    ) -> tuple[Sequence[ObstacleDetection], frozenset[int]]:
        """This frame's obstacle detections that are tracked vehicles (:func:`associate`) become fixes of their
        tracks; returns (the detections left for the obstacle map, the sensor ids to drop from it). With
        NAV_TRAFF_AVOID avoiding, the vehicles are traffic's alone; otherwise (warn, off, a failsafe action) they
        stay obstacles too, as they were before: nothing else would steer around them."""
        table = self.avoidance.table
        if not detections or frame is None or not table.has_tracks:
            return detections, frozenset()
        self.avoidance.set_home(frame.geo)
        tracks = table.tracks
        volumes = detection_volumes(detections, state.pos_ned_m, state.q_ned_frd)
        centers = [frame.home_from_origin(c) if kind is ObstacleKind.SPHERE else None for kind, c, _, _ in volumes]
        ids = [det.obstacle_id for det in detections]
        matched = associate(tracks, state.time_us, centers, [v[2] for v in volumes], ids, self._held)
        for i, key in matched.items():
            center = centers[i]
            assert center is not None
            table.observe(key, state.time_us, center, fix_sigma_m(volumes[i][3]))
            self._held[ids[i]] = key
        if not matched or self.avoidance.params.action is not TrafficAction.AVOID:
            return detections, frozenset()
        return tuple(det for i, det in enumerate(detections) if i not in matched), frozenset(ids[i] for i in matched)

    @property
    def busy(self) -> bool:
        """Reports are waiting or traffic is tracked (else a step has nothing to do)."""
        return bool(self._pending) or self.avoidance.busy

    def step(self, nav: NavigatorLike, state: VehicleState, mode: FlightMode, landed: bool, out: O) -> O:
        """:meth:`update` with the navigator's home frame, fence, tracked obstacles and its step's output ``out``
        (a NavOutput: its mission target and the route after it); a traffic failsafe rides along in ``out``."""
        if not self.busy or (not self._pending and state.time_us - self._last_update_us < UPDATE_PERIOD_US):
            return out  # predictions are straight lines: between reports, 5 Hz re-checks them (the detour is timed)
        self._last_update_us = state.time_us
        target = out.mission_target
        after = nav.route_after_target() if target is not None else None
        obstacles = getattr(nav.planner_output, "obstacles", ())
        failsafe = self.update(state, mode, landed, nav.frame, target, after, nav.geofence, obstacles)
        return out if failsafe is None or out.failsafe is not None else replace(out, failsafe=failsafe)

    def limits(self, geofence: Geofence, obstacles: Sequence[object]) -> AvoidLimits:
        """Where a detour may go: CA_* speed, acceleration and altitude band, GF_MAX_VER_DIST, the fence."""
        g = self.params.get
        ceiling = g("CA_CEILING_M")
        if g("GF_MAX_VER_DIST") > 0.0:
            ceiling = min(ceiling, g("GF_MAX_VER_DIST"))
        fences, margin_m = planner_fence_zones(geofence), g("CA_FENCE_MARG_M")
        return AvoidLimits(g("CA_VMAX_M_S"), g("CA_AMAX_M_S2"), -ceiling, -g("CA_MIN_AGL_M"), fences, margin_m,
                           tuple(obstacles), g("CA_RSAFE_M"))  # fmt: skip

    def update(self, state: VehicleState, mode: FlightMode, landed: bool, frame: HomeFrame | None,
               target: NavTarget | None, route_after: object, geofence: Geofence,
               obstacles: Sequence[object]) -> FailsafeEvent | None:  # fmt: skip
        """One step: the decision (kept in ``decision``), its texts queued, its failsafe event returned.

        ``route_after``: what follows the target about home, as the obstacle planner gets it (None, a point or
        points)."""
        if self.params.version != self._param_version:
            self._param_version = self.params.version
            self.avoidance.set_params(TrafficParams.from_store(self.params))
        reports, self._pending = self._pending, []
        self._frame = frame
        if frame is None:  # no home yet: nothing to put reports about; they wait
            self._pending = reports[-self.avoidance.table.max_tracks :]
            return None
        self.avoidance.set_home(frame.geo)
        self.guard.fences = geofence.zones  # the reactive layer keeps inside the fence too
        route: tuple[Vec3, ...] = ()
        cruise = self.params.get("MIS_CRUISE_SPD")
        mission = mode is FlightMode.AUTO_MISSION and target is not None and target.kind is TargetKind.POSITION
        if mission:
            assert target is not None
            route = (frame.home_from_origin(target.pos_ned_m), *_points(route_after))
            cruise = target.speed_xy_m_s if math.isfinite(target.speed_xy_m_s) else cruise
        own = OwnShip(state.time_us, frame.home_from_origin(state.pos_ned_m), tuple(state.vel_ned_m_s), route, cruise,
                      self.avoidance.system_id)  # fmt: skip
        # the strategic detour waits while the reactive layer flies (a detour timed from before would jump)
        can_avoid = mission and not self.guard.engaged
        quiet = self.guard.engaged or mode in REACTIVE_MODES  # the reactive layer avoids in every autonomous mode
        decision = self.avoidance.update(own, reports, self.limits(geofence, obstacles), can_avoid, not landed,
                                         quiet=quiet)  # fmt: skip
        self.decision = decision
        for text in decision.texts:
            self.say(text)
        return decision.failsafe

    def bound(self, state: VehicleState, control: ControlLike, mode: FlightMode, target: NavTarget,
              dt_s: float, landed: LandedState = LandedState.IN_AIR) -> bool:  # fmt: skip
        """Bound this control step's reference: the reactive layer's (about the origin) is given to ``control``
        (which holds this step's reference: the mission's, the landing's or the detour's) when it binds. True when
        the departure hold keeps the vehicle on its pad (:meth:`TrafficGuard.on_pad`): the caller flies nothing.
        Position and landing targets only (an idle or velocity target is not the autopilot's own flight; a
        landing's position is its touchdown point)."""
        kind, frame = target.kind, self._frame
        if not self.busy or frame is None or (kind is not TargetKind.POSITION and kind is not TargetKind.LAND):
            return False
        ref = control.reference
        self.guard.taking_off = landed is LandedState.TAKEOFF  # still on the pad: no land detection yet
        self.guard.land_spot_ned_m = target.pos_ned_m if kind is TargetKind.LAND else None
        out = self.guard.step(state.time_us, dt_s, frame, state.pos_ned_m, state.vel_ned_m_s, ref.pos_ned_m,
                              ref.vel_ned_m_s, mode, kind is TargetKind.LAND, self.avoidance.table,
                              self.avoidance.params)  # fmt: skip
        if self.guard.texts:
            for text in self.guard.texts:
                self.say(text)
            self.guard.texts.clear()
        if out is None:
            return False
        if self.guard.on_pad(state.time_us, frame, state.pos_ned_m, state.vel_ned_m_s):
            return True
        control.override(out)
        return False

    def override(self, t_us: int, make: Callable[[Vec3, Vec3, Vec3], R]) -> R | None:
        """``make(pos about the origin, vel, acc)`` of the traffic detour at ``t_us``; None when none is flown."""
        decision, frame = self.decision, self._frame
        if decision is None or frame is None or decision.action is not decision.action.AVOID:
            return None
        setpoint = decision.setpoint(t_us)
        if setpoint is None:
            return None
        return make(frame.origin_from_home(setpoint[0]), setpoint[1], setpoint[2])


def _points(after: object) -> tuple[Vec3, ...]:
    """None, one point or an (n, 3) array of points, as a tuple of points."""
    if after is None:
        return ()
    rows = np.asarray(after, float).reshape(-1, 3)
    return tuple((float(r[0]), float(r[1]), float(r[2])) for r in rows)
