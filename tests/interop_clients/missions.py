"""The mission the interoperability tests fly with third-party clients (imports quadsitl: tests only)."""

from __future__ import annotations

import math

from mavlink_bridge.contract.frames import GeoPoint, LocalNedFrame
from mavlink_bridge.contract.mav_enums import GripperAction, MavCmd, MavFrame
from mavlink_bridge.contract.vehicle_api import MissionItem


def short_delivery(home: GeoPoint) -> list[MissionItem]:
    """Speed, take off, fly out, release the payload, hold 1 s, return to launch: ~40 s of sim time.

    Covers a DO item completing in the same step as a NAV item (2 -> 3 -> 4), which is where
    mission progress reporting is most easily out of order.
    """
    out = LocalNedFrame(home).geodetic_from_ned(25.0, 15.0, 0.0)
    nan = math.nan
    rel = MavFrame.GLOBAL_RELATIVE_ALT_INT
    return [
        MissionItem(0, MavCmd.DO_CHANGE_SPEED, MavFrame.MISSION, 1.0, 6.0, -1.0, 0.0),
        MissionItem(1, MavCmd.NAV_TAKEOFF, rel, 0.0, 0.0, 0.0, nan, 0.0, 0.0, 8.0),
        MissionItem(2, MavCmd.NAV_WAYPOINT, rel, 0.0, 1.0, 0.0, nan, out.lat_deg, out.lon_deg, 8.0),
        MissionItem(3, MavCmd.DO_GRIPPER, MavFrame.MISSION, 1.0, float(GripperAction.RELEASE)),
        MissionItem(4, MavCmd.NAV_LOITER_TIME, rel, 1.0, 0.0, 0.0, nan, out.lat_deg, out.lon_deg, 8.0),
        MissionItem(5, MavCmd.NAV_RETURN_TO_LAUNCH, MavFrame.MISSION),
    ]
