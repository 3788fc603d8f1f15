"""OFFBOARD over MAVLink with pymavlink: SET_POSITION_TARGET_* decoded, PX4's streaming rule, setpoint-loss failsafe."""

from __future__ import annotations

import math
import os
import threading
import time

from autopilot_loop import InProcessLockstep, SimLoop
from conftest import free_udp_port
from gcs_fakes import FakeVehicle, ServerHarness

from autopilot.runner import Links, run_loop
from mavlink_bridge.gcs_server import GcsServer
from mavlink_bridge.gcs_types import AltitudeFrame, FlightMode, GlobalPositionTarget, LocalPositionTarget

os.environ.setdefault("MAVLINK20", "1")
from pymavlink import mavutil

mavutil.set_dialect("common")
M = mavutil.mavlink
#: type_mask: position (+ yaw) only: ignore velocity, acceleration and yaw rate.
POSITION_YAW = 0x09F8
POSITION_ONLY = POSITION_YAW | 0x400
VELOCITY_ONLY = 0x0DC7


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
        deadline = time.monotonic() + 5.0
        while server.stats.setpoints_used + server.stats.setpoints_dropped < 5 and time.monotonic() < deadline:
            time.sleep(0.02)
        with harness.locked():
            targets = list(vehicle.position_targets)
        assert targets[0] == LocalPositionTarget((5.0, -2.0, -8.0), 0.5)
        t1 = targets[1]
        assert isinstance(t1, GlobalPositionTarget) and t1.alt_frame is AltitudeFrame.ABOVE_HOME
        assert (t1.lat_deg, t1.lon_deg, t1.alt_m) == (47.3978, 8.5457, 12.0) and math.isnan(t1.yaw_rad)
        assert targets[2].alt_frame is AltitudeFrame.AMSL and targets[2].alt_m == 500.0
        assert len(targets) == 3
        assert (server.stats.setpoints_used, server.stats.setpoints_dropped) == (3, 2)  # velocity-only, body frame
    finally:
        conn.close()
        harness.stop()


def _command(conn, cmd: int, *params: float) -> int:  # type: ignore[no-untyped-def]
    full = [*params, *[0.0] * (7 - len(params))]
    conn.mav.command_long_send(1, 1, cmd, 0, *full)
    return _recv(conn, "COMMAND_ACK", 10.0, lambda m: m.command == cmd).result


def test_offboard_flight_needs_streaming_setpoints_and_holds_when_they_stop() -> None:
    loop = SimLoop("x500")
    ap = loop.ap
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
        streaming.clear()  # the offboard client goes silent: COM_OF_LOSS_T later, COM_OBL_ACT = hold
        _recv(conn, "STATUSTEXT", 30.0, lambda m: "offboard setpoints lost" in m.text)
        hold = FlightMode.AUTO_LOITER
        _recv(conn, "HEARTBEAT", 10.0, lambda m: m.custom_mode == hold.value)
        assert _command(conn, M.MAV_CMD_DO_SET_MODE, 1, 6) == M.MAV_RESULT_DENIED  # stale setpoints: not again
    finally:
        stop.set()
        runner.join(30.0)
        sender.join(5.0)
        conn.close()
        server.close()
    assert ap.commander.armed and ap.commander.in_air
    assert math.dist(loop.sim.pos_ned, (6.0, 0.0, -8.0)) < 1.5  # held near the last setpoint
