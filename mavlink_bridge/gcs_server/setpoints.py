"""Offboard setpoints (SPEC §3 API link, PX4 OFFBOARD): SET_POSITION_TARGET_LOCAL_NED / _GLOBAL_INT decoded.

Position setpoints (MAVSDK ``Offboard.set_position_ned`` and ``set_position_global``): the three position
bits of ``type_mask`` are clear; velocity, acceleration and thrust fields are then ignored. Frames:
LOCAL_NED for the local message; for the global one GLOBAL(_INT) = AMSL altitude,
GLOBAL_RELATIVE_ALT(_INT) and GLOBAL_TERRAIN_ALT(_INT) = above home.

Velocity setpoints (``set_velocity_ned``, ``set_velocity_body``): the local message with the position
bits set and the three velocity bits clear, in LOCAL_NED or a body frame (BODY_NED, BODY_OFFSET_NED,
BODY_FRD: forward, right, down about the heading). Acceleration and thrust fields are ignored.

Yaw is used unless YAW_IGNORE is set; a velocity setpoint without yaw uses the yaw rate unless
YAW_RATE_IGNORE is set. A setpoint of another kind (acceleration-only, thrust, a velocity in the
global message), in an unsupported frame or not finite is dropped and counted (MAVLink has no
acknowledgement for setpoints).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from pymavlink.dialects.v20 import common as mavlink2

from mavlink_bridge.contract.vehicle_api import (
    AltitudeFrame,
    GlobalPositionTarget,
    LocalPositionTarget,
    PositionTarget,
    VelocityFrame,
    VelocityTarget,
)

#: POSITION_TARGET_TYPEMASK bits.
_IGNORE_POSITION = 0x7
_IGNORE_VELOCITY = 0x38
_IGNORE_YAW = 0x400
_IGNORE_YAW_RATE = 0x800
_LOCAL_NED = mavlink2.MAV_FRAME_LOCAL_NED
_BODY_FRAMES = frozenset({mavlink2.MAV_FRAME_BODY_NED, mavlink2.MAV_FRAME_BODY_OFFSET_NED, mavlink2.MAV_FRAME_BODY_FRD})
_AMSL_FRAMES = frozenset({mavlink2.MAV_FRAME_GLOBAL, mavlink2.MAV_FRAME_GLOBAL_INT})
_ABOVE_HOME_FRAMES = frozenset(
    {
        mavlink2.MAV_FRAME_GLOBAL_RELATIVE_ALT,
        mavlink2.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT,
        mavlink2.MAV_FRAME_GLOBAL_TERRAIN_ALT,
        mavlink2.MAV_FRAME_GLOBAL_TERRAIN_ALT_INT,
    }
)


@dataclass(slots=True)
class SetpointStats:
    """Setpoints received, used by the vehicle, and dropped (unsupported or refused)."""

    received: int = 0
    used: int = 0
    dropped: int = 0


def setpoint_from_msg(msg: mavlink2.MAVLink_message) -> PositionTarget | VelocityTarget | None:
    """The setpoint a SET_POSITION_TARGET_* message carries, or None when it has none we support."""
    mask = int(msg.type_mask)
    yaw = math.nan if mask & _IGNORE_YAW else float(msg.yaw)  # NaN: not given (PX4 reads it so too)
    if math.isinf(yaw):
        return None
    frame = int(msg.coordinate_frame)
    if mask & _IGNORE_POSITION:
        return _velocity_target(msg, mask, frame, yaw)
    if msg.get_type() == "SET_POSITION_TARGET_LOCAL_NED":
        if frame != _LOCAL_NED:
            return None
        pos = (float(msg.x), float(msg.y), float(msg.z))
        if not all(math.isfinite(v) for v in pos):
            return None
        return LocalPositionTarget(pos, yaw)
    if frame in _AMSL_FRAMES:
        alt_frame = AltitudeFrame.AMSL
    elif frame in _ABOVE_HOME_FRAMES:
        alt_frame = AltitudeFrame.ABOVE_HOME
    else:
        return None
    lat, lon, alt = msg.lat_int / 1e7, msg.lon_int / 1e7, float(msg.alt)
    if not (-90.0 <= lat <= 90.0 and -180.0 <= lon <= 180.0 and math.isfinite(alt)):
        return None
    return GlobalPositionTarget(lat, lon, alt, alt_frame, yaw)


def _velocity_target(msg: mavlink2.MAVLink_message, mask: int, frame: int, yaw: float) -> VelocityTarget | None:
    """A velocity-only local setpoint; None for anything else (acceleration-only, global, other frames)."""
    if (mask & _IGNORE_POSITION) != _IGNORE_POSITION or mask & _IGNORE_VELOCITY:
        return None  # part of a position, or not all of a velocity
    if msg.get_type() != "SET_POSITION_TARGET_LOCAL_NED":
        return None
    if frame == _LOCAL_NED:
        vel_frame = VelocityFrame.LOCAL_NED
    elif frame in _BODY_FRAMES:
        vel_frame = VelocityFrame.BODY
    else:
        return None
    vel = (float(msg.vx), float(msg.vy), float(msg.vz))
    yaw_rate = math.nan if mask & _IGNORE_YAW_RATE or not math.isnan(yaw) else float(msg.yaw_rate)
    if not all(math.isfinite(v) for v in vel) or math.isinf(yaw_rate):
        return None
    return VelocityTarget(vel, vel_frame, yaw, yaw_rate)


class SetpointProtocol:
    """Hands decoded setpoints to ``vehicle.set_position_target`` / ``vehicle.set_velocity_target``."""

    HANDLED = frozenset({"SET_POSITION_TARGET_LOCAL_NED", "SET_POSITION_TARGET_GLOBAL_INT"})

    def __init__(self, vehicle: object) -> None:
        self._vehicle = vehicle
        self.stats = SetpointStats()

    def handle(self, msg: mavlink2.MAVLink_message) -> None:
        self.stats.received += 1
        target = setpoint_from_msg(msg)
        vehicle = self._vehicle
        if target is None:
            used = False
        elif isinstance(target, VelocityTarget):
            used = vehicle.set_velocity_target(target)  # type: ignore[attr-defined]
        else:
            used = vehicle.set_position_target(target)  # type: ignore[attr-defined]
        if used:
            self.stats.used += 1
        else:
            self.stats.dropped += 1
