"""Conflict resolution: the paper's Bézier detour generalised to moving traffic (paper §3.3, SPEC §13).

A resolution is one of a few maneuvers, tried in the order the rules of :mod:`autopilot.traffic.rules` prefer:
an offset of the route to the right of the encounter (or left), a climb or a descent, a stop, or a move aside
and hold when the vehicle is hovering. An offset detour is a C1 cubic Bézier chain (:func:`fit_detour`, the
planner's hodograph-bounded fit) through ``own position -> route(t1) + offset -> route(t2) + offset -> route(t3)``:
``t1`` is as soon as the offset can be reached, ``t2`` past the conflict window (the route is the mission's,
flown at cruise speed); it rejoins the route before the mission target (so every item is still reached), or, when
the window outlasts the leg, waits beside the target until clear. Each candidate is *predicted*: the vehicle
along the curve (then the route) against every track moving straight on, sampled over NAV_TRAFF_COLL_T (longer
when the conflict window is), scored by the smallest separation ratio to the volumes grown by NAV_TRAFF_MARGIN:
the moving obstacle is the track's separation volume swept along its course. A candidate that leaves the
altitude limits, crosses a fence or enters a known obstacle's safety sphere is refused with its reason. The
first candidate keeping separation wins; else the first keeping it from traffic with right of way; else the
one keeping the most.
"""

from __future__ import annotations

import bisect
import itertools
import math
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from enum import Enum

import numpy as np

from autopilot.planner.bezier import BezierPath, fit_detour
from autopilot.planner.geometry import path_clear_of_fences
from autopilot.planner.path_shapes import brake_path
from autopilot.traffic.cpa import predict_approach, separation_ratio
from autopilot.traffic.param_decls import SeparationVolume
from autopilot.traffic.tracks import TrafficTrack
from mavlink_bridge.contract.frames import Vec3

#: Prediction step (s) over the horizon.
PREDICT_STEP_S = 0.25
#: Via points closer than this (m) are merged.
MIN_VIA_SPACING_M = 1.0
#: Lead and lag (s) of the offset around the predicted loss-of-separation window.
WINDOW_PAD_S = 2.0
#: How far past the prediction a hold is checked against each track's straight line (s).
HOLD_LOOKAHEAD_S = 600.0


class Maneuver(Enum):
    ROUTE = "keep the route"
    RIGHT = "turn right"
    LEFT = "turn left"
    CLIMB = "climb"
    DESCEND = "descend"
    STOP = "stop"


@dataclass(frozen=True, slots=True)
class OwnShip:
    """The vehicle as the traffic avoidance sees it, about home (NED, m, m/s)."""

    t_us: int
    pos_home_ned_m: Vec3
    vel_ned_m_s: Vec3
    route_home_ned_m: tuple[Vec3, ...] = ()  # what it flies next (mission target first); empty: it hovers
    cruise_m_s: float = 5.0
    system_id: int = 1


@dataclass(frozen=True, slots=True)
class AvoidLimits:
    """Where a detour may go: speed and acceleration bounds, altitude band (NED down, about home), fences and
    known obstacles (objects with ``signed_distance(points)``), and the clearances from them."""

    v_max_m_s: float = 6.0
    a_max_m_s2: float = 3.0
    down_min_m: float = -math.inf  # the ceiling (most negative down allowed)
    down_max_m: float = -2.0  # the floor (CA_MIN_AGL_M above home)
    fences: tuple[object, ...] = ()
    fence_margin_m: float = 3.0
    obstacles: tuple[object, ...] = ()
    r_safe_m: float = 2.0


@dataclass(frozen=True, slots=True)
class Threat:
    """A track and the separation volume to plan for against it (``column``: the volume reaches down to the
    ground, :func:`autopilot.traffic.rules.owns_column`)."""

    track: TrafficTrack
    volume: SeparationVolume
    column: bool = False


@dataclass(frozen=True, slots=True)
class Resolution:
    """A chosen maneuver: its Bézier path about home from ``start_us`` (None: keep the route), whether the path's end
    is held until the conflict clears, the smallest predicted separation ratio (>= 1: kept) and why others lost."""

    maneuver: Maneuver
    offset_m: float
    path: BezierPath | None
    start_us: int
    hold_at_end: bool
    min_ratio: float
    refused: tuple[str, ...] = field(default=(), compare=False)
    offset_ned_m: Vec3 = (0.0, 0.0, 0.0)  # the offset held from the route (zero for a stop or the route)

    @property
    def safe(self) -> bool:
        return self.min_ratio >= 1.0

    def setpoint(self, t_us: int) -> tuple[Vec3, Vec3, Vec3] | None:
        """(pos, vel, acc) about home at ``t_us``; None once an unheld path is flown."""
        path = self.path
        if path is None:
            return None
        t_s = (t_us - self.start_us) * 1e-6
        if t_s > path.duration_s and not self.hold_at_end:
            return None
        return path.state_tuple(t_s)

    def describe(self) -> str:
        if self.maneuver in (Maneuver.ROUTE, Maneuver.STOP):
            return self.maneuver.value
        hold = ", hold" if self.hold_at_end else ""
        return f"{self.maneuver.value} {self.offset_m:.0f} m{hold}"


class RouteLine:
    """The route as a polyline from the vehicle, flown at cruise speed: position and direction by arclength."""

    def __init__(self, start: Vec3, points: Sequence[Vec3]) -> None:
        pts = [tuple(float(x) for x in start)]
        for p in points:
            if math.dist(pts[-1], p) > 1e-6:
                pts.append(tuple(float(x) for x in p))
        self.points = np.array(pts, float)
        seg = np.linalg.norm(np.diff(self.points, axis=0), axis=1) if len(pts) > 1 else np.zeros(0)
        self.cum = [0.0, *itertools.accumulate(seg.tolist())]
        self.length_m = self.cum[-1]
        at_target = not points or math.dist(pts[0], points[0]) <= 1e-6
        self.target_s_m = 0.0 if at_target else self.cum[1]  # arclength of the first point (the mission target)

    def at(self, s_m: float) -> Vec3:
        s = min(max(s_m, 0.0), self.length_m)
        i = min(max(bisect.bisect_right(self.cum, s) - 1, 0), len(self.cum) - 2) if len(self.cum) > 1 else 0
        if len(self.cum) < 2:
            p = self.points[0]
            return (float(p[0]), float(p[1]), float(p[2]))
        f = (s - self.cum[i]) / max(self.cum[i + 1] - self.cum[i], 1e-9)
        p = self.points[i] + f * (self.points[i + 1] - self.points[i])
        return (float(p[0]), float(p[1]), float(p[2]))

    def direction(self, s_m: float) -> Vec3:
        if self.length_m <= 0.0 or s_m >= self.length_m:
            return (0.0, 0.0, 0.0)
        i = min(max(bisect.bisect_right(self.cum, s_m) - 1, 0), len(self.cum) - 2)
        d = self.points[i + 1] - self.points[i]
        d = d / max(float(np.linalg.norm(d)), 1e-9)
        return (float(d[0]), float(d[1]), float(d[2]))


def predicted_min_ratio(own_ned_m: np.ndarray, times_s: np.ndarray, t_us: int, threats: Sequence[Threat],
                        hold: bool = False) -> float:  # fmt: skip
    """Smallest ``max(d_h/H, |d_v|/V)`` over samples ``own_ned_m`` (m, 3) at ``times_s`` after ``t_us`` and tracks.

    ``hold``: the vehicle stays at the last sample forever, so each track's closest approach to that point after
    the last sample counts too (a hold is only safe if the traffic passes clear of it, however late).
    """
    worst = math.inf
    for threat in threats:
        tr, vol = threat.track, threat.volume
        dt = times_s + (t_us - tr.t_us) * 1e-6
        rel = np.asarray(tr.pos_home_ned_m) + np.outer(dt, tr.vel_ned_m_s) - own_ned_m
        dv = np.maximum(rel[:, 2], 0.0) if threat.column else np.abs(rel[:, 2])
        ratio = np.maximum(np.hypot(rel[:, 0], rel[:, 1]) / vol.hor_m, dv / vol.ver_m)
        worst = min(worst, float(ratio.min()))
        if hold:
            r0, v = rel[-1], np.asarray(tr.vel_ned_m_s)
            approach = predict_approach(tuple(r0), tuple(v), HOLD_LOOKAHEAD_S, vol, threat.column)
            if approach.conflict:
                mid_s = 0.5 * (approach.loss_in_s + min(approach.loss_out_s, HOLD_LOOKAHEAD_S))
                worst = min(worst, 0.99 * separation_ratio(tuple(r0 + v * mid_s), vol, threat.column))
    return worst


class Resolver:
    """Builds and predicts the candidate maneuvers for one vehicle at one time."""

    def __init__(self, own: OwnShip, limits: AvoidLimits, horizon_s: float) -> None:
        self.own = own
        self.limits = limits
        self.horizon_s = horizon_s
        self.route = RouteLine(own.pos_home_ned_m, own.route_home_ned_m)
        self.cruise = max(own.cruise_m_s, 0.0) if self.route.length_m > 0.0 else 0.0
        self.times = self.sample_times(horizon_s)

    @staticmethod
    def sample_times(span_s: float) -> np.ndarray:
        return np.arange(0.0, span_s + 1e-9, PREDICT_STEP_S)

    # ------------------------------------------------------------------ predicted trajectories
    def _route_samples(self, s0_m: float, t0_s: float, times: np.ndarray) -> np.ndarray:
        return np.array([self.route.at(s0_m + self.cruise * max(t - t0_s, 0.0)) for t in times])

    def route_trajectory(self) -> np.ndarray:
        """Samples of the vehicle keeping its route (no maneuver)."""
        return self._route_samples(0.0, 0.0, self.times)

    def path_trajectory(self, path: BezierPath, s_after_m: float | None) -> np.ndarray:
        """Samples along ``path``, then along the route from arclength ``s_after_m`` (None: hold the end)."""
        out = np.empty((len(self.times), 3))
        end = path.duration_s
        for k, t in enumerate(self.times):
            if t <= end or s_after_m is None:
                out[k] = path.state_tuple(float(t))[0]
            else:
                out[k] = self.route.at(s_after_m + self.cruise * (float(t) - end))
        return out

    # ------------------------------------------------------------------ candidates
    def _where_refused(self, path: BezierPath) -> str | None:
        lim = self.limits
        if not path.limits_ok:  # the controller cannot follow it: a 17 m/s² "descend" fell faster than gravity
            return "beyond the speed or acceleration limit"
        samples = path.sample(1.0)
        start_down = self.own.pos_home_ned_m[2]
        floor = max(lim.down_max_m, start_down)  # a vehicle below the floor may stay as low as it is
        ceiling = min(lim.down_min_m, start_down)
        if float(samples[:, 2].max()) > floor + 0.1:
            return "below the altitude floor"
        if float(samples[:, 2].min()) < ceiling - 0.1:
            return "above the altitude ceiling"
        if lim.fences and path_clear_of_fences(lim.fences, samples, lim.fence_margin_m) is not None:  # type: ignore[arg-type]
            return "crosses the fence"
        for obstacle in lim.obstacles:
            if float(np.min(obstacle.signed_distance(samples))) < lim.r_safe_m:  # type: ignore[attr-defined]
                return "enters an obstacle's safety volume"
        return None

    def offset(self, maneuver: Maneuver, delta: Vec3, window: tuple[float, float]) -> tuple[BezierPath, float | None]:
        """The detour holding ``delta`` off the route over ``window`` (s), and the route arclength it rejoins at
        (None: it moves aside and holds there, the vehicle having no route to follow)."""
        lim, own, route = self.limits, self.own, self.route
        size = math.sqrt(sum(d * d for d in delta))
        ramp_s = 2.0 * math.sqrt(size / lim.a_max_m_s2) + 0.5
        t1 = ramp_s  # the offset is reached as early as the vehicle can, and held over the whole approach
        t2 = max(window[1] + WINDOW_PAD_S, t1 + 0.5)
        shift = lambda p: (p[0] + delta[0], p[1] + delta[1], p[2] + delta[2])  # noqa: E731
        end_vel: Vec3 = (0.0, 0.0, 0.0)
        s_rejoin: float | None = self.cruise * (t2 + ramp_s)
        target_s = route.target_s_m  # the detour rejoins before the mission target, so the target is reached
        a, b = shift(route.at(min(self.cruise * t1, target_s))), shift(route.at(min(self.cruise * t2, target_s)))
        if route.length_m <= 0.0:  # hovering: move aside and hold
            points, s_rejoin = [own.pos_home_ned_m, shift(own.pos_home_ned_m)], None
        elif s_rejoin is not None and s_rejoin < target_s:  # offset over the window, then back on the route
            points = [own.pos_home_ned_m, a, b, route.at(s_rejoin)]
            d = route.direction(s_rejoin)
            end_vel = (d[0] * self.cruise, d[1] * self.cruise, d[2] * self.cruise)
        else:  # the window outlasts the leg to the target: wait beside it until clear
            points, s_rejoin = [own.pos_home_ned_m, a, b], None
        pts = [points[0]]
        for p in points[1:]:
            if math.dist(pts[-1], p) >= MIN_VIA_SPACING_M:
                pts.append(p)
        if len(pts) < 2:
            pts.append(points[-1] if math.dist(points[0], points[-1]) > 1e-6 else shift(points[0]))
        if s_rejoin is None:
            return self._fit_and_stop(pts), None
        path = fit_detour(np.array(pts), np.array(own.vel_ned_m_s), np.array(end_vel), lim.v_max_m_s, lim.a_max_m_s2)
        return path, s_rejoin

    def _fit_and_stop(self, pts: list[Vec3]) -> BezierPath:
        """The chain through ``pts`` at cruise speed up to a braking distance before the last, then a straight
        constant-deceleration stop on it (fit_detour alone would spread the slowdown over the whole last leg).
        When that is beyond the limits (a moving vehicle turning to a point close by), the chain that simply
        stops at the last point, which takes longer and may overshoot the turn, if that one is within them."""
        path = self._cruise_and_stop(pts)
        if path.limits_ok:
            return path
        lim = self.limits
        slow = fit_detour(np.array(pts), np.array(self.own.vel_ned_m_s), np.zeros(3), lim.v_max_m_s, lim.a_max_m_s2)
        return slow if slow.limits_ok else path

    def _cruise_and_stop(self, pts: list[Vec3]) -> BezierPath:
        lim = self.limits
        last, prev = np.array(pts[-1]), np.array(pts[-2])
        leg = float(np.linalg.norm(last - prev))
        direction = (last - prev) / max(leg, 1e-9)
        speed = min(max(self.own.cruise_m_s, 0.5), lim.v_max_m_s, math.sqrt(lim.a_max_m_s2 * leg))
        brake_m = speed * speed / (2.0 * lim.a_max_m_s2)
        head = [*pts[:-1], tuple(last - direction * brake_m)]
        if math.dist(head[-1], head[-2]) < 0.5:
            head = head[:-1]  # too short a leg to cruise: brake from the previous point
        if len(head) < 2:
            return fit_detour(np.array(pts), np.array(self.own.vel_ned_m_s), np.zeros(3), lim.v_max_m_s, lim.a_max_m_s2)
        fit = fit_detour(
            np.array(head), np.array(self.own.vel_ned_m_s), direction * speed, lim.v_max_m_s, lim.a_max_m_s2
        )
        stop = brake_path(fit.end_ned, direction * speed, lim.a_max_m_s2)
        ctrl = np.concatenate((fit.ctrl_ned, stop.ctrl_ned))
        ctrl.setflags(write=False)
        durations = np.concatenate((fit.durations_s, stop.durations_s))
        durations.setflags(write=False)
        return BezierPath(ctrl, durations, max(fit.v_bound_m_s, stop.v_bound_m_s),
                          max(fit.a_bound_m_s2, stop.a_bound_m_s2), fit.limits_ok)  # fmt: skip

    def stop(self) -> BezierPath:
        return brake_path(np.array(self.own.pos_home_ned_m), np.array(self.own.vel_ned_m_s), self.limits.a_max_m_s2)

    def choose(self, plans: Sequence[tuple[Maneuver, float, Vec3]], window: tuple[float, float],
               threats: Sequence[Threat], must_clear: Sequence[Threat]) -> Resolution:  # fmt: skip
        """The first of ``plans`` (maneuver, size, offset) keeping separation from every threat; else the first
        keeping it from ``must_clear`` (manned traffic and those with right of way); else the best."""
        own = self.own
        # past the horizon as far as the conflict window (plus the rejoin) reaches, at most twice the horizon
        span = min(2.0 * self.horizon_s, max(self.horizon_s, window[1] + WINDOW_PAD_S + 5.0))
        self.times = self.sample_times(span)
        results: list[tuple[Resolution, float]] = []
        refused: list[str] = []
        for maneuver, size, delta in plans:
            if maneuver is Maneuver.ROUTE:
                traj, path, s_after, hold = self.route_trajectory(), None, None, False
            elif maneuver is Maneuver.STOP:
                path, s_after, hold = self.stop(), None, True
                traj = self.path_trajectory(path, None)
            else:
                path, s_after = self.offset(maneuver, delta, window)
                hold = s_after is None
                traj = self.path_trajectory(path, s_after)
            if path is not None:
                why = self._where_refused(path)
                if why is not None:
                    refused.append(f"{maneuver.value}: {why}")
                    continue
            ratio = predicted_min_ratio(traj, self.times, own.t_us, threats, hold)
            must = predicted_min_ratio(traj, self.times, own.t_us, must_clear, hold) if must_clear else math.inf
            res = Resolution(maneuver, size, path, own.t_us, hold, ratio, (), delta)
            if ratio >= 1.0:
                return replace(res, refused=tuple(refused))
            results.append((res, must))
        if not results:
            stop = self.stop()
            ratio = predicted_min_ratio(self.path_trajectory(stop, None), self.times, own.t_us, threats, True)
            return Resolution(Maneuver.STOP, 0.0, stop, own.t_us, True, ratio, tuple(refused))
        for res, must in results:
            if must >= 1.0:
                return replace(res, refused=tuple(refused))
        best = max(results, key=lambda rm: rm[0].min_ratio)[0]
        return replace(best, refused=tuple(refused))
