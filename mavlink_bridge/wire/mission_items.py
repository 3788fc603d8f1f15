"""MissionItem <-> MISSION_ITEM_INT / MISSION_ITEM conversions (both ends of the mission protocol).

MISSION_ITEM_INT carries x/y as int32: degrees·1e7 in global frames, metres·1e4 in local
frames and the raw value otherwise (MAV_FRAME_MISSION: x/y are params 5/6). The legacy
float MISSION_ITEM (MAVProxy) carries x/y as plain floats.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
from pymavlink.dialects.v20 import common as mavlink2

from mavlink_bridge.contract.vehicle_api import MissionItem, MissionType

#: MAV_FRAME_GLOBAL, _RELATIVE_ALT, _INT, _RELATIVE_ALT_INT, _TERRAIN_ALT, _TERRAIN_ALT_INT.
GLOBAL_FRAMES = frozenset({0, 3, 5, 6, 10, 11})
#: MAV_FRAME_LOCAL_NED, LOCAL_OFFSET_NED, BODY_NED, BODY_OFFSET_NED, LOCAL_ENU, LOCAL_FRD, LOCAL_FLU.
LOCAL_FRAMES = frozenset({1, 4, 7, 8, 9, 20, 21})
_INT32_MIN, _INT32_MAX = -(2**31), 2**31 - 1


class MissionItemEncodeError(ValueError):
    """An item's x/y cannot be carried by MISSION_ITEM_INT (non-finite or beyond int32)."""


def _xy_scale(frame: int) -> float:
    if frame in GLOBAL_FRAMES:
        return 1e7
    if frame in LOCAL_FRAMES:
        return 1e4
    return 1.0


def xy_to_int(value: float, frame: int, what: str = "x") -> int:
    """Scale a coordinate to its int32 wire value for ``frame``; MissionItemEncodeError if impossible."""
    if not math.isfinite(value):
        raise MissionItemEncodeError(f"{what} = {value!r} is not a finite number")
    scaled = round(value * _xy_scale(frame))
    if not _INT32_MIN <= scaled <= _INT32_MAX:
        raise MissionItemEncodeError(f"{what} = {value!r} does not fit MISSION_ITEM_INT in frame {frame}")
    return int(scaled)


def xy_from_int(value: int, frame: int) -> float:
    """The coordinate (degrees, metres or raw) carried by an int32 wire value in ``frame``."""
    return value / _xy_scale(frame)


def as_on_the_wire(item: MissionItem) -> MissionItem:
    """``item`` as an autopilot receives it in MISSION_ITEM_INT: x/y as int32 at the frame's scale, params and z as
    float32 (what an in-process flight hands over instead of an upload)."""
    frame = item.frame
    f32 = np.float32
    return replace(
        item,
        param1=float(f32(item.param1)),
        param2=float(f32(item.param2)),
        param3=float(f32(item.param3)),
        param4=float(f32(item.param4)),
        x_lat_deg=xy_from_int(xy_to_int(item.x_lat_deg, frame), frame),
        y_lon_deg=xy_from_int(xy_to_int(item.y_lon_deg, frame), frame),
        z_alt_m=float(f32(item.z_alt_m)),
    )


def _mission_type(raw: int) -> MissionType:
    try:
        return MissionType(raw)
    except ValueError:
        return MissionType.ALL  # never a valid item type: callers refuse it


def item_from_msg(msg: mavlink2.MAVLink_message) -> MissionItem:
    """A MissionItem from MISSION_ITEM_INT or MISSION_ITEM."""
    if msg.get_type() == "MISSION_ITEM_INT":
        x, y = xy_from_int(msg.x, msg.frame), xy_from_int(msg.y, msg.frame)
    else:
        x, y = float(msg.x), float(msg.y)
    return MissionItem(
        seq=int(msg.seq),
        command=int(msg.command),
        frame=int(msg.frame),
        param1=float(msg.param1),
        param2=float(msg.param2),
        param3=float(msg.param3),
        param4=float(msg.param4),
        x_lat_deg=x,
        y_lon_deg=y,
        z_alt_m=float(msg.z),
        autocontinue=bool(msg.autocontinue),
        mission_type=_mission_type(int(getattr(msg, "mission_type", 0))),
    )


def send_item(
    mav: mavlink2.MAVLink,
    item: MissionItem,
    *,
    seq: int,
    target_system: int,
    target_component: int,
    use_int: bool = True,
    current: bool = False,
) -> None:
    """Send ``item`` as sequence number ``seq`` (MISSION_ITEM_INT, or the float MISSION_ITEM if not ``use_int``)."""
    common = (
        target_system,
        target_component,
        seq,
        item.frame,
        item.command,
        1 if current else 0,
        1 if item.autocontinue else 0,
        item.param1,
        item.param2,
        item.param3,
        item.param4,
    )
    if use_int:
        x = xy_to_int(item.x_lat_deg, item.frame, "x/lat")
        y = xy_to_int(item.y_lon_deg, item.frame, "y/lon")
        mav.mission_item_int_send(*common, x, y, item.z_alt_m, int(item.mission_type))
    else:
        mav.mission_item_send(*common, item.x_lat_deg, item.y_lon_deg, item.z_alt_m, int(item.mission_type))
