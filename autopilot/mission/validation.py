"""Validation of uploaded MISSION and FENCE item lists (SPEC §8, §10).

``validate_mission`` is what the autopilot calls before installing an upload: a refusal
comes with the MAVLink result code and a sentence a user can act on, e.g.
``"item 3: latitude 123.4 outside [-90, 90]"``; the previous mission is then kept.
``check_mission`` returns the same finding with the item index and field as data.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

from autopilot.geofence.fence import FenceError, geo_fence_from_items
from autopilot.mission.param_decls import MISSION_PARAM_DEFAULTS
from autopilot.mission.plan import (
    DEFAULT_HOME_TOL,
    HomeTolerance,
    alt_rel_home_m,
    is_wpl_home_line,
    uses_current_position,
)
from autopilot.parameters.store import ParamStore
from mavlink_bridge.contract.frames import GeoPoint, LocalNedFrame
from mavlink_bridge.contract.mav_enums import (
    AMSL_FRAMES,
    GLOBAL_FRAMES,
    MISSION_COMMANDS,
    NAV_COMMANDS,
    POSITION_COMMANDS,
    GripperAction,
    MavCmd,
    MavFrame,
    command_name,
    frame_name,
)
from mavlink_bridge.contract.vehicle_api import MissionItem, MissionResult, MissionType

#: Mission commands whose param4 is a yaw angle where NaN means "vehicle's choice" (MAVLink convention).
_NAN_YAW_OK = frozenset({MavCmd.NAV_WAYPOINT, MavCmd.NAV_LOITER_TIME, MavCmd.NAV_LAND, MavCmd.NAV_TAKEOFF})
#: Commands whose altitude must lie in [alt_min_m, alt_max_m].
_ALT_CHECKED = frozenset({MavCmd.NAV_WAYPOINT, MavCmd.NAV_LOITER_TIME, MavCmd.NAV_TAKEOFF})
_PARAM_RESULTS = (
    MissionResult.INVALID_PARAM1,
    MissionResult.INVALID_PARAM2,
    MissionResult.INVALID_PARAM3,
    MissionResult.INVALID_PARAM4,
)


@dataclass(frozen=True, slots=True)
class MissionLimits:
    """Upload limits; defaults are the MIS_* parameter defaults."""

    max_items: int = int(MISSION_PARAM_DEFAULTS["MIS_MAX_ITEMS"])
    alt_min_m: float = MISSION_PARAM_DEFAULTS["MIS_ALT_MIN"]
    alt_max_m: float = MISSION_PARAM_DEFAULTS["MIS_ALT_MAX"]
    max_dist_m: float = MISSION_PARAM_DEFAULTS["MIS_DIST_MAX"]
    max_speed_m_s: float = MISSION_PARAM_DEFAULTS["MIS_SPEED_MAX"]

    @classmethod
    def from_params(cls, params: ParamStore) -> MissionLimits:
        """Limits in force from MIS_MAX_ITEMS, MIS_ALT_MIN, MIS_ALT_MAX, MIS_DIST_MAX, MIS_SPEED_MAX."""
        return cls(
            max_items=int(params.get("MIS_MAX_ITEMS")),
            alt_min_m=params.get("MIS_ALT_MIN"),
            alt_max_m=params.get("MIS_ALT_MAX"),
            max_dist_m=params.get("MIS_DIST_MAX"),
            max_speed_m_s=params.get("MIS_SPEED_MAX"),
        )


@dataclass(frozen=True, slots=True)
class MissionIssue:
    """Why an upload is refused: MAVLink result, offending item index (-1: the whole list), field name, reason."""

    result: MissionResult
    item_index: int
    field: str
    reason: str


class _RefusedError(Exception):
    def __init__(self, result: MissionResult, index: int, field: str, message: str) -> None:
        reason = f"item {index}: {message}" if index >= 0 else message
        super().__init__(reason)
        self.issue = MissionIssue(result, index, field, reason)


def _check_finite(i: int, item: MissionItem) -> None:
    for k, value in enumerate((item.param1, item.param2, item.param3, item.param4)):
        if math.isfinite(value) or (k == 3 and math.isnan(value) and item.command in _NAN_YAW_OK):
            continue
        raise _RefusedError(_PARAM_RESULTS[k], i, f"param{k + 1}", f"param{k + 1} is {value} (must be finite)")
    for name, value, result, label in (
        ("x_lat_deg", item.x_lat_deg, MissionResult.INVALID_PARAM5_X, "latitude (x)"),
        ("y_lon_deg", item.y_lon_deg, MissionResult.INVALID_PARAM6_Y, "longitude (y)"),
        ("z_alt_m", item.z_alt_m, MissionResult.INVALID_PARAM7, "altitude (z)"),
    ):
        if not math.isfinite(value):
            raise _RefusedError(result, i, name, f"{label} is {value} (must be finite)")


def _check_position(
    i: int,
    item: MissionItem,
    home: GeoPoint | None,
    frame: LocalNedFrame | None,
    limits: MissionLimits,
    home_tol: HomeTolerance,
) -> None:
    if item.frame not in GLOBAL_FRAMES:
        raise _RefusedError(
            MissionResult.UNSUPPORTED_FRAME,
            i,
            "frame",
            f"frame {frame_name(item.frame)} unsupported for {command_name(item.command)} "
            "(use GLOBAL_RELATIVE_ALT(_INT) or GLOBAL(_INT))",
        )
    here = uses_current_position(item)
    if not here:
        if not -90.0 <= item.x_lat_deg <= 90.0:
            raise _RefusedError(
                MissionResult.INVALID_PARAM5_X, i, "x_lat_deg", f"latitude {item.x_lat_deg:g} outside [-90, 90]"
            )
        if not -180.0 <= item.y_lon_deg <= 180.0:
            raise _RefusedError(
                MissionResult.INVALID_PARAM6_Y, i, "y_lon_deg", f"longitude {item.y_lon_deg:g} outside [-180, 180]"
            )
        dist = 0.0
        if frame is not None and home is not None:  # without home: checked again once it is known
            n, e, _ = frame.ned_from_geodetic(item.x_lat_deg, item.y_lon_deg, home.alt_amsl_m)
            dist = math.hypot(n, e)
        if dist > limits.max_dist_m:
            raise _RefusedError(
                MissionResult.INVALID_PARAM5_X,
                i,
                "x_lat_deg",
                f"{dist:.0f} m from home, more than the {limits.max_dist_m:g} m allowed (MIS_DIST_MAX)",
            )
    if home is None and item.frame in AMSL_FRAMES:
        return  # an AMSL altitude is checked once home is known
    on_ground_ok = (here and item.command == MavCmd.NAV_LOITER_TIME) or (
        home is not None and is_wpl_home_line(i, item, home, home_tol)
    )
    if item.command in _ALT_CHECKED and not on_ground_ok:
        alt = alt_rel_home_m(item, home) if home is not None else item.z_alt_m
        if not limits.alt_min_m <= alt <= limits.alt_max_m:
            raise _RefusedError(
                MissionResult.INVALID_PARAM7,
                i,
                "z_alt_m",
                f"altitude {alt:g} m above home outside [{limits.alt_min_m:g}, {limits.alt_max_m:g}]",
            )


def _check_params(i: int, item: MissionItem, items: Sequence[MissionItem], limits: MissionLimits) -> None:
    cmd = item.command
    p1, p2 = MissionResult.INVALID_PARAM1, MissionResult.INVALID_PARAM2
    if cmd == MavCmd.NAV_WAYPOINT:
        if item.param1 < 0.0:
            raise _RefusedError(p1, i, "param1", f"hold time {item.param1:g} s must be >= 0")
        if item.param2 < 0.0:
            raise _RefusedError(p2, i, "param2", f"acceptance radius {item.param2:g} m must be >= 0")
    elif cmd in (MavCmd.NAV_LOITER_TIME, MavCmd.NAV_DELAY):
        if item.param1 < 0.0:
            raise _RefusedError(
                p1, i, "param1", f"{command_name(cmd)} time {item.param1:g} s must be >= 0 (time of day unsupported)"
            )
    elif cmd == MavCmd.DO_CHANGE_SPEED:
        speed = item.param2
        if speed not in (-1.0, -2.0) and not 0.0 < speed <= limits.max_speed_m_s:
            raise _RefusedError(
                p2,
                i,
                "param2",
                f"speed {speed:g} m/s outside (0, {limits.max_speed_m_s:g}] (or -1 no change, -2 default)",
            )
    elif cmd == MavCmd.DO_GRIPPER:
        if item.param2 not in (float(GripperAction.RELEASE), float(GripperAction.GRAB)):
            raise _RefusedError(p2, i, "param2", f"gripper action {item.param2:g} must be 0 (release) or 1 (grab)")
    elif cmd == MavCmd.DO_JUMP:
        target, repeat = item.param1, item.param2
        if target != int(target) or not 0 <= target < len(items) or int(target) == i:
            raise _RefusedError(
                p1, i, "param1", f"DO_JUMP target {target:g} outside [0, {len(items) - 1}] or the jump itself"
            )
        if repeat != int(repeat) or repeat < -1:
            raise _RefusedError(p2, i, "param2", f"DO_JUMP repeat {repeat:g} must be an integer >= -1")
        if int(target) < i and not any(items[k].command in NAV_COMMANDS for k in range(int(target), i)):
            raise _RefusedError(p1, i, "param1", f"DO_JUMP loop {int(target)}..{i} contains no navigation item")


def _check_mission_items(
    items: Sequence[MissionItem], home: GeoPoint | None, limits: MissionLimits, home_tol: HomeTolerance
) -> None:
    frame = LocalNedFrame(home) if home is not None else None
    for i, item in enumerate(items):
        if item.seq != i:
            raise _RefusedError(MissionResult.INVALID_SEQUENCE, i, "seq", f"sequence number {item.seq}, expected {i}")
        if item.mission_type != MissionType.MISSION:
            raise _RefusedError(
                MissionResult.INVALID, i, "mission_type", f"mission_type {item.mission_type!r} in a MISSION list"
            )
        if item.command not in MISSION_COMMANDS:
            supported = ", ".join(sorted(command_name(c) for c in MISSION_COMMANDS))
            raise _RefusedError(
                MissionResult.UNSUPPORTED,
                i,
                "command",
                f"command {command_name(item.command)} is not supported (supported: {supported})",
            )
        _check_finite(i, item)
        if item.command in POSITION_COMMANDS:
            _check_position(i, item, home, frame, limits, home_tol)
        elif item.frame not in GLOBAL_FRAMES | {MavFrame.MISSION}:
            raise _RefusedError(
                MissionResult.UNSUPPORTED_FRAME,
                i,
                "frame",
                f"frame {frame_name(item.frame)} unsupported for {command_name(item.command)}",
            )
        _check_params(i, item, items, limits)


def _check_fence_items(items: Sequence[MissionItem]) -> None:
    for i, item in enumerate(items):
        if item.seq != i:
            raise _RefusedError(MissionResult.INVALID_SEQUENCE, i, "seq", f"sequence number {item.seq}, expected {i}")
        if item.mission_type != MissionType.FENCE:
            raise _RefusedError(
                MissionResult.INVALID, i, "mission_type", f"mission_type {item.mission_type!r} in a FENCE list"
            )
    try:
        geo_fence_from_items(items)
    except FenceError as exc:
        raise _RefusedError(MissionResult.INVALID, exc.item_index, exc.field, exc.message) from None


def check_mission(
    items: Sequence[MissionItem],
    home: GeoPoint | None,
    limits: MissionLimits | None = None,
    home_tol: HomeTolerance = DEFAULT_HOME_TOL,
) -> MissionIssue | None:
    """The first problem of a complete upload, or None when it can be installed.

    With ``home`` None (no position fix yet) what needs home (MIS_DIST_MAX, AMSL altitudes) is left for the
    check once home is known (:mod:`autopilot.mission.uploads`). ``home_tol``: how far a WPL home line may lie
    from ``home`` (:func:`autopilot.mission.plan.is_wpl_home_line`).

    The list's mission type is taken from its first item (an empty list is a valid "clear").
    FENCE lists are checked by parsing them into zones (:func:`geofence_from_items`).
    """
    limits = limits or MissionLimits()
    try:
        if len(items) > limits.max_items:
            raise _RefusedError(
                MissionResult.NO_SPACE,
                -1,
                "count",
                f"mission has {len(items)} items, at most {limits.max_items} allowed",
            )
        if not items:
            return None
        if items[0].mission_type == MissionType.FENCE:
            _check_fence_items(items)
        elif items[0].mission_type == MissionType.MISSION:
            _check_mission_items(items, home, limits, home_tol)
        else:
            raise _RefusedError(
                MissionResult.UNSUPPORTED, 0, "mission_type", f"mission_type {items[0].mission_type!r} unsupported"
            )
    except _RefusedError as refused:
        return refused.issue
    return None


def validate_mission(
    items: Sequence[MissionItem], home: GeoPoint | None, limits: MissionLimits | None = None
) -> tuple[MissionResult, str]:
    """``(ACCEPTED, "")`` or the MAVLink result and a user-readable reason naming the item."""
    issue = check_mission(items, home, limits)
    return (MissionResult.ACCEPTED, "") if issue is None else (issue.result, issue.reason)
