"""The vehicle's own UTM report (SPEC §13): its estimate, its next waypoint and flight state, once a second."""

from __future__ import annotations

import math

import pytest
from autopilot_fakes import command
from autopilot_loop import SimLoop

from autopilot.flight_tasks.setpoints import NavTarget, TargetKind
from autopilot.navigation.own_report import OwnReportSchedule, flight_state, next_waypoint_ned
from mavlink_bridge.contract.frames import LocalNedFrame
from mavlink_bridge.contract.mav_enums import MavCmd, MavFrame
from mavlink_bridge.contract.traffic import OwnPositionReport, UtmFlightState
from mavlink_bridge.contract.vehicle_api import CommandResult, FlightMode, MissionItem, MissionResult, MissionType

REL = int(MavFrame.GLOBAL_RELATIVE_ALT_INT)


def test_the_schedule_is_one_hertz_with_a_phase_per_system_id() -> None:
    for sys_id, first_us in ((1, 0), (2, 100_000), (12, 100_000)):
        schedule = OwnReportSchedule(sys_id)
        due = [t for t in range(0, 3_000_000, 4_000) if schedule.due(t)]
        assert due == [first_us, first_us + 1_000_000, first_us + 2_000_000]


def test_next_waypoint_and_flight_state_follow_the_mode() -> None:
    go = NavTarget(TargetKind.POSITION, (10.0, 20.0, -15.0))
    land = NavTarget(TargetKind.LAND, (3.0, 4.0, -15.0))
    home = (1.0, 1.0, 0.5)
    assert next_waypoint_ned(go, FlightMode.AUTO_MISSION, home) == (10.0, 20.0, -15.0)
    assert next_waypoint_ned(land, FlightMode.AUTO_LAND, home) == (3.0, 4.0, 0.5)  # touchdown at home's level
    assert next_waypoint_ned(go, FlightMode.POSCTL, home) is None  # a pilot's intent is not known
    assert next_waypoint_ned(NavTarget(TargetKind.IDLE), FlightMode.AUTO_MISSION, home) is None
    assert flight_state(True, True) is UtmFlightState.GROUND
    assert flight_state(False, False) is UtmFlightState.AIRBORNE
    assert flight_state(False, True) is UtmFlightState.EMERGENCY


def _reports(loop: SimLoop, seconds: float) -> list[OwnPositionReport]:
    out: list[OwnPositionReport] = []

    def take() -> None:
        report = loop.ap.own_reporter.report_for(loop.ap.state.time_us)  # type: ignore[union-attr]
        if report is not None:
            out.append(report)

    loop.run_s(seconds, take)
    return out


def test_an_autopilots_own_report_carries_its_estimate_and_next_waypoint() -> None:
    loop = SimLoop()
    on_pad = _reports(loop, 2.0)
    assert [r.t_us for r in on_pad] == [0, 1_000_000]
    assert all(r.flight_state is UtmFlightState.GROUND and math.isnan(r.next_lat_deg) for r in on_pad)
    frame = LocalNedFrame(loop.ap.home_geo)  # type: ignore[arg-type]
    wp = frame.geodetic_from_ned(60.0, 30.0, 0.0)
    items = [
        MissionItem(0, int(MavCmd.NAV_TAKEOFF), REL, z_alt_m=12.0, param4=math.nan),
        MissionItem(1, int(MavCmd.NAV_WAYPOINT), REL, 0.0, 1.0, 0.0, math.nan, wp.lat_deg, wp.lon_deg, 12.0),
        MissionItem(2, int(MavCmd.NAV_LAND), REL, param4=math.nan),
    ]
    assert loop.vehicle.replace_mission(MissionType.MISSION, items) == (MissionResult.ACCEPTED, "")
    assert loop.vehicle.handle_command(command(400, 1.0)) is CommandResult.ACCEPTED
    assert loop.vehicle.handle_command(command(300, 0.0)) is CommandResult.ACCEPTED
    assert loop.run_until(lambda: loop.ap.navigator.current_seq == 1 and loop.alt_m > 11.0, 30.0), loop.texts
    cruising = _reports(loop, 3.0)
    assert len(cruising) == 3
    for r in cruising:
        assert r.flight_state is UtmFlightState.AIRBORNE and r.update_rate_hz == 1.0 and r.sys_id == 1
        assert (r.next_lat_deg, r.next_lon_deg) == pytest.approx((wp.lat_deg, wp.lon_deg), abs=1e-6)
        assert r.next_alt_amsl_m == pytest.approx(loop.ap.home_geo.alt_amsl_m + 12.0, abs=0.5)  # type: ignore[union-attr]
        assert math.isfinite(r.h_acc_m) and math.isfinite(r.v_acc_m)
    last = cruising[-1]
    truth = frame.geodetic_from_ned(*map(float, loop.sim.pos_ned))
    assert last.lat_deg == pytest.approx(truth.lat_deg, abs=2e-5)  # the estimate, near the truth
    assert math.hypot(last.vel_n_m_s, last.vel_e_m_s) > 1.0  # on its way
