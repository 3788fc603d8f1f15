"""MAVProxy's ``wp load`` sends QGC WPL line 0 (home, frame GLOBAL, AMSL) as item 0: accepted, never flown to.

It is recognised at the estimated home within three times the GPS accuracy the estimator reports (issue 22): the
first fix misses the file's home by the GPS error, more than the 1 m that used to be allowed."""

from __future__ import annotations

import math

import pytest
from autopilot_loop import SimLoop
from test_mission_executor import PointVehicle

from autopilot.estimation import make_estimator
from autopilot.mission.executor import MissionExecutor
from autopilot.mission.plan import HomeTolerance, is_wpl_home_line
from autopilot.mission.uploads import UploadStore
from autopilot.mission.validation import check_mission, validate_mission
from mavlink_bridge.contract.frames import GeoPoint, LocalNedFrame
from mavlink_bridge.contract.mav_enums import MavCmd, MavFrame
from mavlink_bridge.contract.vehicle_api import MissionItem, MissionResult, MissionType

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


def _shifted_home(north_m: float, up_m: float) -> GeoPoint:
    """The vehicle's estimated home when its first fix was off by (north, up) from the file's home."""
    g = LocalNedFrame(HOME).geodetic_from_ned(north_m, 0.0, 0.0)
    return GeoPoint(g.lat_deg, g.lon_deg, HOME.alt_amsl_m + up_m)


def test_home_tolerance_is_three_times_the_reported_gps_accuracy_at_least_one_metre() -> None:
    assert HomeTolerance.from_gps(0.8, 1.4) == HomeTolerance(pytest.approx(2.4), pytest.approx(4.2))
    assert HomeTolerance.from_gps(0.1, math.inf) == HomeTolerance(1.0, 1.0)  # no vertical accuracy: the floor
    assert HomeTolerance.from_gps(math.nan, 0.2) == HomeTolerance(1.0, 1.0)


def test_home_line_off_by_the_first_fix_error_is_recognised_within_the_gps_accuracy() -> None:
    """The issue's case: the first fix put home 1.395 m above the file's home line (EKF, GPS epv 1.4 m)."""
    home = _shifted_home(0.9, 1.395)
    tol = HomeTolerance.from_gps(0.8, 1.4)
    assert not is_wpl_home_line(0, _home_line(), home)  # the old fixed 1 m
    assert is_wpl_home_line(0, _home_line(), home, tol)
    assert validate_mission(_mission(), home)[0] != MissionResult.ACCEPTED
    assert check_mission(_mission(), home, None, tol) is None
    assert not is_wpl_home_line(0, _home_line(), _shifted_home(3.0, 0.0), tol)  # beyond 3 x eph: a waypoint
    assert not is_wpl_home_line(0, _home_line(), _shifted_home(0.0, 5.0), tol)  # beyond 3 x epv


def test_executor_and_uploads_use_the_tolerance_they_are_given() -> None:
    home, tol = _shifted_home(0.5, -1.4), HomeTolerance.from_gps(0.8, 1.4)
    store = UploadStore()
    store.set_home(home, tol)
    assert store.upload(MissionType.MISSION, _mission()) == (MissionResult.ACCEPTED, "")
    assert store.flyable
    ex = MissionExecutor(home)
    ex.set_home(home, tol)
    ex.set_mission(_mission())
    vehicle = PointVehicle()
    ex.start(vehicle.t_us)
    out = ex.step(vehicle.sample())
    assert 0 in out.reached and out.target is not None and out.target.seq == 1


@pytest.mark.parametrize(("estimator", "seed"), [("ekf", 12), ("ekf", 22), ("truth", 12)])
def test_mavproxy_style_upload_after_the_first_fix_is_accepted_whichever_estimator_flies(
    estimator: str, seed: int
) -> None:
    """In process: the file's home line is the world's home; the EKF's first fix misses it by more than 1 m with
    these seeds (+1.39 m, -1.37 m), the truth estimator not at all: accepted either way, home line never flown to."""
    loop = SimLoop("x500", seed=seed, estimator=make_estimator(estimator))
    assert loop.run_until(lambda: loop.ap.navigator.frame is not None, 5.0)
    frame = loop.ap.navigator.frame
    assert frame is not None
    true_home = loop.sim.world.home
    off_m = frame.geo.alt_amsl_m - true_home.alt_amsl_m
    assert abs(off_m) > 1.0 if estimator == "ekf" else off_m == pytest.approx(0.0, abs=1e-6)
    line0 = MissionItem(0, MavCmd.NAV_WAYPOINT, MavFrame.GLOBAL, 0, 0, 0, 0, true_home.lat_deg, true_home.lon_deg,
                        true_home.alt_amsl_m)  # fmt: skip
    far = LocalNedFrame(true_home).geodetic_from_ned(30.0, 0.0, 0.0)
    items = [
        line0,
        MissionItem(1, MavCmd.NAV_TAKEOFF, MavFrame.GLOBAL_RELATIVE_ALT, z_alt_m=10.0),
        MissionItem(2, MavCmd.NAV_WAYPOINT, MavFrame.GLOBAL_RELATIVE_ALT, 0, 1, 0, 0, far.lat_deg, far.lon_deg, 10.0),
    ]
    assert loop.vehicle.replace_mission(MissionType.MISSION, items) == (MissionResult.ACCEPTED, "")
    assert loop.ap.navigator.mission_ready
