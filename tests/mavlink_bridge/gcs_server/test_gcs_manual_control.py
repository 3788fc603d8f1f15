"""POSCTL from a joystick: MANUAL_CONTROL decoded, sticks turned into velocities about the heading, and a flight
from takeoff to landing on the sticks alone (centred sticks hold, a silent joystick holds)."""

from __future__ import annotations

import math
import os
import time

import pytest
from autopilot_fakes import command
from autopilot_loop import SimLoop
from gcs_fakes import served_fake_vehicle

from autopilot.flight_tasks.position_control import deadzone, stick_demand
from autopilot.param_schema import make_param_store
from mavlink_bridge.contract.vehicle_api import CommandResult, FlightMode, LandedState, ManualInput

os.environ.setdefault("MAVLINK20", "1")
from pymavlink import mavutil

mavutil.set_dialect("common")
M = mavutil.mavlink
POSCTL = 3  # PX4 main mode


# ---- the stick law --------------------------------------------------------------------------------------------
def test_deadzone_removes_the_centre_band_and_rescales_the_rest() -> None:
    assert deadzone(0.05, 0.1) == 0.0 and deadzone(-0.1, 0.1) == 0.0
    assert deadzone(0.55, 0.1) == pytest.approx(0.5) and deadzone(-1.0, 0.1) == -1.0
    assert deadzone(0.3, 0.0) == 0.3


def test_sticks_ask_for_velocities_about_the_heading_within_the_limits() -> None:
    params = make_param_store()
    params.set("MPC_VEL_MANUAL", 8.0)
    params.set("MPC_HOLD_DZ", 0.0)
    assert stick_demand(ManualInput(), 0.3, params) is None  # all centred: hold
    east = stick_demand(ManualInput(forward=0.5), math.pi / 2, params)  # half stick forward, heading east
    assert east is not None and east.vel_ned_m_s == pytest.approx((0.0, 4.0, 0.0), abs=1e-12)
    right = stick_demand(ManualInput(right=1.0), 0.0, params)
    assert right is not None and right.vel_ned_m_s == pytest.approx((0.0, 8.0, 0.0))
    both = stick_demand(ManualInput(forward=1.0, right=1.0), 0.0, params)  # full diagonal: the same top speed
    assert both is not None and math.hypot(*both.vel_ned_m_s[:2]) == pytest.approx(8.0)
    up = stick_demand(ManualInput(throttle=1.0), 0.0, params)
    down = stick_demand(ManualInput(throttle=0.25), 0.0, params)
    assert up is not None and up.vel_ned_m_s[2] == pytest.approx(-params.get("MPC_Z_VEL_MAX_UP"))
    assert down is not None and down.vel_ned_m_s[2] == pytest.approx(0.5 * params.get("MPC_Z_VEL_MAX_DN"))
    turn = stick_demand(ManualInput(yaw=-1.0), 0.0, params)
    assert turn is not None and turn.yaw_rate_rad_s == pytest.approx(-math.radians(params.get("MPC_YAWRAUTO_MAX")))
    params.set("MPC_XY_VEL_MAX", 5.0)  # the general cap wins over the manual speed
    capped = stick_demand(ManualInput(forward=1.0), 0.0, params)
    assert capped is not None and capped.vel_ned_m_s[0] == pytest.approx(5.0) and capped.speed_xy_m_s == 5.0


# ---- the message ------------------------------------------------------------------------------------------------
def test_manual_control_is_decoded_for_this_system_only() -> None:
    with served_fake_vehicle() as (vehicle, server, harness, conn):
        conn.mav.manual_control_send(1, 500, -250, 750, 1000, 0)
        conn.mav.manual_control_send(0, 2000, -2000, 1500, 0x7FFF, 0)  # broadcast; clamped; yaw axis unused
        conn.mav.manual_control_send(1, 0x7FFF, 0x7FFF, 0x7FFF, 0x7FFF, 0)  # every axis unused: centred
        conn.mav.manual_control_send(2, 1000, 0, 500, 0, 0)  # another vehicle's
        deadline = time.monotonic() + 5.0
        while time.monotonic() < deadline:
            with harness.locked():
                if server.manual.stats.received + server.stats.not_for_us == 4:
                    break
            time.sleep(0.02)
        with harness.locked():
            got = list(vehicle.manual_inputs)
            stats, not_for_us = server.manual.stats, server.stats.not_for_us
    assert got == [
        ManualInput(0.5, -0.25, 0.75, 1.0),
        ManualInput(1.0, -1.0, 1.0, 0.0),
        ManualInput(0.0, 0.0, 0.5, 0.0),
    ]
    assert (stats.received, stats.used, stats.refused, not_for_us) == (3, 3, 0, 1)  # system 2's: dropped by the server


# ---- a flight on the sticks -------------------------------------------------------------------------------------
def test_posctl_flight_on_the_sticks_takeoff_fly_turn_hold_land() -> None:
    loop = SimLoop("x500")  # link timeouts on a clock that runs like sim time (SimLoop's default)
    vehicle, sim, ap = loop.vehicle, loop.sim, loop.ap
    sticks = [ManualInput()]

    def joystick() -> None:  # a GCS sends its sticks continuously
        assert vehicle.set_manual_input(sticks[0])

    loop.run_s(2.0)  # GPS fix, home
    assert vehicle.handle_command(command(M.MAV_CMD_DO_SET_MODE, 1, POSCTL)) is CommandResult.ACCEPTED
    assert vehicle.handle_command(command(M.MAV_CMD_COMPONENT_ARM_DISARM, 1)) is CommandResult.ACCEPTED
    loop.run_s(1.0, joystick)  # centred throttle on the ground: no takeoff
    assert ap.commander.armed and ap.commander.landed_state is LandedState.ON_GROUND
    sticks[0] = ManualInput(throttle=1.0)
    loop.run_s(5.0, joystick)
    climb = ap.params.get("MPC_Z_VEL_MAX_UP")
    assert ap.commander.in_air and sim.vel_ned[2] == pytest.approx(-climb, abs=0.15)
    sticks[0] = ManualInput(forward=0.55)  # half speed after the 0.1 deadzone: 5 m/s along the heading
    loop.run_s(6.0, joystick)
    yaw = ap.state.yaw_rad
    assert sim.vel_ned == pytest.approx((5.0 * math.cos(yaw), 5.0 * math.sin(yaw), 0.0), abs=0.2)
    sticks[0] = ManualInput(yaw=1.0)
    yaw0 = ap.state.yaw_rad
    loop.run_s(2.0, joystick)
    turned = (ap.state.yaw_rad - yaw0 + math.pi) % (2 * math.pi) - math.pi
    assert math.degrees(turned) == pytest.approx(2.0 * ap.params.get("MPC_YAWRAUTO_MAX"), abs=10.0)
    sticks[0] = ManualInput()  # let go: brake and hold where it stopped
    loop.run_s(5.0, joystick)
    held = tuple(sim.pos_ned)
    loop.run_s(5.0, joystick)
    assert math.dist(held, sim.pos_ned) < 0.1 and math.hypot(*sim.vel_ned[:2]) < 0.05
    sticks[0] = ManualInput(forward=1.0)
    loop.run_s(1.0, joystick)
    loop.run_s(6.0)  # the joystick goes silent mid-flight: after COM_RC_LOSS_T (wall clock) it holds
    assert math.hypot(*sim.vel_ned[:2]) < 0.1
    sticks[0] = ManualInput(throttle=0.0)
    loop.run_s(25.0, joystick)
    assert "Landing detected" in loop.texts and not ap.commander.armed
    assert sim.pos_ned[2] == pytest.approx(0.0, abs=0.1) and ap.commander.mode is FlightMode.POSCTL
