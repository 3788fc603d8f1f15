"""The planner's state, decisions and per-step output (the messages ``AvoidancePlanner`` returns)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import Enum

import numpy as np

from mavlink_bridge.contract.wire import Vec3, fast_frozen_init

from .bezier import BezierPath
from .detour import CandidateReport, CandidateStatus, DetourPlan, DetourSide
from .obstacle_map import TrackedObstacle
from .path_shapes import sample_path
from .threat import Threat


class PlannerState(Enum):
    """What the planner is doing."""

    CLEAR = "clear"  # route clear: no override
    DETOUR = "detour"  # flying a Bézier detour
    HOLD = "hold"  # no safe detour: braking / hovering, retrying
    DISABLED = "disabled"  # CA_ENABLE = 0: obstacles are mapped only


class DecisionReason(Enum):
    """Why a decision was taken."""

    THREAT = "threat"  # a conflict appeared on the route or velocity direction
    REPLAN = "replan"  # new obstacles made the active detour unsafe
    RETRY = "retry"  # retry from HOLD


@dataclass(frozen=True, slots=True)
class AvoidanceDecision:
    """One avoidance decision: which way, why, and the cost of every candidate."""

    time_us: int
    obstacle_id: int
    distance_m: float  # vehicle to obstacle surface
    side: DetourSide
    reason: DecisionReason
    candidates: tuple[CandidateReport, ...]

    @property
    def text(self) -> str:
        """e.g. ``avoid: obstacle 3 at 12.4 m, going LEFT (cost 18.2 m vs over 24.1 m, under ruled out: ground)``."""
        head = "avoid: " + ("replan, " if self.reason is DecisionReason.REPLAN else "")
        head += f"obstacle {self.obstacle_id} at {self.distance_m:.1f} m, "
        others = []
        chosen_cost = math.nan
        for c in self.candidates:
            name = c.side.value.lower()
            if c.status is CandidateStatus.CHOSEN:
                chosen_cost = c.cost_m
            elif c.status is CandidateStatus.NOT_EVALUATED:
                others.append(f"{name} {c.cost_m:.1f} m")
            else:
                others.append(f"{name} ruled out: {c.reason}")
        if self.side is DetourSide.HOLD:
            return head + "no safe detour, holding (" + ", ".join(others) + ")"
        return head + f"going {self.side.value} (cost {chosen_cost:.1f} m vs " + ", ".join(others) + ")"

    @property
    def short_text(self) -> str:
        """At most 50 characters (one MAVLink 1 STATUSTEXT)."""
        return f"avoid obs {self.obstacle_id} {self.distance_m:.1f}m: {self.side.value}"[:50]


@dataclass(frozen=True, slots=True)
class DetourSetpoint:
    """The reference override while avoiding (NED, SI): position, velocity and acceleration feed-forward."""

    pos_ned_m: Vec3
    vel_ned_m_s: Vec3
    acc_ned_m_s2: Vec3


@fast_frozen_init
@dataclass(frozen=True, slots=True)
class PlannerOutput:
    """Everything one ``update`` produced (for the runner, telemetry and STATUSTEXT)."""

    time_us: int
    state: PlannerState
    setpoint: DetourSetpoint | None  # None: follow the route
    detour: DetourPlan | None  # the active detour (Bézier control points + samples) or None
    hold_path: BezierPath | None  # the braking path while in HOLD
    decisions: tuple[AvoidanceDecision, ...]  # decisions taken this update
    obstacles: tuple[TrackedObstacle, ...]
    threat: Threat | None
    clearance_m: float  # vehicle to the nearest tracked obstacle surface (inf if none)
    look_ahead_ned: Vec3 | None = None  # where the forward camera should look (reference LOOK_AHEAD_S ahead)
    replanned: bool = False  # a detour search ran in this update (for planning-time statistics)
    #: Waypoints of this update's route (0 = ``route_target_ned``, k = the k-th of ``route_next_ned``) that the
    #: active or last detour bypassed: the route resumes toward ``route[rejoin_route_index]``; the caller
    #: advances its target by this many (0: nothing bypassed, or already advanced).
    rejoin_route_index: int = 0

    @property
    def planned_path_ned(self) -> np.ndarray | None:
        """Sampled points of the active detour or braking path, (m, 3), for drawing."""
        if self.detour is not None:
            return self.detour.samples_ned
        return sample_path(self.hold_path) if self.hold_path is not None else None
