"""Commander: arming checks with reasons, PX4 mode encodings, takeoff/hold/land/RTL flows, touchdown, commands."""

from __future__ import annotations

import math

import pytest
from autopilot_fakes import FRAME, KinematicLoop, command, make_commander, make_state, set_context, update

from autopilot.commander.commands import (
    FORCE_MAGIC,
)
from autopilot.flight_tasks.setpoints import TargetKind
from autopilot.safety.failsafe import FailsafeAction, FailsafeEvent, FailsafeKind
from mavlink_bridge.contract.mav_enums import MavCmd
from mavlink_bridge.contract.vehicle_api import CommandResult, FlightMode, LandedState

ARM = (MavCmd.COMPONENT_ARM_DISARM, 1.0)
DISARM = (MavCmd.COMPONENT_ARM_DISARM, 0.0)


def test_px4_mode_encoding_round_trips_main_and_sub_mode() -> None:
    assert FlightMode.AUTO_LOITER.value == (4 << 16) | (3 << 24)
    assert FlightMode.POSCTL.px4_main_mode == 3 and FlightMode.POSCTL.px4_sub_mode == 0
    for mode in FlightMode:
        assert FlightMode.from_px4(mode.px4_main_mode, mode.px4_sub_mode) is mode
    commander = make_commander()
    update(commander, make_state(), 0.0)
    assert commander.handle_command(command(MavCmd.DO_SET_MODE, 1, 4, 2)) is CommandResult.ACCEPTED
    assert commander.mode is FlightMode.AUTO_TAKEOFF
    assert commander.handle_command(command(MavCmd.DO_SET_MODE, 1, 4, 0)) is CommandResult.ACCEPTED
    assert commander.mode is FlightMode.AUTO_LOITER  # AUTO without sub mode = HOLD
    assert commander.handle_command(command(MavCmd.DO_SET_MODE, 1, 1, 0)) is CommandResult.DENIED  # MANUAL: no RC
    assert "not supported" in commander.last_reason
    assert commander.handle_command(command(MavCmd.DO_SET_MODE, 1, 9, 0)) is CommandResult.DENIED
    assert "unknown PX4 mode" in commander.last_reason
    assert commander.handle_command(command(MavCmd.DO_SET_MODE, 0, 4, 3)) is CommandResult.DENIED


@pytest.mark.parametrize(
    ("state_kwargs", "reason"),
    [
        ({"valid": False}, "estimator not ready"),
        ({"gps_fix_type": 2}, "no 3D GPS fix"),
    ],
)
def test_arming_refused_with_reason(state_kwargs: dict[str, object], reason: str) -> None:
    commander = make_commander()
    update(commander, make_state(**state_kwargs), 0.0)  # type: ignore[arg-type]
    assert commander.handle_command(command(*ARM)) is CommandResult.DENIED
    assert reason in commander.last_reason
    assert not commander.armed
    assert any(reason in t.text for t in commander.drain_texts())


def test_arming_refused_without_state_in_air_in_failsafe_and_in_land_mode() -> None:
    commander = make_commander()
    assert commander.handle_command(command(*ARM)) is CommandResult.TEMPORARILY_REJECTED
    update(commander, make_state(), 0.0)
    set_context(commander, failsafe_reasons=frozenset({"geofence breach"}))
    assert commander.handle_command(command(*ARM)) is CommandResult.DENIED
    assert "failsafe active" in commander.last_reason
    set_context(commander, failsafe_reasons=frozenset())
    commander.mode = FlightMode.AUTO_LAND
    assert commander.handle_command(command(*ARM)) is CommandResult.DENIED
    assert "AUTO_LAND" in commander.last_reason
    commander.mode = FlightMode.AUTO_LOITER
    commander.landed_state = LandedState.IN_AIR
    assert commander.handle_command(command(*ARM)) is CommandResult.DENIED
    assert "not on the ground" in commander.last_reason
    assert commander.handle_command(command(MavCmd.DO_SET_MODE, 1, 4, 4)) is CommandResult.DENIED  # no mission
    assert "no valid mission" in commander.last_reason


def test_force_arm_skips_checks_and_disarm_in_air_needs_force() -> None:
    commander = make_commander()
    update(commander, make_state(gps_fix_type=0), 0.0)
    assert commander.handle_command(command(MavCmd.COMPONENT_ARM_DISARM, 1.0, FORCE_MAGIC)) is CommandResult.ACCEPTED
    assert commander.armed and commander.home is not None
    commander.landed_state = LandedState.IN_AIR
    assert commander.handle_command(command(*DISARM)) is CommandResult.DENIED
    assert "in air" in commander.last_reason
    assert commander.handle_command(command(MavCmd.COMPONENT_ARM_DISARM, 0.0, FORCE_MAGIC)) is CommandResult.ACCEPTED
    assert not commander.armed
    assert commander.handle_command(command(MavCmd.COMPONENT_ARM_DISARM, 2.0)) is CommandResult.DENIED


def test_commands_that_need_flight_are_refused_on_the_ground() -> None:
    commander = make_commander()
    update(commander, make_state(), 0.0)
    for cmd in (
        (MavCmd.NAV_LAND,),
        (MavCmd.NAV_RETURN_TO_LAUNCH,),
        (MavCmd.DO_REPOSITION, -1, 1, 0, math.nan, 47.4, 8.5, 500),
    ):
        result = commander.handle_command(command(*cmd))
        assert result in (CommandResult.DENIED, CommandResult.TEMPORARILY_REJECTED), cmd
        assert commander.last_reason
    assert commander.handle_command(command(12345)) is CommandResult.UNSUPPORTED
    assert commander.handle_command(command(MavCmd.NAV_TAKEOFF, 0, 0, 0, 0, 0, 0, math.inf)) is CommandResult.DENIED


def test_takeoff_altitude_frames_and_range() -> None:
    commander = make_commander()
    update(commander, make_state(), 0.0)
    # COMMAND_LONG param7 is AMSL (PX4): 10 m AMSL is below home at 488 m
    assert commander.handle_command(command(MavCmd.NAV_TAKEOFF, *[0] * 6, 10.0)) is CommandResult.DENIED
    assert "AMSL" in commander.last_reason
    ok = commander.handle_command(command(MavCmd.NAV_TAKEOFF, *[0] * 6, 488.0 + 15.0))
    assert ok is CommandResult.ACCEPTED and commander.mode is FlightMode.AUTO_TAKEOFF
    assert commander.takeoff.alt_rel_m == pytest.approx(15.0)
    rel = command(MavCmd.NAV_TAKEOFF, *[0] * 6, 12.0, is_int=True, frame=6)
    assert commander.handle_command(rel) is CommandResult.ACCEPTED
    assert commander.takeoff.alt_rel_m == pytest.approx(12.0)
    assert commander.handle_command(command(MavCmd.NAV_TAKEOFF, *[0] * 6, math.nan)) is CommandResult.ACCEPTED
    assert commander.takeoff.alt_rel_m == pytest.approx(commander.params.get("MIS_TAKEOFF_ALT"))


def _takeoff(loop: KinematicLoop, alt_m: float = 10.0) -> None:
    commander = loop.commander
    loop.step()
    assert (
        commander.handle_command(command(MavCmd.NAV_TAKEOFF, *[0] * 6, alt_m, is_int=True, frame=6)).name == "ACCEPTED"
    )
    assert commander.landed_state is LandedState.ON_GROUND
    assert commander.handle_command(command(*ARM)) is CommandResult.ACCEPTED
    assert loop.run_until(lambda: commander.mode is FlightMode.AUTO_LOITER, 30.0)
    assert commander.landed_state is LandedState.IN_AIR
    assert -loop.pos[2] == pytest.approx(alt_m, abs=commander.params.get("MIS_ALT_ACC_RAD"))


def test_takeoff_hold_land_touchdown_and_auto_disarm() -> None:
    loop = KinematicLoop(make_commander())
    commander = loop.commander
    _takeoff(loop)
    loop.run_s(3.0)
    assert -loop.pos[2] == pytest.approx(10.0, abs=0.05)  # holds
    assert commander.handle_command(command(MavCmd.NAV_LAND)) is CommandResult.ACCEPTED
    assert commander.mode is FlightMode.AUTO_LAND
    loop.step()
    assert commander.landed_state is LandedState.LANDING
    assert loop.run_until(lambda: commander.landed_state is LandedState.ON_GROUND, 60.0)
    touchdown_s = loop.time_us / 1e6
    assert loop.pos[2] == pytest.approx(0.0, abs=1e-6)
    assert commander.armed  # disarms only after COM_DISARM_LAND
    assert loop.run_until(lambda: not commander.armed, 5.0)
    assert loop.time_us / 1e6 - touchdown_s == pytest.approx(commander.params.get("COM_DISARM_LAND"), abs=0.02)
    texts = [t.text for t in commander.drain_texts()]
    assert "Landing detected" in texts and "Disarmed (landed)" in texts
    modes = [m for _, m in commander.mode_history]
    assert modes == [FlightMode.AUTO_TAKEOFF, FlightMode.AUTO_LOITER, FlightMode.AUTO_LAND, FlightMode.AUTO_LOITER]


def test_hovering_vehicle_is_never_detected_as_landed() -> None:
    loop = KinematicLoop(make_commander())
    _takeoff(loop, 3.0)
    loop.run_s(10.0)
    assert loop.commander.landed_state is LandedState.IN_AIR and loop.commander.armed


def test_reposition_flies_to_a_global_point_and_faces_it() -> None:
    loop = KinematicLoop(make_commander())
    commander = loop.commander
    _takeoff(loop)
    goal = FRAME.geodetic_from_ned(30.0, 40.0, 0.0)
    req = command(MavCmd.DO_REPOSITION, -1, 1, 0, math.nan, goal.lat_deg, goal.lon_deg, 15.0, is_int=True, frame=6)
    assert commander.handle_command(req) is CommandResult.ACCEPTED
    assert loop.run_until(lambda: math.dist(loop.pos, (30.0, 40.0, -15.0)) < 0.1, 40.0)
    assert loop.gen.yaw_rad == pytest.approx(math.atan2(40.0, 30.0), abs=1e-6)
    bad = command(MavCmd.DO_REPOSITION, -1, 1, 0, math.nan, 123.0, 8.5, 15.0, is_int=True, frame=6)
    assert commander.handle_command(bad) is CommandResult.DENIED


def test_rtl_climbs_returns_and_lands_at_home() -> None:
    loop = KinematicLoop(make_commander())
    commander = loop.commander
    commander.params.set("MIS_RTL_ALT", 20.0)
    _takeoff(loop)
    commander.goto(loop.state(), (40.0, -20.0, -10.0))
    assert loop.run_until(lambda: math.dist(loop.pos, (40.0, -20.0, -10.0)) < 0.1, 40.0)
    assert commander.handle_command(command(MavCmd.NAV_RETURN_TO_LAUNCH)) is CommandResult.ACCEPTED
    max_alt = 0.0
    far_from_home_alt = []
    for _ in range(round(120.0 / loop.dt_s)):
        loop.step()
        max_alt = max(max_alt, -loop.pos[2])
        if math.hypot(loop.pos[0], loop.pos[1]) > 20.0:
            far_from_home_alt.append(-loop.pos[2])
        if not commander.armed:
            break
    assert not commander.armed and commander.landed_state is LandedState.ON_GROUND
    assert max_alt == pytest.approx(20.0, abs=0.5)
    assert min(far_from_home_alt[len(far_from_home_alt) // 2 :]) > 19.0  # returned at the RTL altitude
    assert math.hypot(loop.pos[0], loop.pos[1]) < commander.params.get("MIS_ACC_RAD")


def test_change_speed_gripper_and_failsafe_actions() -> None:
    loop = KinematicLoop(make_commander())
    commander = loop.commander
    _takeoff(loop)
    assert commander.handle_command(command(MavCmd.DO_CHANGE_SPEED, 1, 3.0)) is CommandResult.ACCEPTED
    assert commander.speed_xy_m_s == 3.0
    assert commander.handle_command(command(MavCmd.DO_CHANGE_SPEED, 1, 99.0)) is CommandResult.DENIED
    assert commander.handle_command(command(MavCmd.DO_CHANGE_SPEED, 2, 1.0)) is CommandResult.UNSUPPORTED
    assert commander.handle_command(command(MavCmd.DO_CHANGE_SPEED, 1, -2.0)) is CommandResult.ACCEPTED
    assert commander.speed_xy_m_s == commander.params.get("MIS_CRUISE_SPD")
    assert commander.handle_command(command(MavCmd.DO_GRIPPER, 1, 0)) is CommandResult.ACCEPTED
    assert commander.gripper_release
    assert commander.handle_command(command(MavCmd.DO_GRIPPER, 1, 7)) is CommandResult.DENIED
    commander.apply_failsafe(FailsafeEvent(FailsafeKind.BATTERY_CRITICAL, FailsafeAction.WARN, "battery"))
    assert commander.mode is FlightMode.AUTO_LOITER
    commander.apply_failsafe(FailsafeEvent(FailsafeKind.GEOFENCE, FailsafeAction.RTL, "fence"))
    assert commander.mode is FlightMode.AUTO_RTL
    commander.apply_failsafe(FailsafeEvent(FailsafeKind.GCS_LOSS, FailsafeAction.LAND, "gcs"))
    assert commander.mode is FlightMode.AUTO_LAND


def test_offboard_needs_a_setpoint_and_mission_target_drives_auto_mission() -> None:
    loop = KinematicLoop(make_commander())
    commander = loop.commander
    _takeoff(loop)
    assert commander.handle_command(command(MavCmd.DO_SET_MODE, 1, 6, 0)) is CommandResult.DENIED
    commander.set_offboard_target((5.0, 0.0, -12.0))
    assert commander.handle_command(command(MavCmd.DO_SET_MODE, 1, 6, 0)) is CommandResult.DENIED  # not streaming
    set_context(commander, offboard_streaming=True)  # the runner: setpoints arrive within COM_OF_LOSS_T
    assert commander.handle_command(command(MavCmd.DO_SET_MODE, 1, 6, 0)) is CommandResult.ACCEPTED
    assert loop.run_until(lambda: math.dist(loop.pos, (5.0, 0.0, -12.0)) < 0.1, 20.0)
    set_context(commander, mission_ready=True)
    assert commander.handle_command(command(MavCmd.MISSION_START)) is CommandResult.ACCEPTED
    from autopilot.flight_tasks.setpoints import NavTarget

    loop.mission_target = NavTarget(TargetKind.POSITION, (0.0, 8.0, -6.0))
    assert loop.run_until(lambda: math.dist(loop.pos, (0.0, 8.0, -6.0)) < 0.1, 20.0)


def test_home_is_set_at_the_first_3d_fix_and_moved_at_arming() -> None:
    commander = make_commander()
    update(commander, make_state(gps_fix_type=2), 0.0)
    assert commander.home is None
    update(commander, make_state((1.0, 2.0, 0.0)), 0.0)
    assert commander.home is not None and commander.home.pos_ned_m == (1.0, 2.0, 0.0)
    update(commander, make_state((3.0, 4.0, 0.0)), 0.0)
    assert commander.home.pos_ned_m == (1.0, 2.0, 0.0)
    assert commander.handle_command(command(*ARM)) is CommandResult.ACCEPTED
    assert commander.home.pos_ned_m == (3.0, 4.0, 0.0)


def test_cached_speeds_and_land_detector_follow_parameter_changes_in_flight() -> None:
    """The commander caches parameter-derived values per ``ParamStore.version``: a change applies next step."""
    loop = KinematicLoop(make_commander())
    commander = loop.commander
    _takeoff(loop, 3.0)
    loop.run_s(6.0)
    assert commander.mode is FlightMode.AUTO_LOITER
    target = update(commander, loop.state(), loop.thrust_ratio)
    assert target.speed_up_m_s == commander.params.get("MPC_Z_VEL_MAX_UP")
    commander.params.set("MPC_Z_VEL_MAX_UP", 2.5)
    commander.params.set("MPC_XY_VEL_MAX", 1.5)
    target = update(commander, loop.state(), loop.thrust_ratio)
    assert (target.speed_xy_m_s, target.speed_up_m_s) == (1.5, 2.5)
    assert commander.handle_command(command(MavCmd.NAV_LAND)) is CommandResult.ACCEPTED
    commander.params.set("LNDMC_TRIG_TIME", 1.5)  # a longer confirmation before "Landing detected"
    assert loop.run_until(lambda: commander.landed_state is LandedState.ON_GROUND, 60.0)
    quiet_since_us = commander.land_detector.quiet_since_us
    assert quiet_since_us is not None
    assert loop.time_us - round(loop.dt_s * 1e6) - quiet_since_us >= 1.5e6
