"""Offboard setpoints (SPEC §3 API link, PX4 OFFBOARD): SET_POSITION_TARGET_LOCAL_NED / _GLOBAL_INT decoded.

Position setpoints only (what PX4 calls a position setpoint; MAVSDK ``Offboard.set_position_ned`` and
``set_position_global``): the three position bits of ``type_mask`` must be clear; velocity,
acceleration and thrust fields are ignored; yaw is used unless YAW_IGNORE is set. A setpoint
that is velocity-only, in an unsupported frame or not finite is dropped and counted (MAVLink has
no acknowledgement for setpoints). Frames: LOCAL_NED for the local message; for the global one
GLOBAL(_INT) = AMSL altitude, GLOBAL_RELATIVE_ALT(_INT) and GLOBAL_TERRAIN_ALT(_INT) = above home.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from pymavlink.dialects.v20 import common as mavlink2

from mavlink_bridge.gcs_types import AltitudeFrame, GlobalPositionTarget, LocalPositionTarget, PositionTarget

#: POSITION_TARGET_TYPEMASK bits.
_IGNORE_POSITION = 0x7
_IGNORE_YAW = 0x400
_LOCAL_NED = mavlink2.MAV_FRAME_LOCAL_NED
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


def position_target_from_msg(msg: mavlink2.MAVLink_message) -> PositionTarget | None:
    """The position setpoint a SET_POSITION_TARGET_* message carries, or None when it has none we support."""
    mask = int(msg.type_mask)
    if mask & _IGNORE_POSITION:
        return None
    yaw = math.nan if mask & _IGNORE_YAW else float(msg.yaw)
    frame = int(msg.coordinate_frame)
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


class SetpointProtocol:
    """Hands decoded position setpoints to ``vehicle.set_position_target``."""

    HANDLED = frozenset({"SET_POSITION_TARGET_LOCAL_NED", "SET_POSITION_TARGET_GLOBAL_INT"})

    def __init__(self, vehicle: object) -> None:
        self._vehicle = vehicle
        self.stats = SetpointStats()

    def handle(self, msg: mavlink2.MAVLink_message) -> None:
        self.stats.received += 1
        target = position_target_from_msg(msg)
        if target is not None and self._vehicle.set_position_target(target):  # type: ignore[attr-defined]
            self.stats.used += 1
        else:
            self.stats.dropped += 1
