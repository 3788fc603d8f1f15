"""Detour candidates around the threat (paper §3.3): over, under, left, right; least Euclidean cost wins.

For each side the detour is the tangent–arc–tangent path from the vehicle to the rejoin point around the
safety circle of radius ``ρ = r + R_safe + margin`` in that side's plane (:mod:`.detour_geometry`); its
length is the candidate's Euclidean cost. Its checks are in :mod:`.detour_checks`.

The rejoin point lies ``ρ + rejoin_m`` along the route past the route's *first* pass by the
obstacle (progress along a self-crossing route is monotone: a later pass of the same place is not
where the vehicle is). The route after the rejoin point, for the vehicle's stopping distance plus
``CONTINUATION_S`` of flight, must clear every obstacle by R_safe too, and so must the straight ray along
the route's direction there (a corner just past the rejoin point cannot be turned at speed), both inside the
fence: a detour must not hand the vehicle back to the route where it cannot brake or turn before the next
safety volume.

Reachable mission items are never skipped (SPEC §7, issue 22; :mod:`.reachability`): the detour follows the
route through the reachable items before the obstacle whose legs are clear, leaves it after the last of them,
and rejoins *at* the first reachable item past the obstacle when the plain rejoin point lies beyond it
(arriving at cruise speed, or at rest when the route after the item is not clear). Only unreachable items
(inside a safety volume or the fence margin) and via points around the fence are passed.

One search (:func:`plan_detour`), in plain Python until a curve is fitted (numpy's per-call overhead
dominates on a handful of points):

1. the four sides around the threat are built once (tangent–arc–tangent polylines), ruled out by
   cheap rules (ground, altitude floor/ceiling, a column's unknown top) and checked exactly, segment
   by segment, against every tracked obstacle's R_safe volume and the fences;
2. while a side blocked by other obstacles is cheaper than the best open candidate, the threat's
   volume is merged with the nearest blocker (:func:`enclosing_volume`, up to ``MAX_CLUSTER_MERGES``
   times) and the four sides are built around the cluster: candidates of every merge level are
   ranked together by cost;
3. only the cheapest open candidate is fitted (``bezier.fit_detour``) and its curve checked against
   the dynamic limits, every obstacle (clearance >= R_safe + half the sample spacing), the altitude
   band and the fences; on failure the next one is, and the first that passes is chosen. A side
   whose curve broke the dynamic limits is not fitted again around a larger cluster (it only turns
   harder).
"""

from __future__ import annotations

import heapq
import itertools
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from .bezier import fit_detour
from .detour_checks import (
    Obstacles,
    altitude_rule,
    as_arrays,
    check_samples,
    clearance_need,
    near_hull,
    polyline_blocker,
)
from .detour_geometry import V3, RoutePolyline, side_polyline
from .detour_types import CandidateReport, CandidateStatus, DetourLimits, DetourPlan, DetourResult, DetourSide
from .geometry import path_clear_of_fences
from .obstacle_map import ObstacleArrays, ObstacleKind, TrackedObstacle, row_signed_distance
from .path_shapes import SAMPLE_STEP_M, enclosing_volume
from .reachability import unreachable_reason

#: How many times blocking neighbours may be merged into the threat's volume before giving up.
MAX_CLUSTER_MERGES = 3
#: The route after the rejoin point is checked for the stopping distance plus this many seconds of flight.
CONTINUATION_S = 2.0
#: A fitted curve's clearance is evaluated to the obstacles within R_safe + this of its control hull.
_CLEARANCE_REACH_M = 1.0
#: How many times the rejoin point is pushed past a later pass of the same obstacle(s) on the route.
_MAX_REJOIN_PUSHES = 3
#: A route item this near the vehicle along the route is where it is (the executor reaches it), not ahead.
_AT_WAYPOINT_M = 0.5
#: ``_Search._handoff``: the route after the rejoin point leaves the fence.
_FENCE_AFTER = -2


@dataclass(slots=True)
class _Candidate:
    """One side around one merge level's volume, as the search sees it (mutable within one search)."""

    side: DetourSide
    level: int
    via: list[V3]  # vehicle, via points, rejoin
    cost_m: float
    status: CandidateStatus | None = None  # None: open (passed the polyline checks, not fitted yet)
    reason: str = ""

    def report(self) -> CandidateReport:
        return CandidateReport(self.side, self.cost_m, self.status or CandidateStatus.NOT_EVALUATED, self.reason)


@dataclass(slots=True)
class _Level:
    """One merge level: the volume, where the detours around it rejoin, and its four candidates."""

    volume: TrackedObstacle
    members: frozenset[int]  # obstacle ids the volume encloses
    rejoin: V3
    route_dir: V3
    rejoin_index: int
    continuation: list[V3]
    candidates: list[_Candidate]
    blockers: set[int]  # obstacles (not members) that block a candidate: merging one may open it
    bound_m: float  # least cost of a candidate so blocked (a merge cannot be cheaper than that side was)
    stop: bool = False  # the detour ends at a waypoint at rest
    prefix_index: int = -1  # the last route row the detour passes through before leaving the route (-1: none)


_SIDES = (DetourSide.LEFT, DetourSide.RIGHT, DetourSide.OVER, DetourSide.UNDER)


def _build_candidate(
    side: DetourSide, level: int, pos: V3, rejoin: V3, volume: TrackedObstacle, e1: V3, rho: float, limits: DetourLimits
) -> _Candidate:
    """The tangent–arc–tangent polyline on one side, its cost and any rule that rules it out."""
    if volume.kind is ObstacleKind.COLUMN and side in (DetourSide.OVER, DetourSide.UNDER):
        rule = "stands on the ground" if side is DetourSide.UNDER else "top unknown"
        return _Candidate(side, level, [], math.inf, CandidateStatus.RULED_OUT, rule)
    points, length = side_polyline(side, pos, rejoin, volume.center_ned, e1, rho)
    rule = altitude_rule(points, limits)
    if rule:
        return _Candidate(side, level, points, length, CandidateStatus.RULED_OUT, rule)
    return _Candidate(side, level, points, length)


def _densify(points: Sequence[V3], step_m: float) -> np.ndarray:
    """Points along a polyline at most ``step_m`` apart (vertices included), ``(m, 3)``."""
    poly = np.asarray(points, float).reshape(-1, 3)
    out = [poly[:1]]
    for a, b in itertools.pairwise(poly):
        n = max(1, math.ceil(float(np.linalg.norm(b - a)) / step_m))
        out.append(a + (b - a) * (np.arange(1, n + 1) / n)[:, None])
    return np.concatenate(out)


# ------------------------------------------------------------------------------- the search


def _block(lvl: _Level, cand: _Candidate, oid: int) -> None:
    """Mark a candidate blocked by obstacle ``oid``; a blocker outside the volume is a merge option."""
    cand.status, cand.reason = CandidateStatus.BLOCKED, f"obstacle {oid}"
    if oid not in lvl.members:
        lvl.blockers.add(oid)
        lvl.bound_m = min(lvl.bound_m, cand.cost_m)


class _Search:
    """One detour search from a vehicle state: merge levels, candidates, fits."""

    def __init__(
        self,
        pos: np.ndarray,
        vel: np.ndarray,
        route: np.ndarray,
        arrays: ObstacleArrays,
        limits: DetourLimits,
        items: Sequence[bool] | None = None,
    ) -> None:
        self.pos_np, self.vel_np = pos, vel
        self.pos: V3 = (float(pos[0]), float(pos[1]), float(pos[2]))
        self.route = RoutePolyline([self.pos] + [(float(p[0]), float(p[1]), float(p[2])) for p in route])
        # the route rows a detour flies through or rejoins at instead of passing: mission items (via points around
        # the fence may be passed), checked for reachability only when a detour would pass them
        self.route_np = route
        self.items = [True] * len(route) if items is None else [bool(f) for f in items][: len(route)]
        self._reachable: dict[int, bool] = {}
        self.arrays, self.limits = arrays, limits
        self.rows = arrays.rows
        # an obstacle the vehicle is already nearer than R_safe must not get nearer (cf. check_path)
        self.need = clearance_need(self.pos, arrays, limits.r_safe_m)
        self.need_curve = clearance_need(self.pos, arrays, limits.r_safe_m + 0.5 * SAMPLE_STEP_M)
        self.reach_curve = [n + _CLEARANCE_REACH_M for n in self.need_curve]
        self.need_route = [limits.r_safe_m] * len(self.rows)
        speed = math.sqrt(float(vel[0]) ** 2 + float(vel[1]) ** 2 + float(vel[2]) ** 2)
        self.speed_end = min(limits.v_max_m_s, max(speed, limits.cruise_m_s))
        self.continuation_m = self.speed_end**2 / (2.0 * limits.a_max_m_s2) + CONTINUATION_S * self.speed_end

    def level(self, volume: TrackedObstacle, members: frozenset[int], index: int) -> _Level:
        """Rejoin point, route continuation and the four candidates around ``volume``."""
        lim = self.limits
        rho = volume.radius_m + lim.r_safe_m + lim.margin_m
        planar = volume.kind is ObstacleKind.COLUMN
        s_pass = self.route.first_pass(volume.center_ned, planar, rho)
        s_rejoin = s_pass + rho + lim.rejoin_m
        prefix, s_start, prefix_index = self._prefix(s_pass)
        blocked_by = -1
        for _ in range(_MAX_REJOIN_PUSHES + 1):
            continuation, blocked_by = self._handoff(s_rejoin)
            if blocked_by < 0 or blocked_by not in members:
                break
            # the route passes the volume again soon after the rejoin point: rejoin after that pass
            sub = RoutePolyline(continuation)
            s_rejoin += sub.first_pass(volume.center_ned, planar, rho) + rho + lim.rejoin_m
        stop = False
        s_waypoint = self._reachable_before(s_rejoin, s_start)
        if s_waypoint is not None:  # rejoin at the waypoint, never past it (at rest if the route after it is blocked)
            s_rejoin = s_waypoint
            continuation, blocked_by = self._handoff(s_rejoin)
            stop = blocked_by != -1
            if stop:
                continuation = continuation[:1]
            blocked_by = -1
        rejoin, route_dir, seg = self.route.at(s_rejoin)
        start = prefix[-1]
        hx, hy = rejoin[0] - start[0], rejoin[1] - start[1]
        h = math.hypot(hx, hy)
        if h < 1e-9:
            hx, hy = route_dir[0], route_dir[1]
            h = math.hypot(hx, hy)
        e1 = (hx / h, hy / h, 0.0) if h > 1e-9 else (1.0, 0.0, 0.0)
        cands = [_build_candidate(side, index, start, rejoin, volume, e1, rho, lim) for side in _SIDES]
        if len(prefix) > 1:  # along the route through the reachable items before the obstacle, then around it
            for cand in cands:
                if cand.via:
                    cand.via = prefix[:-1] + cand.via
                    cand.cost_m += s_start
        lvl = _Level(volume, members, rejoin, route_dir, seg, continuation, cands, set(), math.inf, stop, prefix_index)
        for cand in cands:
            if cand.status is not None:
                continue
            if blocked_by == _FENCE_AFTER:
                cand.status, cand.reason = CandidateStatus.BLOCKED, "fence after the rejoin point"
                continue
            oid = blocked_by if blocked_by >= 0 else polyline_blocker(cand.via, self.rows, self.need)
            if oid >= 0:
                _block(lvl, cand, oid)
            elif lim.fences and path_clear_of_fences(lim.fences, np.array(cand.via), 0.0) is not None:
                cand.status, cand.reason = CandidateStatus.BLOCKED, "fence"
        return lvl

    def _handoff(self, s_rejoin: float) -> tuple[list[V3], int]:
        """The route after a rejoin at ``s_rejoin`` for ``continuation_m`` and what blocks handing the vehicle back
        there: an obstacle id, ``_FENCE_AFTER`` or -1 (clear). Checked on that stretch of route and on the straight
        ray along the route's direction at the rejoin point (the vehicle cannot turn at a corner just after it: the
        threat check that runs when the detour ends looks along the velocity as far; routing benchmark world 478),
        against the obstacles' safety volumes and the fences (the route handed over may be a straight leg whose
        via points around the fence an earlier detour consumed; world 167)."""
        continuation = self.route.stretch(s_rejoin, self.continuation_m)
        if len(continuation) < 2:
            return continuation, -1
        paths = [continuation]
        if len(continuation) > 2:  # a corner within reach: the ray differs from the route
            (x, y, z), (dx, dy, dz), _ = self.route.at(s_rejoin)
            m = self.continuation_m
            paths.append([(x, y, z), (x + dx * m, y + dy * m, z + dz * m)])
        for path in paths:
            blocker = polyline_blocker(path, self.rows, self.need_route)
            if blocker >= 0:
                return continuation, blocker
        fences = self.limits.fences
        if fences and any(path_clear_of_fences(fences, np.array(p), 0.0) is not None for p in paths):
            return continuation, _FENCE_AFTER
        return continuation, -1

    def _is_reachable(self, k: int) -> bool:
        """Route row ``k`` lies outside every safety volume and the fence margin (cached per search)."""
        if k not in self._reachable:
            lim = self.limits
            why = unreachable_reason(self.route_np[k], self.arrays, lim.r_safe_m, lim.fences, lim.fence_margin_m)
            self._reachable[k] = not why
        return self._reachable[k]

    def _prefix(self, s_pass: float) -> tuple[list[V3], float, int]:
        """The route from the vehicle through the reachable items before the volume's first pass (at ``s_pass``),
        up to the first unreachable one or the first whose leg is not clear: the detour follows it and leaves the
        route at its end. Returns the polyline (the vehicle alone when there is no such item), its arc length and
        the route row of its last item (-1: none)."""
        cum = self.route.cum
        s_end, k_end = 0.0, -1
        for k, item in enumerate(self.items):
            s_k = cum[k + 1]
            if s_k >= s_pass:
                break
            if not item or s_k < _AT_WAYPOINT_M:
                continue
            if not self._is_reachable(k):
                break
            if polyline_blocker(self.route.stretch(s_end, s_k - s_end), self.rows, self.need) >= 0:
                break  # the route to it is not clear: leave it before
            s_end, k_end = s_k, k
        if k_end < 0:
            return [self.pos], 0.0, -1
        return self.route.stretch(0.0, s_end), s_end, k_end

    def _reachable_before(self, s_rejoin: float, s_after: float) -> float | None:
        """Arc length of the first reachable route item past ``s_after`` that a rejoin at ``s_rejoin`` would pass
        (None: none). Items within ``_AT_WAYPOINT_M`` of the vehicle along the route count as where it is."""
        cum = self.route.cum
        for k, item in enumerate(self.items):
            s_k = cum[k + 1]
            if s_k >= s_rejoin - 1e-6:
                return None
            if item and s_k > max(s_after + 1e-6, _AT_WAYPOINT_M) and self._is_reachable(k):
                return s_k
        return None

    def merged(self, lvl: _Level, index: int) -> _Level:
        """The next level: ``lvl``'s volume merged with its blocker nearest the volume's centre."""
        c = lvl.volume.center_ned
        by_id = {row[0]: row for row in self.rows}
        nearest = min(lvl.blockers, key=lambda oid: (row_signed_distance(by_id[oid], c), oid))
        other = next(o for o in self.arrays.obstacles if o.obstacle_id == nearest)
        return self.level(enclosing_volume(lvl.volume, other), lvl.members | {nearest}, index)

    def fit(self, cand: _Candidate, lvl: _Level, threat_id: int) -> DetourPlan | str:
        """The checked Bézier detour of a candidate, or why it fails."""
        lim = self.limits
        s = 0.0 if lvl.stop else self.speed_end
        vel_end = (lvl.route_dir[0] * s, lvl.route_dir[1] * s, lvl.route_dir[2] * s)
        path = fit_detour(cand.via, self.vel_np, vel_end, lim.v_max_m_s, lim.a_max_m_s2)
        if not path.limits_ok:
            return "dynamic limits"
        samples, times = path.sample_with_times(SAMPLE_STEP_M)
        near = near_hull(path.ctrl_ned, self.rows, self.reach_curve)
        why, clearance = check_samples(samples, self.need_curve, self.arrays, lim, near)
        if why:
            return why
        samples.setflags(write=False)
        times.setflags(write=False)
        via = np.array(cand.via)
        via.setflags(write=False)
        continuation = _densify(lvl.continuation, SAMPLE_STEP_M)
        continuation.setflags(write=False)
        return DetourPlan(
            cand.side,
            threat_id,
            via,
            path,
            samples,
            cand.cost_m,
            clearance,
            np.array(lvl.rejoin),
            lvl.rejoin_index,
            continuation,
            times,
            lvl.stop,
            lvl.prefix_index,
        )


def plan_detour(
    pos_ned: np.ndarray,
    vel_ned: np.ndarray,
    route_ned: np.ndarray,
    threat: TrackedObstacle,
    obstacles: Obstacles,
    limits: DetourLimits,
    route_items: Sequence[bool] | None = None,
) -> DetourResult:
    """Choose and fit the least-cost safe detour around ``threat`` that rejoins ``route_ned``.

    ``route_ned`` is the route ahead of the vehicle (current target, next target, ...). The detour
    starts at ``pos_ned`` with ``vel_ned`` and rejoins the route ``ρ + rejoin_m`` past its first pass
    by the obstacle, along the route at the speed it had (at least ``cruise_m_s``, at most v_max).
    Candidates around the threat and around clusters of it with blocking neighbours (up to
    ``MAX_CLUSTER_MERGES`` merges) are ranked by cost; the cheapest that passes every check is chosen
    (module docstring). The reports are those of the chosen candidate's merge level (the last level
    built when none passes).

    A detour never passes a reachable mission item (``route_items`` flags the rows of ``route_ned`` that are
    items, None: all; reachable: :func:`~autopilot.planner.reachability.unreachable_reason` is empty): it
    flies through those before the obstacle (``DetourPlan.prefix_route_index``) and ends at the first one past
    it, along the route at speed, or at rest when the route after it is not clear for the stopping distance
    plus ``CONTINUATION_S``.
    """
    search = _Search(
        np.asarray(pos_ned, float),
        np.asarray(vel_ned, float),
        np.asarray(route_ned, float).reshape(-1, 3),
        as_arrays(obstacles),
        limits,
        route_items,
    )
    levels = [search.level(threat, frozenset((threat.obstacle_id,)), 0)]
    heap: list[tuple[float, int, _Candidate]] = []
    seq = 0

    def push(lvl: _Level) -> None:
        nonlocal seq
        for cand in lvl.candidates:
            if cand.status is None:
                heapq.heappush(heap, (cand.cost_m, seq, cand))
            seq += 1

    push(levels[0])
    dynamic_failed: set[DetourSide] = set()
    chosen: DetourPlan | None = None
    chosen_level = -1
    while True:
        last = levels[-1]
        best = heap[0][0] if heap else math.inf
        if len(levels) <= MAX_CLUSTER_MERGES and last.blockers and last.bound_m < best:
            levels.append(search.merged(last, len(levels)))
            push(levels[-1])
            continue
        if not heap:
            break
        cand = heapq.heappop(heap)[2]
        lvl = levels[cand.level]
        if cand.side in dynamic_failed:
            cand.status, cand.reason = CandidateStatus.BLOCKED, "dynamic limits"
            continue
        result = search.fit(cand, lvl, threat.obstacle_id)
        if isinstance(result, DetourPlan):
            cand.status, chosen, chosen_level = CandidateStatus.CHOSEN, result, cand.level
            break
        if result.startswith("obstacle "):
            _block(lvl, cand, int(result.split()[1]))
        else:
            cand.status, cand.reason = CandidateStatus.BLOCKED, result
            if result == "dynamic limits":
                dynamic_failed.add(cand.side)
    reported = levels[chosen_level] if chosen is not None else levels[-1]
    return DetourResult(chosen, tuple(c.report() for c in reported.candidates))
