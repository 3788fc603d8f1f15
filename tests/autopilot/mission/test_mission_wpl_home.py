"""MAVProxy's ``wp load`` sends QGC WPL line 0 (home, frame GLOBAL, AMSL) as item 0: accepted, never flown to."""

from __future__ import annotations

from test_mission_executor import PointVehicle

from autopilot.mission.executor import MissionExecutor
from autopilot.mission.plan import is_wpl_home_line
from autopilot.mission.validation import validate_mission
from mavlink_bridge.contract.frames import GeoPoint, LocalNedFrame
from mavlink_bridge.contract.mav_enums import MavCmd, MavFrame
from mavlink_bridge.contract.vehicle_api import MissionItem, MissionResult

HOME = GeoPoint(30.2635, 120.1233, 12.0)


def _home_line(seq: int = 0) -> MissionItem:
    return MissionItem(seq, MavCmd.NAV_WAYPOINT, MavFrame.GLOBAL, 0, 0, 0, 0, HOME.lat_deg, HOME.lon_deg, 12.0)


def _mission() -> list[MissionItem]:
    far = LocalNedFrame(HOME).geodetic_from_ned(30.0, 0.0, 0.0)
    return [
        _home_line(),
        MissionItem(1, MavCmd.NAV_TAKEOFF, MavFrame.GLOBAL_RELATIVE_ALT, z_alt_m=10.0),
        MissionItem(2, MavCmd.NAV_WAYPOINT, MavFrame.GLOBAL_RELATIVE_ALT, x_lat_deg=far.lat_deg,
                    y_lon_deg=far.lon_deg, z_alt_m=10.0),
        MissionItem(3, MavCmd.NAV_LAND, MavFrame.GLOBAL_RELATIVE_ALT, x_lat_deg=far.lat_deg,
                    y_lon_deg=far.lon_deg),
    ]  # fmt: skip


def test_home_line_is_recognised_only_as_item_zero_on_the_ground() -> None:
    assert is_wpl_home_line(0, _home_line(), HOME)
    assert not is_wpl_home_line(1, _home_line(1), HOME)
    high = MissionItem(0, MavCmd.NAV_WAYPOINT, MavFrame.GLOBAL, z_alt_m=30.0)
    assert not is_wpl_home_line(0, high, HOME)
    relative = MissionItem(0, MavCmd.NAV_WAYPOINT, MavFrame.GLOBAL_RELATIVE_ALT, z_alt_m=0.0)
    assert not is_wpl_home_line(0, relative, HOME)


def test_validation_accepts_the_home_line_but_not_a_ground_waypoint_later() -> None:
    assert validate_mission(_mission(), HOME)[0] == MissionResult.ACCEPTED
    later = [*_mission()[1:3], _home_line(2)]
    later = [MissionItem(i, it.command, it.frame, *(0.0,) * 4, it.x_lat_deg, it.y_lon_deg, it.z_alt_m)
             for i, it in enumerate(later)]  # fmt: skip
    result, reason = validate_mission(later, HOME)
    assert result == MissionResult.INVALID_PARAM7 and "item 2" in reason


def test_executor_completes_the_home_line_at_once_and_flies_the_rest() -> None:
    ex = MissionExecutor(HOME)
    ex.set_mission(_mission())
    vehicle = PointVehicle()
    ex.start(vehicle.t_us)
    out = ex.step(vehicle.sample())
    assert 0 in out.reached
    assert out.target is not None and out.target.seq == 1  # takeoff next: home was never a target
    vehicle.fly(ex, 120.0)
    assert [seq for seq, _ in vehicle.reached] == [1, 2, 3]  # 0 was reached in the first step above
