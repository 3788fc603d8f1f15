"""The detour planner's inputs and results: sides, candidate reports, limits, the chosen plan."""

from __future__ import annotations

from dataclasses import dataclass, field
from enum import Enum

import numpy as np

from .bezier import BezierPath
from .geometry import FenceZone


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
    RULED_OUT = "ruled out"  # by a rule before fitting (ground, ceiling, column top unknown)
    BLOCKED = "blocked"  # its polyline or fitted curve fails a check (obstacle, fence, limits)
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
    fence_margin_m: float = 0.0  # CA_FENCE_MARG_M: a waypoint this near a fence boundary is not rejoined at


@dataclass(frozen=True, slots=True)
class DetourPlan:
    """A chosen detour: via polyline, the fitted Bézier path, its samples and checks.

    ``rejoin_route_index`` is the index, in the route the detour was planned on (0 = the current
    target, k = the k-th waypoint after it), of the waypoint that ends the route leg the detour
    rejoins: once the detour is flown, the route resumes toward it (the waypoints before it were
    bypassed). ``continuation_ned`` is the route after the rejoin point that was checked clear.
    ``stops_at_rejoin``: the detour ends at a reachable waypoint at rest (the route after it was not clear
    for the stopping distance), so the next leg starts from a hover. ``prefix_route_index``: the detour first
    follows the route through its points up to this one (reachable items before the obstacle; -1: none), which
    the vehicle reaches on the way and which are therefore not bypassed.
    """

    side: DetourSide
    obstacle_id: int
    via_ned: np.ndarray  # (k+1, 3) tangent–arc–tangent polyline, vehicle -> rejoin
    path: BezierPath
    samples_ned: np.ndarray  # (m, 3) consecutive points <= _SAMPLE_STEP_M apart
    cost_m: float
    min_clearance_m: float  # over the samples, to the tracked obstacles within R_safe + 1 m of the curve (inf: none)
    rejoin_ned: np.ndarray
    rejoin_route_index: int = 0
    continuation_ned: np.ndarray = field(default_factory=lambda: np.empty((0, 3)))
    sample_times_s: np.ndarray = field(default_factory=lambda: np.empty(0))  # time of each sample on the path
    stops_at_rejoin: bool = False
    prefix_route_index: int = -1


@dataclass(frozen=True, slots=True)
class DetourResult:
    """The plan (None when no candidate is safe) and the report of every candidate."""

    plan: DetourPlan | None
    candidates: tuple[CandidateReport, ...]


# ------------------------------------------------------------------------------- scalar geometry
