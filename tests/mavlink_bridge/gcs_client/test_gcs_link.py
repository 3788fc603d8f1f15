"""GCS link over loopback: PX4 identity and modes, honest command acks, parameters, stream rates,
REQUEST_MESSAGE, signing, and hostile datagrams."""

from __future__ import annotations

import os
import random
import socket
import time

import pytest
from conftest import free_udp_port
from gcs_fakes import HOME_LAT_DEG, MAV_CMD_COMPONENT_ARM_DISARM, FakeVehicle, ServerHarness

from autopilot.parameters.store import ParamSpec, ParamStore
from mavlink_bridge.contract.vehicle_api import CommandResult, FlightMode, LandedState
from mavlink_bridge.gcs_client.client import (
    CommandFailedError,
    GcsClient,
    GcsTimeoutError,
    ParamNotFoundError,
    ParamRefusedError,
)
from mavlink_bridge.gcs_server.server import GcsServer
from mavlink_bridge.wire.lossy import LossProfile, LossyUdpProxy
from mavlink_bridge.wire.signing import signing_key_from_text

os.environ.setdefault("MAVLINK20", "1")
from pymavlink import mavutil

mavutil.set_dialect("common")
M = mavutil.mavlink


def _start(**server_kwargs) -> tuple[ServerHarness, int]:
    server_port, gcs_port = free_udp_port(), free_udp_port()
    vehicle = FakeVehicle()
    server = GcsServer(
        f"udpin:127.0.0.1:{server_port}", vehicle, default_target_url=f"udpout:127.0.0.1:{gcs_port}", **server_kwargs
    )
    return ServerHarness(server, vehicle), gcs_port


@pytest.fixture
def link():
    harness, gcs_port = _start()
    client = GcsClient(f"udpin:127.0.0.1:{gcs_port}", timeout_s=3.0, retry_s=0.1)
    client.wait_heartbeat(5.0)
    yield harness, client
    client.close()
    harness.stop()


@pytest.fixture
def raw():
    """A plain pymavlink GCS talking to a fresh server (interoperability with an unmodified client)."""
    harness, _ = _start()
    conn = mavutil.mavlink_connection(f"udpout:127.0.0.1:{harness.server.local_port}", source_system=255)
    conn.mav.heartbeat_send(M.MAV_TYPE_GCS, M.MAV_AUTOPILOT_INVALID, 0, 0, 0)
    yield harness, conn
    conn.close()
    harness.stop()


def _recv(conn, kind: str, timeout_s: float = 3.0, **fields):
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        msg = conn.recv_match(type=kind, blocking=True, timeout=0.2)
        if msg is not None and all(getattr(msg, k) == v for k, v in fields.items()):
            return msg
    raise AssertionError(f"no {kind} {fields} within {timeout_s} s")


def test_heartbeat_is_a_px4_quadrotor_and_modes_decode_with_pymavlink(raw) -> None:
    _harness, conn = raw
    hb = _recv(conn, "HEARTBEAT")
    assert (hb.type, hb.autopilot) == (M.MAV_TYPE_QUADROTOR, M.MAV_AUTOPILOT_PX4)
    assert hb.base_mode & M.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED
    assert not hb.base_mode & M.MAV_MODE_FLAG_SAFETY_ARMED
    assert mavutil.mode_string_v10(hb) == "LOITER"
    names = {}
    for mode in (FlightMode.AUTO_MISSION, FlightMode.AUTO_RTL, FlightMode.AUTO_LAND, FlightMode.POSCTL):
        conn.mav.command_long_send(1, 1, M.MAV_CMD_DO_SET_MODE, 0, 1, mode.px4_main_mode, mode.px4_sub_mode, 0, 0, 0, 0)
        assert _recv(conn, "COMMAND_ACK", command=M.MAV_CMD_DO_SET_MODE).result == M.MAV_RESULT_ACCEPTED
        hb = _recv(conn, "HEARTBEAT", custom_mode=int(mode))
        names[mode] = mavutil.mode_string_v10(hb)
    assert names == {
        FlightMode.AUTO_MISSION: "MISSION",
        FlightMode.AUTO_RTL: "RTL",
        FlightMode.AUTO_LAND: "LAND",
        FlightMode.POSCTL: "POSCTL",
    }


def test_telemetry_streams_decode_to_the_snapshot(link) -> None:
    _harness, client = link
    status = client.wait_until(lambda s: s.pos_ned_m is not None and s.home is not None and s.lat_deg, 3.0)
    assert status.pos_ned_m == pytest.approx((1.0, 2.0, -3.0))
    assert status.alt_rel_m == pytest.approx(3.0)
    assert status.home.alt_amsl_m == pytest.approx(488.0)
    assert status.landed_state is LandedState.ON_GROUND
    assert status.battery_remaining_pct == 87.0
    assert status.sim_time_s is not None and status.sim_time_s > 0.0


def test_commands_are_acked_honestly(link) -> None:
    harness, client = link
    client.arm()
    client.wait_until(lambda s: s.armed and s.landed_state is LandedState.IN_AIR, 3.0)
    client.set_mode(FlightMode.AUTO_RTL)
    client.wait_until(lambda s: s.mode is FlightMode.AUTO_RTL, 3.0)
    client.disarm()
    with harness.locked():
        harness.vehicle.arming_refused = True
    with pytest.raises(CommandFailedError) as err:
        client.arm()
    assert err.value.result is CommandResult.DENIED
    assert client.command(31010, 1.0) is CommandResult.UNSUPPORTED  # MAV_CMD_USER_1: nobody implements it
    with pytest.raises(CommandFailedError):
        client.start_mission()  # no mission: the fake vehicle denies


def test_retried_command_is_answered_once_and_consistently(raw) -> None:
    harness, conn = raw
    for confirmation in (0, 1, 2):
        conn.mav.command_long_send(1, 1, MAV_CMD_COMPONENT_ARM_DISARM, confirmation, 1, 0, 0, 0, 0, 0, 0)
        ack = _recv(conn, "COMMAND_ACK", command=MAV_CMD_COMPONENT_ARM_DISARM)
        assert ack.result == M.MAV_RESULT_ACCEPTED
        assert (ack.target_system, ack.target_component) == (255, 0)
    assert harness.vehicle.command_calls[MAV_CMD_COMPONENT_ARM_DISARM] == 1
    assert harness.server.stats.command_duplicates == 2


def test_command_int_reaches_the_vehicle_in_degrees(raw) -> None:
    harness, conn = raw
    conn.mav.command_int_send(1, 1, 6, 192, 0, 0, -1, 0, 0, 0, 473977419, 85455938, 20.0)  # DO_REPOSITION
    assert _recv(conn, "COMMAND_ACK", command=192).result == M.MAV_RESULT_UNSUPPORTED
    request = harness.vehicle.requests[-1]
    assert request.is_int and request.frame == 6
    assert request.params[4:] == pytest.approx((47.3977419, 8.5455938, 20.0))


def test_params_get_set_list_and_refusal_keeps_old_value(link) -> None:
    harness, client = link
    assert client.list_params() == {"MC_ROLL_P": 8.0, "MPC_XY_VEL_MAX": 5.0, "NAV_ACC_RAD": 1.0}
    assert client.get_param("MC_ROLL_P") == 8.0
    assert client.set_param("MC_ROLL_P", 6.5) == 6.5
    assert harness.vehicle.params.get("MC_ROLL_P") == 6.5
    with pytest.raises(ParamRefusedError) as err:
        client.set_param("MPC_XY_VEL_MAX", 99.0)
    assert err.value.value_in_force == 5.0
    assert "outside the allowed range" in err.value.reason
    assert client.get_param("MPC_XY_VEL_MAX") == 5.0
    with pytest.raises(ParamNotFoundError):
        client.get_param("NO_SUCH_PARAM")


def _attitude_rate_hz(conn, n: int = 12) -> float:
    """ATTITUDE messages per second of SIM time (from time_boot_ms), over ``n`` messages."""
    times = []
    deadline = time.monotonic() + 5.0
    while len(times) < n and time.monotonic() < deadline:
        msg = conn.recv_match(type="ATTITUDE", blocking=True, timeout=0.2)
        if msg is not None:
            times.append(msg.time_boot_ms)
    assert len(times) == n
    return (n - 1) / ((times[-1] - times[0]) / 1000.0)


def test_set_message_interval_changes_a_stream_rate() -> None:
    harness, _ = _start(max_stream_speedup=None)  # rates in pure sim time, however fast the harness runs
    conn = mavutil.mavlink_connection(f"udpout:127.0.0.1:{harness.server.local_port}", source_system=255)
    conn.mav.heartbeat_send(M.MAV_TYPE_GCS, M.MAV_AUTOPILOT_INVALID, 0, 0, 0)
    try:
        _check_rates(conn)
    finally:
        conn.close()
        harness.stop()


def test_stream_rate_is_capped_in_wall_time() -> None:
    harness, _ = _start(max_stream_speedup=1.0)
    harness.sim_step_us = 40_000  # sim runs ~40x faster than real time
    conn = mavutil.mavlink_connection(f"udpout:127.0.0.1:{harness.server.local_port}", source_system=255)
    conn.mav.heartbeat_send(M.MAV_TYPE_GCS, M.MAV_AUTOPILOT_INVALID, 0, 0, 0)
    try:
        _recv(conn, "ATTITUDE")
        t0, n = time.monotonic(), 0
        while time.monotonic() - t0 < 0.5:
            n += conn.recv_match(type="ATTITUDE", blocking=True, timeout=0.1) is not None
        assert 10 <= n <= 40  # 50 Hz in wall time at most (25 in 0.5 s, with slack), not 40 x 50 Hz
    finally:
        conn.close()
        harness.stop()


def _check_rates(conn) -> None:
    _recv(conn, "ATTITUDE")
    assert _attitude_rate_hz(conn) == pytest.approx(50.0, rel=0.1)
    conn.mav.command_long_send(
        1, 1, M.MAV_CMD_SET_MESSAGE_INTERVAL, 0, M.MAVLINK_MSG_ID_ATTITUDE, 200_000, 0, 0, 0, 0, 0
    )
    assert _recv(conn, "COMMAND_ACK", command=M.MAV_CMD_SET_MESSAGE_INTERVAL).result == M.MAV_RESULT_ACCEPTED
    conn.recv_match(type="ATTITUDE", blocking=True, timeout=0.5)  # skip one sent before the change
    assert _attitude_rate_hz(conn, 6) == pytest.approx(5.0, rel=0.1)
    conn.mav.command_long_send(1, 1, M.MAV_CMD_SET_MESSAGE_INTERVAL, 0, 424242, 200_000, 0, 0, 0, 0, 0)
    assert _recv(conn, "COMMAND_ACK", command=M.MAV_CMD_SET_MESSAGE_INTERVAL).result == M.MAV_RESULT_DENIED


def test_request_message_autopilot_version(raw) -> None:
    _harness, conn = raw
    conn.mav.command_long_send(1, 1, M.MAV_CMD_REQUEST_MESSAGE, 0, M.MAVLINK_MSG_ID_AUTOPILOT_VERSION, 0, 0, 0, 0, 0, 0)
    assert _recv(conn, "COMMAND_ACK", command=M.MAV_CMD_REQUEST_MESSAGE).result == M.MAV_RESULT_ACCEPTED
    version = _recv(conn, "AUTOPILOT_VERSION")
    needed = (
        M.MAV_PROTOCOL_CAPABILITY_MISSION_INT
        | M.MAV_PROTOCOL_CAPABILITY_MISSION_FENCE
        | M.MAV_PROTOCOL_CAPABILITY_PARAM_FLOAT
        | M.MAV_PROTOCOL_CAPABILITY_COMMAND_INT
        | M.MAV_PROTOCOL_CAPABILITY_MAVLINK2
    )
    assert version.capabilities & needed == needed
    # Until the server has its first telemetry snapshot it answers TEMPORARILY_REJECTED (nothing to send yet);
    # a GCS asks again, as here (on a loaded machine the first snapshot can come after the first request).
    deadline = time.monotonic() + 5.0
    while True:
        conn.mav.command_long_send(1, 1, M.MAV_CMD_REQUEST_MESSAGE, 0, M.MAVLINK_MSG_ID_HOME_POSITION, 0, 0, 0, 0, 0, 0)
        result = _recv(conn, "COMMAND_ACK", command=M.MAV_CMD_REQUEST_MESSAGE).result
        if result != M.MAV_RESULT_TEMPORARILY_REJECTED or time.monotonic() > deadline:
            break
        time.sleep(0.1)
    assert result == M.MAV_RESULT_ACCEPTED
    assert _recv(conn, "HOME_POSITION").latitude == 473977419


def test_signing_required_rejects_unsigned_and_wrongly_signed_commands() -> None:
    key = signing_key_from_text("delivery-fleet-secret")
    harness, gcs_port = _start(require_signing=True, signing_key=key)
    try:
        unsigned = GcsClient(f"udpin:127.0.0.1:{gcs_port}", timeout_s=0.6, retry_s=0.1)
        unsigned.wait_heartbeat(5.0)  # the vehicle's own (signed) telemetry is readable
        with pytest.raises(GcsTimeoutError):
            unsigned.command(MAV_CMD_COMPONENT_ARM_DISARM, 1.0)
        unsigned.close()
        wrong = GcsClient(
            f"udpin:127.0.0.1:{gcs_port}", signing_key=signing_key_from_text("guess"), timeout_s=0.6, retry_s=0.1
        )
        wrong.wait_heartbeat(5.0)
        with pytest.raises(GcsTimeoutError):
            wrong.command(MAV_CMD_COMPONENT_ARM_DISARM, 1.0)
        wrong.close()
        assert harness.vehicle.command_calls[MAV_CMD_COMPONENT_ARM_DISARM] == 0
        stats = harness.server.stats
        assert stats.rejected_unsigned > 0 and stats.rejected_bad_signature > 0
        signed = GcsClient(f"udpin:127.0.0.1:{gcs_port}", signing_key=key, timeout_s=3.0, retry_s=0.1)
        signed.wait_heartbeat(5.0)
        signed.arm()
        signed.close()
        assert harness.vehicle.command_calls[MAV_CMD_COMPONENT_ARM_DISARM] == 1
    finally:
        harness.stop()


def test_garbage_datagrams_never_crash_the_server(link) -> None:
    harness, client = link
    rng = random.Random(5)
    valid = M.MAVLink(None, 255, 190)
    packet = bytes(valid.command_long_encode(1, 1, 400, 0, 1, 0, 0, 0, 0, 0, 0).pack(valid))
    samples = [bytes(rng.getrandbits(8) for _ in range(rng.randint(0, 300))) for _ in range(300)]
    samples += [packet[:n] for n in range(len(packet))]  # every truncation
    samples += [packet[:-3] + bytes([packet[-3] ^ 0xFF]) + packet[-2:]]  # bad CRC
    samples += [b"\xfd" * 280, b"\xfe\xff" + b"\x00" * 300, bytes(65000)]
    for i in range(200):  # valid header, random payload bytes, correct length byte
        body = bytes(rng.getrandbits(8) for _ in range(rng.randint(0, 60)))
        samples.append(bytes([0xFD, len(body), 0, 0, i % 256, 1, 1, rng.randint(0, 255), 0, 0]) + body + b"\x00\x00")
    peer = harness.server.peer_address
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
        for data in samples:
            sock.sendto(data, ("127.0.0.1", harness.server.local_port))
            time.sleep(0.0002)
    client.pump(0.3)
    assert harness.server.peer_address == peer  # garbage does not hijack the reply address
    assert harness.server.stats.malformed > 300
    assert harness.server.stats.handler_errors == 0
    assert harness.vehicle.command_calls[MAV_CMD_COMPONENT_ARM_DISARM] == 0
    client.arm()  # still serving
    assert harness.error is None


def test_gcs_heartbeat_age_tracks_the_client(link) -> None:
    harness, client = link
    client.pump(1.2)
    assert harness.server.gcs_heartbeat_age_s < 1.5


def test_param_list_of_300_over_a_lossy_link() -> None:
    server_port = free_udp_port()
    vehicle = FakeVehicle()
    vehicle.params = ParamStore(ParamSpec(f"TEST_P{i:03d}", float(i), 0.0, 1000.0, "", "test") for i in range(300))
    harness = ServerHarness(GcsServer(f"udpin:127.0.0.1:{server_port}", vehicle), vehicle)
    profile = LossProfile(drop_p=0.1, duplicate_p=0.05, reorder_p=0.05, seed=11)
    try:
        with LossyUdpProxy(("127.0.0.1", server_port), profile) as proxy:
            host, port = proxy.listen_address
            client = GcsClient(f"udpout:{host}:{port}", timeout_s=3.0, retry_s=0.1)
            try:
                client.wait_heartbeat(5.0)
                params = client.list_params()
                assert params == {f"TEST_P{i:03d}": float(i) for i in range(300)}
                assert client.set_param("TEST_P123", 7.0) == 7.0
                assert proxy.stats.dropped > 0
            finally:
                client.close()
    finally:
        harness.stop()


def test_request_home_gets_home_position_at_once_when_its_stream_is_off() -> None:
    """HOME_POSITION streams at 0.5 Hz (in wall time at --speed max): a client asks for it, as QGroundControl does."""
    harness, gcs_port = _start()
    first = GcsClient(f"udpin:127.0.0.1:{gcs_port}", timeout_s=3.0, retry_s=0.1)
    first.wait_heartbeat(5.0)
    first.set_message_interval(M.MAVLINK_MSG_ID_HOME_POSITION, -1.0)  # its stream off
    first.close()
    client = GcsClient(f"udpin:127.0.0.1:{gcs_port}", timeout_s=3.0, retry_s=0.1)  # a client that never saw it
    try:
        client.wait_heartbeat(5.0)
        client.pump(0.3)
        assert client.telemetry().home is None
        client.request_home()
        home = client.telemetry().home
        assert home is not None and home.lat_deg == pytest.approx(HOME_LAT_DEG)
    finally:
        client.close()
        harness.stop()
