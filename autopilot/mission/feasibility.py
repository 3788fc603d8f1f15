"""Mission feasibility against the fence, the ceiling and the known world (SPEC §7-§8, issue 13).

PX4's mission feasibility checks are the anchor: once home is known every positional item is checked
against the geofence (inside an exclusion zone, outside the inclusion zones, beyond GF_MAX_HOR_DIST,
above the GF_MAX_VER_DIST ceiling) and a failing item is named with the reason. Unlike PX4, a *leg*
that crosses a zone is accepted: the route planner (:mod:`autopilot.planner.route_graph`) plans it
around, and only a mission with a leg that has no route at all is refused, with the reason.

Pure functions of the items, home, the local fence and the limits; positions about home (NED, m).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

from autopilot.flight_tasks.rtl import return_alt_m
from autopilot.geofence.fence import Geofence, zone_label
from autopilot.mission.plan import (
    DEFAULT_HOME_TOL,
    HomeTolerance,
    alt_rel_home_m,
    is_wpl_home_line,
    item_position_ned,
    uses_current_position,
)
from autopilot.mission.validation import MissionIssue
from autopilot.planner.route_graph import KnownWorld
from mavlink_bridge.contract.frames import GeoPoint, LocalNedFrame, Vec3
from mavlink_bridge.contract.mav_enums import POSITION_COMMANDS, MavCmd
from mavlink_bridge.contract.vehicle_api import MissionItem, MissionResult


@dataclass(frozen=True, slots=True)
class FeasibilityLimits:
    """What a mission must respect; ``inf`` switches a limit off (GF_* = 0)."""

    ceiling_m: float = math.inf  # GF_MAX_VER_DIST: highest altitude above home
    max_hor_dist_m: float = math.inf  # GF_MAX_HOR_DIST: furthest horizontal distance from home
    margin_m: float = 3.0  # CA_FENCE_MARG_M: the route keeps this far from fence boundaries
    rtl_alt_m: float = 30.0  # MIS_RTL_ALT (below GF_MAX_VER_DIST): a return climbs to this altitude (at least)
    takeoff_alt_m: float = 10.0  # MIS_TAKEOFF_ALT: where the first leg starts when the mission has no takeoff

    @classmethod
    def from_params(cls, get: Callable[[str], float]) -> FeasibilityLimits:
        """From a parameter getter (``ParamStore.get``): GF_MAX_VER_DIST, GF_MAX_HOR_DIST (0 = off),
        CA_FENCE_MARG_M, MIS_RTL_ALT, MIS_TAKEOFF_ALT."""
        ver, hor = get("GF_MAX_VER_DIST"), get("GF_MAX_HOR_DIST")
        return cls(
            ceiling_m=ver if ver > 0.0 else math.inf,
            max_hor_dist_m=hor if hor > 0.0 else math.inf,
            margin_m=get("CA_FENCE_MARG_M"),
            rtl_alt_m=return_alt_m(get),
            takeoff_alt_m=get("MIS_TAKEOFF_ALT"),
        )


def _refuse(result: MissionResult, index: int, field: str, message: str) -> MissionIssue:
    return MissionIssue(result, index, field, f"item {index}: {message}" if index >= 0 else message)


def position_issue(
    index: int, pos_ned_m: Vec3, fence: Geofence, limits: FeasibilityLimits, what: str = ""
) -> MissionIssue | None:
    """Why a point (about home) may not be flown to: inside an exclusion zone, outside the inclusion zones,
    beyond GF_MAX_HOR_DIST or above the ceiling; None when it may."""
    what = what or f"item {index}"
    for k, zone in enumerate(fence.zones, start=1):
        if not zone.inclusion and zone.contains(pos_ned_m):
            return MissionIssue(
                MissionResult.INVALID_PARAM5_X, index, "x_lat_deg", f"{what}: inside {zone_label(zone, k)}"
            )
    dist = math.hypot(pos_ned_m[0], pos_ned_m[1])
    if any(z.inclusion for z in fence.zones) and fence.violates((pos_ned_m[0], pos_ned_m[1], 0.0)):
        inclusions = [zone_label(z, k) for k, z in enumerate(fence.zones, start=1) if z.inclusion]
        return MissionIssue(
            MissionResult.INVALID_PARAM5_X,
            index,
            "x_lat_deg",
            f"{what}: {dist:.0f} m from home, outside the inclusion fence ({', '.join(inclusions)})",
        )
    if dist > limits.max_hor_dist_m:
        return MissionIssue(
            MissionResult.INVALID_PARAM5_X,
            index,
            "x_lat_deg",
            f"{what}: {dist:.0f} m from home, beyond the {limits.max_hor_dist_m:g} m limit (GF_MAX_HOR_DIST)",
        )
    alt = -pos_ned_m[2]
    if alt > limits.ceiling_m:
        return MissionIssue(
            MissionResult.INVALID_PARAM7,
            index,
            "z_alt_m",
            f"{what}: altitude {alt:g} m above home, over the {limits.ceiling_m:g} m ceiling (GF_MAX_VER_DIST)",
        )
    return None


@dataclass(frozen=True, slots=True)
class MissionLeg:
    """One straight leg the mission asks for, between two positions about home (``from_seq`` -1 = home)."""

    from_seq: int
    to_seq: int
    start_ned_m: Vec3
    goal_ned_m: Vec3


def mission_legs(
    items: Sequence[MissionItem],
    home: GeoPoint,
    limits: FeasibilityLimits,
    home_tol: HomeTolerance = DEFAULT_HOME_TOL,
) -> list[MissionLeg]:
    """The legs of a mission in list order (takeoff climbs where it is; a DO_JUMP adds the leg back to its
    target; RTL climbs to MIS_RTL_ALT and flies home; LAND descends where it is or at its position)."""
    frame = LocalNedFrame(home)
    legs: list[MissionLeg] = []
    prev_seq = -1
    prev: Vec3 = (0.0, 0.0, -limits.takeoff_alt_m)
    pos_of: dict[int, Vec3] = {}
    for i, item in enumerate(items):
        cmd = item.command
        if cmd == MavCmd.DO_JUMP:
            target = int(item.param1)
            nxt = next((k for k in range(target, len(items)) if k in pos_of), None)
            if nxt is not None and nxt != prev_seq:
                legs.append(MissionLeg(prev_seq, nxt, prev, pos_of[nxt]))
            continue
        if cmd == MavCmd.NAV_RETURN_TO_LAUNCH:
            alt = max(-prev[2], limits.rtl_alt_m)
            legs.append(MissionLeg(prev_seq, i, (prev[0], prev[1], -alt), (0.0, 0.0, -alt)))
            prev_seq, prev = i, (0.0, 0.0, -alt)
            continue
        if cmd not in POSITION_COMMANDS or is_wpl_home_line(i, item, home, home_tol):
            continue
        if cmd == MavCmd.NAV_TAKEOFF:
            prev = (prev[0], prev[1], -alt_rel_home_m(item, home))
            prev_seq = i
            pos_of[i] = prev
            continue
        if uses_current_position(item):
            pos = (prev[0], prev[1], prev[2] if cmd != MavCmd.NAV_LAND else 0.0)
        else:
            n, e, d = item_position_ned(item, frame)
            pos = (n, e, prev[2] if cmd == MavCmd.NAV_LAND else d)
        legs.append(MissionLeg(prev_seq, i, prev, pos))
        pos_of[i] = pos
        prev_seq, prev = i, pos
    return legs


def check_feasibility(
    items: Sequence[MissionItem],
    home: GeoPoint,
    fence: Geofence,
    limits: FeasibilityLimits | None = None,
    world: KnownWorld | None = None,
    home_tol: HomeTolerance = DEFAULT_HOME_TOL,
) -> MissionIssue | None:
    """The first reason the mission cannot be flown with this fence from this home, or None.

    Checks home, then every positional item (:func:`position_issue`), then that every leg has a route
    around the fence inflated by ``limits.margin_m`` (``world``: a prebuilt :class:`KnownWorld` of the
    same fence and margin, built here when None; ``home_tol``: how far a WPL home line may lie from ``home``)."""
    limits = limits or FeasibilityLimits()
    if fence.violates((0.0, 0.0, 0.0)):
        return _refuse(MissionResult.INVALID, -1, "home", "home lies outside the geofence: no mission can be flown")
    frame = LocalNedFrame(home)
    for i, item in enumerate(items):
        if item.command not in POSITION_COMMANDS or is_wpl_home_line(i, item, home, home_tol):
            continue
        if uses_current_position(item):  # only a takeoff's altitude is known here
            if item.command != MavCmd.NAV_TAKEOFF:
                continue
            n, e, d = 0.0, 0.0, -alt_rel_home_m(item, home)
        else:
            n, e, d = item_position_ned(item, frame)
        issue = position_issue(i, (n, e, d), fence, limits)
        if issue is not None:
            return MissionIssue(issue.result, i, issue.field, issue.reason)
    if not fence.zones:
        return None
    world = world or KnownWorld(fence, limits.margin_m)
    for leg in mission_legs(items, home, limits, home_tol):
        result = world.route(leg.start_ned_m, leg.goal_ned_m)
        if not result.ok:
            origin = "home" if leg.from_seq < 0 else f"item {leg.from_seq}"
            return _refuse(
                MissionResult.INVALID, leg.to_seq, "route", f"no route from {origin} around the fence ({result.reason})"
            )
    return None
