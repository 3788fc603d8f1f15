"""OFFBOARD over MAVLink with pymavlink: SET_POSITION_TARGET_* decoded (position and velocity setpoints), PX4's
streaming rule, setpoint-loss failsafe, a velocity-controlled flight from takeoff to landing."""

from __future__ import annotations

import math
import os
import threading
import time

import pytest
from autopilot_fakes import command
from autopilot_loop import InProcessLockstep, SimLoop
from conftest import free_udp_port
from gcs_fakes import FakeVehicle, ServerHarness

from autopilot.io_loop import Links, run_loop
from mavlink_bridge.contract.vehicle_api import (
    AltitudeFrame,
    CommandResult,
    FlightMode,
    GlobalPositionTarget,
    LocalPositionTarget,
    VelocityFrame,
    VelocityTarget,
)
from mavlink_bridge.gcs_server.server import GcsServer

os.environ.setdefault("MAVLINK20", "1")
from pymavlink import mavutil

mavutil.set_dialect("common")
M = mavutil.mavlink
#: type_mask: position (+ yaw) only: ignore velocity, acceleration and yaw rate.
POSITION_YAW = 0x09F8
POSITION_ONLY = POSITION_YAW | 0x400
VELOCITY_ONLY = 0x0DC7
#: velocity + yaw rate (MAVSDK set_velocity_body), velocity + yaw (set_velocity_ned), acceleration only.
VELOCITY_YAW_RATE = 0x05C7
VELOCITY_YAW = 0x09C7
ACCELERATION_ONLY = 0x0C3F
#: Failure deadline (wall s) of each exchange in the in-process flight: a numba kernel compiled on first use (a
#: fresh clone) holds the autopilot thread for many seconds on a loaded 2-core machine.
WAIT_S = 60.0


def _recv(conn, kind: str, timeout_s: float, predicate=lambda m: True):  # type: ignore[no-untyped-def]
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        msg = conn.recv_match(type=kind, blocking=True, timeout=0.2)
        if msg is not None and predicate(msg):
            return msg
    raise AssertionError(f"no matching {kind} within {timeout_s} s")


def test_setpoint_messages_are_decoded_for_the_vehicle() -> None:
    port = free_udp_port()
    vehicle = FakeVehicle()
    server = GcsServer(f"udpin:127.0.0.1:{port}", vehicle, default_target_url=f"udpout:127.0.0.1:{free_udp_port()}")
    harness = ServerHarness(server, vehicle)
    conn = mavutil.mavlink_connection(f"udpout:127.0.0.1:{port}", source_system=255)
    try:
        conn.mav.set_position_target_local_ned_send(
            0, 1, 1, M.MAV_FRAME_LOCAL_NED, POSITION_YAW, 5, -2, -8, *[0] * 6, 0.5, 0
        )
        conn.mav.set_position_target_local_ned_send(0, 1, 1, M.MAV_FRAME_LOCAL_NED, VELOCITY_ONLY, 0, 0, 0, 1, *[0] * 7)
        conn.mav.set_position_target_local_ned_send(0, 1, 1, M.MAV_FRAME_BODY_NED, POSITION_ONLY, 1, 0, 0, *[0] * 8)
        lat, lon = 473978000, 85457000
        frame = M.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT
        conn.mav.set_position_target_global_int_send(0, 1, 1, frame, POSITION_ONLY, lat, lon, 12.0, *[0] * 8)
        conn.mav.set_position_target_global_int_send(
            0, 1, 1, M.MAV_FRAME_GLOBAL_INT, POSITION_ONLY, lat, lon, 500.0, *[0] * 8
        )
        local = conn.mav.set_position_target_local_ned_send
        local(0, 1, 1, M.MAV_FRAME_BODY_NED, VELOCITY_YAW_RATE, 0, 0, 0, 1.5, -0.5, 0.2, 0, 0, 0, 0, 0.3)
        local(0, 1, 1, M.MAV_FRAME_LOCAL_NED, VELOCITY_YAW, 0, 0, 0, -1, 2, 0, 0, 0, 0, 1.25, 0.3)
        local(0, 1, 1, M.MAV_FRAME_BODY_FRD, VELOCITY_ONLY, 0, 0, 0, 0.5, 0, 0, *[0] * 5)
        local(0, 1, 1, M.MAV_FRAME_LOCAL_NED, ACCELERATION_ONLY, 0, 0, 0, 0, 0, 0, 1, 0, 0, 0, 0)  # dropped
        local(0, 1, 1, M.MAV_FRAME_LOCAL_NED, VELOCITY_ONLY, 0, 0, 0, math.nan, 0, 0, *[0] * 5)  # dropped
        local(0, 1, 1, M.MAV_FRAME_LOCAL_NED, VELOCITY_YAW, 0, 0, 0, 1, 0, 0, 0, 0, 0, math.inf, 0)  # dropped
        local(0, 1, 1, M.MAV_FRAME_GLOBAL_INT, VELOCITY_ONLY, 0, 0, 0, 1, 0, 0, *[0] * 5)  # dropped: not local
        conn.mav.set_position_target_global_int_send(0, 1, 1, frame, VELOCITY_ONLY, 0, 0, 0, 1, 0, 0, *[0] * 5)
        deadline = time.monotonic() + 5.0
        while server.stats.setpoints_used + server.stats.setpoints_dropped < 13 and time.monotonic() < deadline:
            time.sleep(0.02)
        with harness.locked():
            targets = list(vehicle.position_targets)
            velocities = list(vehicle.velocity_targets)
        assert targets[0] == LocalPositionTarget((5.0, -2.0, -8.0), 0.5)
        t1 = targets[1]
        assert isinstance(t1, GlobalPositionTarget) and t1.alt_frame is AltitudeFrame.ABOVE_HOME
        assert (t1.lat_deg, t1.lon_deg, t1.alt_m) == (47.3978, 8.5457, 12.0) and math.isnan(t1.yaw_rad)
        assert targets[2].alt_frame is AltitudeFrame.AMSL and targets[2].alt_m == 500.0
        assert len(targets) == 3
        nan = math.nan
        body, local_ned = VelocityFrame.BODY, VelocityFrame.LOCAL_NED
        expected = [
            VelocityTarget((1.0, 0.0, 0.0), local_ned, nan, nan),
            VelocityTarget((1.5, -0.5, 0.2), body, nan, 0.3),  # float32 on the wire: compared below
            VelocityTarget((-1.0, 2.0, 0.0), local_ned, 1.25, nan),  # a yaw wins: the yaw rate is not used
            VelocityTarget((0.5, 0.0, 0.0), body, nan, nan),
        ]
        assert len(velocities) == len(expected)
        for got, want in zip(velocities, expected, strict=True):
            assert got.frame is want.frame
            assert got.vel_m_s == pytest.approx(want.vel_m_s)
            assert got.yaw_rad == pytest.approx(want.yaw_rad, nan_ok=True)
            assert got.yaw_rate_rad_s == pytest.approx(want.yaw_rate_rad_s, nan_ok=True)
        # dropped: position in a body frame, acceleration-only, NaN velocity, infinite yaw, velocity in a global
        # frame (local message) and in the global message
        assert (server.stats.setpoints_used, server.stats.setpoints_dropped) == (7, 6)
    finally:
        conn.close()
        harness.stop()


def _command(conn, cmd: int, *params: float) -> int:  # type: ignore[no-untyped-def]
    full = [*params, *[0.0] * (7 - len(params))]
    conn.mav.command_long_send(1, 1, cmd, 0, *full)
    return _recv(conn, "COMMAND_ACK", WAIT_S, lambda m: m.command == cmd).result


def test_offboard_flight_needs_streaming_setpoints_and_holds_when_they_stop() -> None:
    loop = SimLoop("x500")
    ap = loop.ap
    # A loaded machine can stall the setpoint thread for a second (wall clock): tolerate that in flight; the
    # default 1 s comes back over PARAM_SET right before the client goes silent on purpose.
    ap.params.set("COM_OF_LOSS_T", 10.0)
    port = free_udp_port()
    server = GcsServer(
        f"udpin:127.0.0.1:{port}", loop.vehicle, default_target_url=f"udpout:127.0.0.1:{free_udp_port()}"
    )
    stop = threading.Event()
    runner = threading.Thread(target=run_loop, args=(ap, Links(InProcessLockstep(loop), [server]), stop.is_set))
    runner.start()
    conn = mavutil.mavlink_connection(f"udpout:127.0.0.1:{port}", source_system=255, source_component=190)
    streaming = threading.Event()

    def stream() -> None:
        while not stop.is_set():
            if streaming.is_set():
                conn.mav.set_position_target_local_ned_send(
                    0, 1, 1, M.MAV_FRAME_LOCAL_NED, POSITION_ONLY, 6.0, 0.0, -8.0, *[0] * 8
                )
            time.sleep(0.05)

    sender = threading.Thread(target=stream)
    sender.start()
    try:
        conn.mav.heartbeat_send(M.MAV_TYPE_GCS, M.MAV_AUTOPILOT_INVALID, 0, 0, 0)
        _recv(conn, "LOCAL_POSITION_NED", 20.0)
        assert _command(conn, M.MAV_CMD_DO_SET_MODE, 1, 6) == M.MAV_RESULT_DENIED  # no setpoints yet
        streaming.set()
        _recv(conn, "HEARTBEAT", 5.0)
        time.sleep(0.3)
        assert _command(conn, M.MAV_CMD_DO_SET_MODE, 1, 6) == M.MAV_RESULT_ACCEPTED
        assert _command(conn, M.MAV_CMD_COMPONENT_ARM_DISARM, 1) == M.MAV_RESULT_ACCEPTED
        _recv(conn, "LOCAL_POSITION_NED", 60.0, lambda m: math.dist((m.x, m.y, m.z), (6.0, 0.0, -8.0)) < 0.5)
        conn.mav.param_set_send(1, 1, b"COM_OF_LOSS_T", 1.0, M.MAV_PARAM_TYPE_REAL32)
        _recv(conn, "PARAM_VALUE", WAIT_S, lambda m: m.param_id == "COM_OF_LOSS_T" and m.param_value == 1.0)
        streaming.clear()  # the offboard client goes silent: COM_OF_LOSS_T later, COM_OBL_ACT = hold
        _recv(conn, "STATUSTEXT", WAIT_S, lambda m: "offboard setpoints lost" in m.text)
        hold = FlightMode.AUTO_LOITER
        _recv(conn, "HEARTBEAT", WAIT_S, lambda m: m.custom_mode == hold.value)
        assert _command(conn, M.MAV_CMD_DO_SET_MODE, 1, 6) == M.MAV_RESULT_DENIED  # stale setpoints: not again
    finally:
        stop.set()
        runner.join(30.0)
        sender.join(5.0)
        conn.close()
        server.close()
    assert ap.commander.armed and ap.commander.in_air
    assert math.dist(loop.sim.pos_ned, (6.0, 0.0, -8.0)) < 1.5  # held near the last setpoint


def test_velocity_setpoints_fly_takeoff_cruise_turn_and_land() -> None:
    """OFFBOARD on velocity setpoints alone, as a MAVSDK ``set_velocity_*`` client flies: a climbing setpoint
    takes off, NED and body-frame velocities are tracked, a yaw rate turns the heading, a descending setpoint
    lands and the vehicle disarms on the ground."""
    loop = SimLoop("x500")
    vehicle, sim = loop.vehicle, loop.sim
    setpoint = [VelocityTarget((1.0, 0.0, 0.0))]  # level: no takeoff from the ground

    def stream() -> None:  # a client streams its latest setpoint; OFFBOARD needs them to keep coming
        assert vehicle.set_velocity_target(setpoint[0])

    loop.run_s(2.0)  # GPS fix, home
    stream()
    assert vehicle.handle_command(command(M.MAV_CMD_DO_SET_MODE, 1, 6)) is CommandResult.ACCEPTED
    assert vehicle.handle_command(command(M.MAV_CMD_COMPONENT_ARM_DISARM, 1)) is CommandResult.ACCEPTED
    loop.run_s(1.0, stream)
    assert loop.ap.commander.armed and not loop.ap.commander.in_air and math.dist(sim.pos_ned, (0, 0, 0)) < 0.05
    setpoint[0] = VelocityTarget((0.0, 0.0, -1.5))
    loop.run_s(6.0, stream)
    assert loop.ap.commander.in_air and sim.vel_ned[2] == pytest.approx(-1.5, abs=0.1)
    setpoint[0] = VelocityTarget((2.0, -1.0, 0.0))
    loop.run_s(6.0, stream)
    assert sim.vel_ned == pytest.approx((2.0, -1.0, 0.0), abs=0.15)
    setpoint[0] = VelocityTarget((1.0, 0.0, 0.0), VelocityFrame.BODY, yaw_rate_rad_s=math.radians(30.0))
    yaw0 = loop.ap.state.yaw_rad
    loop.run_s(3.0, stream)
    turned = (loop.ap.state.yaw_rad - yaw0 + math.pi) % (2 * math.pi) - math.pi
    assert math.degrees(turned) == pytest.approx(90.0, abs=8.0)  # 30 deg/s for 3 s (the reference leads a bit)
    course = math.atan2(sim.vel_ned[1], sim.vel_ned[0])
    assert abs((course - loop.ap.state.yaw_rad + math.pi) % (2 * math.pi) - math.pi) < math.radians(20.0)  # forward
    setpoint[0] = VelocityTarget((0.0, 0.0, 1.0))
    loop.run_s(2.0, stream)
    horizontal = math.hypot(sim.vel_ned[0], sim.vel_ned[1])
    assert horizontal < 0.2 and sim.vel_ned[2] == pytest.approx(1.0, abs=0.15)
    loop.run_s(30.0, stream)
    assert "Landing detected" in loop.texts
    assert not loop.ap.commander.armed and sim.pos_ned[2] == pytest.approx(0.0, abs=0.1)
    assert loop.ap.commander.mode is FlightMode.OFFBOARD  # it stayed in OFFBOARD throughout
