"""The item-to-target translation: what the setpoint generator flies in each phase of an active item."""

from __future__ import annotations

from enum import IntEnum

from autopilot.mission.executor_types import NavKind, NavTarget
from mavlink_bridge.contract.frames import Vec3
from mavlink_bridge.contract.mav_enums import MavCmd
from mavlink_bridge.contract.vehicle_api import MissionItem

_NAN = float("nan")


class ItemPhase(IntEnum):
    """Where the executor is within the current item."""

    START = 0
    CLIMB = 1
    APPROACH = 2
    HOLD = 3
    RETURN = 4
    DESCEND = 5


def phase_target(
    phase: ItemPhase,
    item: MissionItem,
    seq: int,
    goal_ned_m: Vec3,
    speed_m_s: float,
    accept_m: float,
    radius_m: float,
    next_pos_ned_m: Vec3 | None,
    landed: bool,
) -> NavTarget | None:
    """The target for item ``seq`` in ``phase`` (None at START); ``radius_m`` and ``next_pos_ned_m`` (the
    pass-through lookahead) apply while approaching a waypoint, ``accept_m`` otherwise."""
    cmd, yaw = item.command, item.param4
    if phase == ItemPhase.CLIMB:
        kind = NavKind.TAKEOFF if cmd == MavCmd.NAV_TAKEOFF else NavKind.RETURN
        return NavTarget(kind, seq, goal_ned_m, yaw if kind == NavKind.TAKEOFF else _NAN, speed_m_s, accept_m)
    if phase == ItemPhase.RETURN:
        return NavTarget(NavKind.RETURN, seq, goal_ned_m, _NAN, speed_m_s, accept_m)
    if phase == ItemPhase.DESCEND:
        land_yaw = yaw if cmd == MavCmd.NAV_LAND else _NAN
        return NavTarget(NavKind.LAND, seq, goal_ned_m, land_yaw, speed_m_s, accept_m)
    if phase == ItemPhase.APPROACH:
        nxt = next_pos_ned_m
        return NavTarget(NavKind.WAYPOINT, seq, goal_ned_m, yaw, speed_m_s, radius_m, nxt is not None, nxt)
    if phase == ItemPhase.HOLD:
        kind = NavKind.IDLE if landed else NavKind.LOITER
        return NavTarget(kind, seq, goal_ned_m, yaw if cmd != MavCmd.NAV_DELAY else _NAN, speed_m_s, accept_m)
    return None
