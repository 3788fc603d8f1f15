"""Detour candidates around the threat (paper §3.3): over, under, left, right; least Euclidean cost wins.

For each side the detour lies in a plane through the obstacle centre spanned by the horizontal
route direction ``e1`` and the side direction ``e2`` (up/down for over/under, right/left for the
sides); the third coordinate is interpolated linearly from the vehicle to the rejoin point. In that
plane the shortest path from the vehicle to the rejoin point around the safety circle of radius
``ρ = r + R_safe + margin`` is tangent–arc–tangent; its length is the candidate's Euclidean
cost. Cheap rules first (ground, altitude floor/ceiling, a column's unknown top), then, in order of
cost, the fitted Bézier (``bezier.fit_detour``) is checked against the dynamic limits, every
tracked obstacle (clearance >= R_safe + half the sample spacing), the altitude band and the
fences; the first candidate that passes is chosen.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence
from dataclasses import dataclass
from enum import Enum

import numpy as np

from .bezier import BezierPath, bernstein_matrix, fit_detour
from .geometry import FenceZone, path_clear_of_fences, polyline_length
from .obstacle_map import ObstacleArrays, ObstacleKind, TrackedObstacle

_UP_NED = np.array((0.0, 0.0, -1.0))
_ARC_STEP_RAD = math.radians(30.0)
_SAMPLE_STEP_M = 0.4
#: How many times blocking neighbours may be merged into the threat's volume before giving up.
MAX_CLUSTER_MERGES = 3


class DetourSide(Enum):
    """Which way a detour passes the obstacle (HOLD: no safe detour, brake and hover)."""

    OVER = "OVER"
    UNDER = "UNDER"
    LEFT = "LEFT"
    RIGHT = "RIGHT"
    HOLD = "HOLD"


class CandidateStatus(Enum):
    """Outcome of one candidate."""

    CHOSEN = "chosen"
    RULED_OUT = "ruled out"  # by a rule before fitting (ground, ceiling, column top unknown, fence)
    BLOCKED = "blocked"  # its fitted curve fails a check (obstacle, fence, limits)
    NOT_EVALUATED = "not evaluated"  # a cheaper candidate was chosen first


@dataclass(frozen=True, slots=True)
class CandidateReport:
    """One candidate's cost (tangent–arc–tangent length, m; inf when ruled out) and fate."""

    side: DetourSide
    cost_m: float
    status: CandidateStatus
    reason: str = ""


@dataclass(frozen=True, slots=True)
class DetourLimits:
    """What a detour must respect (altitudes above home; the ground is at altitude 0)."""

    r_safe_m: float
    margin_m: float
    v_max_m_s: float
    a_max_m_s2: float
    rejoin_m: float
    min_agl_m: float
    alt_floor_m: float
    alt_ceiling_m: float
    fences: tuple[FenceZone, ...] = ()
    cruise_m_s: float = 5.0  # detour speed when the vehicle flies slower (e.g. starts from a hover)


@dataclass(frozen=True, slots=True)
class DetourPlan:
    """A chosen detour: via polyline, the fitted Bézier path, its samples and checks."""

    side: DetourSide
    obstacle_id: int
    via_ned: np.ndarray  # (k+1, 3) tangent–arc–tangent polyline, vehicle -> rejoin
    path: BezierPath
    samples_ned: np.ndarray  # (m, 3) consecutive points <= _SAMPLE_STEP_M apart
    cost_m: float
    min_clearance_m: float  # over the samples, to every tracked obstacle surface
    rejoin_ned: np.ndarray


@dataclass(frozen=True, slots=True)
class DetourResult:
    """The plan (None when no candidate is safe) and the report of every candidate."""

    plan: DetourPlan | None
    candidates: tuple[CandidateReport, ...]


def _unit(v: np.ndarray) -> np.ndarray | None:
    n = float(np.linalg.norm(v))
    return v / n if n > 1e-9 else None


def _point_at_arclength(points: np.ndarray, s_m: float) -> tuple[np.ndarray, np.ndarray]:
    """Point at arc length ``s_m`` along a polyline (clamped) and the unit direction there."""
    left = max(s_m, 0.0)
    for a, b in itertools.pairwise(points):
        seg = float(np.linalg.norm(b - a))
        if seg < 1e-9:
            continue
        if left <= seg:
            return a + (b - a) * (left / seg), (b - a) / seg
        left -= seg
    tail = next(
        (b - a for a, b in zip(points[-2::-1], points[::-1], strict=False) if np.linalg.norm(b - a) > 1e-9), None
    )
    direction = _unit(tail) if tail is not None else None
    return points[-1].copy(), direction if direction is not None else np.array((1.0, 0.0, 0.0))


def _closest_arclength(points: np.ndarray, obstacle: TrackedObstacle) -> float:
    """Arc length of the polyline point nearest the obstacle centre (axis for a column)."""
    c = np.array(obstacle.center_ned)
    dims = slice(0, 3) if obstacle.kind is ObstacleKind.SPHERE else slice(0, 2)
    best_d, best_s, s0 = math.inf, 0.0, 0.0
    for a, b in itertools.pairwise(points):
        d = (b - a)[dims]
        seg = float(np.linalg.norm(b - a))
        dd = float(d @ d)
        t = 0.0 if dd < 1e-12 else min(max(float((c[dims] - a[dims]) @ d) / dd, 0.0), 1.0)
        dist = float(np.linalg.norm(a[dims] + t * d - c[dims]))
        if dist < best_d:
            best_d, best_s = dist, s0 + t * seg
        s0 += seg
    return best_s


def _tangent_angle(p_uw: np.ndarray, rho: float) -> float:
    """Angle of the tangent point from p to the circle |x| = ρ on the +w side (radial if inside)."""
    d = math.hypot(p_uw[0], p_uw[1])
    alpha = math.atan2(p_uw[1], p_uw[0])
    if d <= rho:
        return alpha
    beta = math.acos(rho / d)
    a1, a2 = alpha + beta, alpha - beta
    return a1 if math.sin(a1) >= math.sin(a2) else a2


def _arc_polyline_uw(p_uw: np.ndarray, j_uw: np.ndarray, rho: float) -> tuple[np.ndarray, float]:
    """Tangent–arc–tangent from p to j passing the circle on the +w side: via points (u, w) and length."""
    th_p, th_j = _tangent_angle(p_uw, rho), _tangent_angle(j_uw, rho)
    # angles measured so that moving from p (behind, u < 0) to j (ahead) decreases θ through π/2
    th_p = th_p % (2 * math.pi)
    th_j = th_j % (2 * math.pi)
    if th_j > th_p:
        th_j -= 2 * math.pi
    sweep = th_p - th_j
    if sweep > math.pi * 1.5 or (p_uw[1] >= rho and j_uw[1] >= rho):
        return np.empty((0, 2)), float(np.linalg.norm(j_uw - p_uw))  # the straight line already clears
    n = max(1, math.ceil(sweep / _ARC_STEP_RAD))
    step = sweep / n
    r_via = rho / math.cos(step / 2.0)  # circumscribed polygon: its chords stay outside ρ
    th = th_p - step * np.arange(n + 1)
    via = r_via * np.stack((np.cos(th), np.sin(th)), axis=1)
    length = (
        math.hypot(*(via[0] - p_uw))
        + float(np.linalg.norm(np.diff(via, axis=0), axis=1).sum())
        + math.hypot(*(j_uw - via[-1]))
    )
    return via, length


@dataclass(frozen=True, slots=True)
class _Candidate:
    side: DetourSide
    via_ned: np.ndarray
    cost_m: float
    rule: str  # non-empty: ruled out by this rule


def _build_candidate(
    side: DetourSide,
    pos: np.ndarray,
    rejoin: np.ndarray,
    obstacle: TrackedObstacle,
    e1: np.ndarray,
    rho: float,
    limits: DetourLimits,
) -> _Candidate:
    right = np.array((-e1[1], e1[0], 0.0))
    e2 = {DetourSide.OVER: _UP_NED, DetourSide.UNDER: -_UP_NED, DetourSide.RIGHT: right, DetourSide.LEFT: -right}[side]
    e3 = np.cross(e1, e2)
    c = np.array(obstacle.center_ned)
    if obstacle.kind is ObstacleKind.COLUMN and side in (DetourSide.OVER, DetourSide.UNDER):
        rule = "stands on the ground" if side is DetourSide.UNDER else "top unknown"
        return _Candidate(side, np.empty((0, 3)), math.inf, rule)
    basis = np.stack((e1, e2, e3))
    p_l, j_l = basis @ (pos - c), basis @ (rejoin - c)
    via_uw, length = _arc_polyline_uw(p_l[:2], j_l[:2], rho)
    du = j_l[0] - p_l[0]
    frac = np.clip((via_uw[:, 0] - p_l[0]) / du, 0.0, 1.0) if abs(du) > 1e-9 else np.full(len(via_uw), 0.5)
    third = p_l[2] + frac * (j_l[2] - p_l[2])
    via = c + np.column_stack((via_uw, third)) @ basis
    polyline = np.vstack((pos, via, rejoin))
    cost = polyline_length(polyline) if len(via) else length
    alts = -polyline[:, 2]
    if alts.min() < max(limits.min_agl_m, 0.0) - 1e-9:
        return _Candidate(side, polyline, cost, "ground")
    if alts.min() < limits.alt_floor_m - 1e-9:
        return _Candidate(side, polyline, cost, "altitude floor")
    if alts.max() > limits.alt_ceiling_m + 1e-9:
        return _Candidate(side, polyline, cost, "ceiling")
    return _Candidate(side, polyline, cost, "")


Obstacles = Sequence[TrackedObstacle] | ObstacleArrays


def as_arrays(obstacles: Obstacles) -> ObstacleArrays:
    """The obstacles as :class:`ObstacleArrays` (passed through when they already are)."""
    return obstacles if isinstance(obstacles, ObstacleArrays) else ObstacleArrays(tuple(obstacles))


def path_clearance(samples_ned: np.ndarray, obstacles: Obstacles) -> tuple[float, int]:
    """Smallest surface distance of the samples to any obstacle, and that obstacle's id (-1 if none)."""
    arrays = as_arrays(obstacles)
    if not len(arrays):
        return math.inf, -1
    per_obstacle = arrays.signed_distance(samples_ned).min(axis=0)
    i = int(per_obstacle.argmin())
    return float(per_obstacle[i]), int(arrays.ids[i])


def check_path(
    samples_ned: np.ndarray,
    start_ned: np.ndarray,
    obstacles: Obstacles,
    limits: DetourLimits,
    tol_m: float = 0.5 * _SAMPLE_STEP_M,
) -> str:
    """Why a sampled path is unsafe ("" when it is safe).

    Clearance to every obstacle must be >= R_safe + ``tol_m`` (default half the sample spacing:
    points between two samples are within that of one); an obstacle already nearer than that at the start must not
    get nearer. Altitudes stay in [max(min AGL, floor), ceiling]; fences are checked per segment.
    """
    arrays = as_arrays(obstacles)
    if len(arrays):
        need = np.minimum(limits.r_safe_m + tol_m, arrays.signed_distance(start_ned[None, :])[0] - 0.05)
        short = arrays.signed_distance(samples_ned).min(axis=0) - need
        worst = int(short.argmin())
        if short[worst] < 0.0:
            return f"obstacle {int(arrays.ids[worst])}"
    alts = -samples_ned[:, 2]
    if alts.min() < max(limits.min_agl_m, limits.alt_floor_m) - 1e-6:
        return "ground" if limits.min_agl_m >= limits.alt_floor_m else "altitude floor"
    if alts.max() > limits.alt_ceiling_m + 1e-6:
        return "ceiling"
    if path_clear_of_fences(limits.fences, samples_ned, 0.0) is not None:
        return "fence"
    return ""


def plan_detour(
    pos_ned: np.ndarray,
    vel_ned: np.ndarray,
    route_ned: np.ndarray,
    threat: TrackedObstacle,
    obstacles: Obstacles,
    limits: DetourLimits,
) -> DetourResult:
    """Choose and fit the least-cost safe detour around ``threat`` that rejoins ``route_ned``.

    ``route_ned`` is the route ahead of the vehicle (current target, next target, ...). The detour
    starts at ``pos_ned`` with ``vel_ned`` and rejoins the route ``ρ + rejoin_m`` past the point
    nearest the obstacle along the route at the speed it had (at least ``cruise_m_s``, at most v_max).
    If every side is blocked by other obstacles, the threat and the nearest blocker are wrapped in
    one enclosing volume and the sides are tried around it (up to MAX_CLUSTER_MERGES times).
    """
    pos = np.asarray(pos_ned, float)
    vel = np.asarray(vel_ned, float)
    route = np.vstack((pos, np.asarray(route_ned, float).reshape(-1, 3)))
    reports: dict[DetourSide, CandidateReport] = {}
    sides = (DetourSide.LEFT, DetourSide.RIGHT, DetourSide.OVER, DetourSide.UNDER)
    obstacles = as_arrays(obstacles)
    by_id = {o.obstacle_id: o for o in obstacles.obstacles}
    volume = threat
    for attempt in range(MAX_CLUSTER_MERGES + 1):
        chosen = _try_sides(pos, vel, route, volume, threat.obstacle_id, obstacles, limits, sides, reports)
        if chosen is not None:
            return DetourResult(chosen, tuple(reports[s] for s in sides))
        blockers = {int(r.reason.split()[1]) for r in reports.values() if r.reason.startswith("obstacle ")}
        blockers = {b for b in blockers if b in by_id}
        if not blockers or attempt == MAX_CLUSTER_MERGES:
            break
        c = np.array(volume.center_ned)
        nearest = min(blockers, key=lambda b: float(by_id[b].signed_distance(c[None, :])[0]))
        volume = enclosing_volume(volume, by_id[nearest])
    return DetourResult(None, tuple(reports[s] for s in sides))


def enclosing_volume(a: TrackedObstacle, b: TrackedObstacle) -> TrackedObstacle:
    """The smallest sphere (or, if either is a column, vertical column) enclosing two obstacles; keeps a's id."""
    column = ObstacleKind.COLUMN in (a.kind, b.kind)
    ca, cb = np.array(a.center_ned), np.array(b.center_ned)
    if column:
        cb[2] = ca[2]
    d = float(np.linalg.norm(cb - ca))
    if d + b.radius_m <= a.radius_m:
        c, r = ca, a.radius_m
    elif d + a.radius_m <= b.radius_m:
        c, r = cb, b.radius_m
    else:
        r = 0.5 * (d + a.radius_m + b.radius_m)
        c = ca + (cb - ca) * (r - a.radius_m) / d
    kind = ObstacleKind.COLUMN if column else ObstacleKind.SPHERE
    center = (float(c[0]), float(c[1]), float(c[2]))
    return TrackedObstacle(a.obstacle_id, kind, center, r, a.first_seen_us, a.last_seen_us, a.detections)


def _try_sides(
    pos: np.ndarray,
    vel: np.ndarray,
    route: np.ndarray,
    volume: TrackedObstacle,
    threat_id: int,
    obstacles: ObstacleArrays,
    limits: DetourLimits,
    sides: tuple[DetourSide, ...],
    reports: dict[DetourSide, CandidateReport],
) -> DetourPlan | None:
    """Build the four candidates around ``volume``, check them in order of cost; fill ``reports``."""
    rho = volume.radius_m + limits.r_safe_m + limits.margin_m
    s_rejoin = _closest_arclength(route, volume) + rho + limits.rejoin_m
    rejoin, route_dir = _point_at_arclength(route, s_rejoin)
    horiz = _unit(np.array((rejoin[0] - pos[0], rejoin[1] - pos[1], 0.0)))
    if horiz is None:
        horiz = _unit(np.array((route_dir[0], route_dir[1], 0.0)))
    e1 = horiz if horiz is not None else np.array((1.0, 0.0, 0.0))
    speed = min(limits.v_max_m_s, max(float(np.linalg.norm(vel)), limits.cruise_m_s))
    vel_end = route_dir * speed
    candidates = sorted(
        (_build_candidate(side, pos, rejoin, volume, e1, rho, limits) for side in sides), key=lambda c: c.cost_m
    )
    chosen: DetourPlan | None = None
    for cand in candidates:
        if cand.rule:
            reports[cand.side] = CandidateReport(cand.side, cand.cost_m, CandidateStatus.RULED_OUT, cand.rule)
            continue
        if chosen is not None:
            reports[cand.side] = CandidateReport(cand.side, cand.cost_m, CandidateStatus.NOT_EVALUATED)
            continue
        why = check_path(_densify(cand.via_ned, 1.0), pos, obstacles, limits, tol_m=0.0)  # cheap pre-check
        if not why:
            path = fit_detour(cand.via_ned, vel, vel_end, limits.v_max_m_s, limits.a_max_m_s2)
            if not path.limits_ok:
                why = "dynamic limits"
            else:
                samples = path.sample(_SAMPLE_STEP_M)
                why = check_path(samples, pos, obstacles, limits)
        if why:
            reports[cand.side] = CandidateReport(cand.side, cand.cost_m, CandidateStatus.BLOCKED, why)
            continue
        clearance, _ = path_clearance(samples, obstacles)
        samples.setflags(write=False)
        chosen = DetourPlan(cand.side, threat_id, cand.via_ned, path, samples, cand.cost_m, clearance, rejoin)
        reports[cand.side] = CandidateReport(cand.side, cand.cost_m, CandidateStatus.CHOSEN)
    return chosen


def _densify(polyline: np.ndarray, step_m: float) -> np.ndarray:
    """Points along a polyline at most ``step_m`` apart (vertices included)."""
    out = [polyline[:1]]
    for a, b in itertools.pairwise(polyline):
        n = max(1, math.ceil(float(np.linalg.norm(b - a)) / step_m))
        out.append(a + (b - a) * (np.arange(1, n + 1) / n)[:, None])
    return np.concatenate(out)


def brake_path(pos_ned: np.ndarray, vel_ned: np.ndarray, a_max_m_s2: float) -> BezierPath:
    """Straight constant deceleration to a hover (cubic Hermite with end velocity 0, |a| = |v|/T)."""
    pos = np.asarray(pos_ned, float)
    vel = np.asarray(vel_ned, float)
    speed = float(np.linalg.norm(vel))
    duration = max(speed / a_max_m_s2, 0.05)
    stop = pos + vel * duration / 2.0
    ctrl = np.stack((pos, pos + vel * duration / 3.0, stop, stop))[None]
    ctrl.setflags(write=False)
    durations = np.array((duration,))
    durations.setflags(write=False)
    return BezierPath(ctrl, durations, speed, speed / duration, True)


def sample_path(path: BezierPath) -> np.ndarray:
    """Samples of a path at the planner's checking step (for telemetry and checks)."""
    n = max(2, math.ceil(path.v_bound_m_s * float(path.durations_s.max()) / _SAMPLE_STEP_M))
    basis = bernstein_matrix(3, np.linspace(0.0, 1.0, n + 1))
    return np.einsum("mj,kjd->kmd", basis, path.ctrl_ned).reshape(-1, 3)
