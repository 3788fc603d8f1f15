"""Mission protocol over loopback: round trips (MISSION, FENCE), 600 items, refusals and failures keep the old mission,
legacy float items, a lossy link, clear and set-current."""

from __future__ import annotations

import math
import os
import threading
import time
from dataclasses import replace

import pytest
from conftest import free_udp_port
from gcs_fakes import FakeVehicle, ServerHarness, fence_circle, waypoint

from mavlink_bridge.contract.vehicle_api import MissionResult, MissionType
from mavlink_bridge.gcs_client.client import GcsClient, MissionUploadError
from mavlink_bridge.gcs_server.missions import TransferTimeouts
from mavlink_bridge.gcs_server.server import GcsServer
from mavlink_bridge.wire.lossy import LossProfile, LossyUdpProxy

os.environ.setdefault("MAVLINK20", "1")
from pymavlink import mavutil

mavutil.set_dialect("common")


@pytest.fixture
def link():
    """(harness, client): a GcsServer over a FakeVehicle and a GcsClient, both on loopback."""
    server_port, gcs_port = free_udp_port(), free_udp_port()
    vehicle = FakeVehicle()
    server = GcsServer(
        f"udpin:127.0.0.1:{server_port}",
        vehicle,
        default_target_url=f"udpout:127.0.0.1:{gcs_port}",
        mission_timeouts=TransferTimeouts(retry_s=0.1, max_retries=4),
    )
    harness = ServerHarness(server, vehicle)
    client = GcsClient(f"udpin:127.0.0.1:{gcs_port}", timeout_s=4.0, retry_s=0.1)
    client.wait_heartbeat(5.0)
    yield harness, client
    client.close()
    harness.stop()


def _route(n: int) -> list:
    return [waypoint(i, 1000 * i, -700 * i, 10.0 + (i % 7)) for i in range(n)]


def test_mission_and_fence_round_trip_equal(link) -> None:
    harness, client = link
    mission, fence = _route(12), [fence_circle(0, 8.0), fence_circle(1, 12.5)]
    client.upload_mission(mission)
    client.upload_mission(fence, MissionType.FENCE)
    assert client.download_mission() == mission
    assert client.download_mission(MissionType.FENCE) == [replace(f, mission_type=MissionType.FENCE) for f in fence]
    assert harness.vehicle.missions[MissionType.MISSION] == mission


def test_600_item_upload_and_download(link) -> None:
    harness, client = link
    route = _route(600)
    client.upload_mission(route)
    assert harness.vehicle.missions[MissionType.MISSION] == route
    assert harness.vehicle.replace_calls == 1  # one complete list, never partial ones
    assert client.download_mission() == route


@pytest.mark.parametrize(
    ("bad", "result", "reason"),
    [
        (lambda it: replace(it, x_lat_deg=95.0), MissionResult.INVALID_PARAM5_X, "latitude 95 out of range"),
        (lambda it: replace(it, command=31999), MissionResult.UNSUPPORTED, "command 31999 not supported"),
        (lambda it: replace(it, z_alt_m=math.nan), MissionResult.INVALID_PARAM7, "altitude is not a number"),
    ],
)
def test_invalid_item_is_refused_and_old_mission_kept(link, bad, result, reason) -> None:
    harness, client = link
    old = _route(5)
    client.upload_mission(old)
    new = _route(8)
    new[6] = bad(new[6])
    with pytest.raises(MissionUploadError) as err:
        client.upload_mission(new)
    assert err.value.result is result
    assert reason in err.value.text and "item 6" in err.value.text  # the long STATUSTEXT arrives whole
    assert harness.vehicle.missions[MissionType.MISSION] == old
    assert client.download_mission() == old


def test_client_that_stops_mid_upload_times_out_and_old_mission_stays(link) -> None:
    harness, client = link
    old = _route(4)
    client.upload_mission(old)
    server_port = harness.server.local_port
    raw = mavutil.mavlink_connection(f"udpout:127.0.0.1:{server_port}", source_system=250)
    try:
        raw.mav.mission_count_send(1, 1, 10, 0)
        answered = 0
        deadline = time.monotonic() + 5.0
        ack = None
        while time.monotonic() < deadline:
            msg = raw.recv_match(type=["MISSION_REQUEST_INT", "MISSION_ACK"], blocking=True, timeout=0.5)
            if msg is None:
                continue
            if msg.get_type() == "MISSION_ACK":
                ack = msg
                break
            if answered < 3 and msg.seq == answered:
                item = _route(10)[msg.seq]
                raw.mav.mission_item_int_send(
                    1, 1, msg.seq, 6, 16, 0, 1, 0, 0, 0, 0, round(item.x_lat_deg * 1e7), round(item.y_lon_deg * 1e7), 10
                )
                answered += 1
        assert ack is not None, "the vehicle never closed the abandoned transfer"
        assert ack.type == MissionResult.ERROR
    finally:
        raw.close()
    assert harness.server.stats.mission_uploads_failed == 1
    assert harness.vehicle.missions[MissionType.MISSION] == old
    assert client.download_mission() == old


def test_client_cancel_keeps_old_mission(link) -> None:
    harness, client = link
    old = _route(3)
    client.upload_mission(old)
    client.mav.mission_count_send(1, 1, 20, 0)
    client.pump(0.2)
    client.mav.mission_ack_send(1, 1, int(MissionResult.OPERATION_CANCELLED), 0)
    client.pump(0.2)
    assert harness.server.stats.mission_uploads_failed == 1
    assert harness.vehicle.missions[MissionType.MISSION] == old


def test_legacy_float_mission_item_upload(link) -> None:
    """A MAVProxy-style client answers with float MISSION_ITEM; the vehicle switches to MISSION_REQUEST."""
    harness, _client = link
    raw = mavutil.mavlink_connection(f"udpout:127.0.0.1:{harness.server.local_port}", source_system=251)
    route = _route(4)
    kinds = set()
    try:
        raw.mav.mission_count_send(1, 1, len(route), 0)
        ack = None
        deadline = time.monotonic() + 5.0
        while ack is None and time.monotonic() < deadline:
            msg = raw.recv_match(
                type=["MISSION_REQUEST_INT", "MISSION_REQUEST", "MISSION_ACK"], blocking=True, timeout=0.5
            )
            if msg is None:
                continue
            if msg.get_type() == "MISSION_ACK":
                ack = msg
                continue
            kinds.add(msg.get_type())
            it = route[msg.seq]
            raw.mav.mission_item_send(1, 1, msg.seq, 6, 16, 0, 1, 0, 1, 0, 0, it.x_lat_deg, it.y_lon_deg, it.z_alt_m)
    finally:
        raw.close()
    assert ack is not None and ack.type == MissionResult.ACCEPTED
    assert "MISSION_REQUEST" in kinds
    stored = harness.vehicle.missions[MissionType.MISSION]
    assert [round(s.x_lat_deg, 5) for s in stored] == [round(r.x_lat_deg, 5) for r in route]


def test_upload_over_lossy_link() -> None:
    server_port = free_udp_port()
    vehicle = FakeVehicle()
    server = GcsServer(
        f"udpin:127.0.0.1:{server_port}", vehicle, mission_timeouts=TransferTimeouts(retry_s=0.1, max_retries=20)
    )
    harness = ServerHarness(server, vehicle)
    profile = LossProfile(drop_p=0.1, duplicate_p=0.05, reorder_p=0.05, seed=3)
    with LossyUdpProxy(("127.0.0.1", server_port), profile) as proxy:
        host, port = proxy.listen_address
        client = GcsClient(f"udpout:{host}:{port}", timeout_s=6.0, retry_s=0.1)
        try:
            client.wait_heartbeat(5.0)
            route = _route(60)
            client.upload_mission(route)
            assert vehicle.missions[MissionType.MISSION] == route
            assert client.download_mission() == route
            assert proxy.stats.dropped > 0 and proxy.stats.duplicated > 0
        finally:
            client.close()
    harness.stop()


def test_clear_and_set_current(link) -> None:
    harness, client = link
    client.upload_mission(_route(6))
    client.set_current_item(3)
    assert harness.vehicle.current_seq == 3
    client.wait_until(lambda s: s.mission_seq_current == 3 and s.mission_count == 6, 3.0)
    client.clear_mission()
    assert harness.vehicle.missions[MissionType.MISSION] == []
    assert client.download_mission() == []


def test_items_reached_reach_the_client(link) -> None:
    harness, client = link
    with harness.locked():
        harness.vehicle.pending_reached.extend([0, 1, 2])
    status = client.wait_until(lambda s: len(s.items_reached) == 3, 3.0)
    assert status.items_reached == (0, 1, 2)


def test_too_many_items_is_refused_with_no_space() -> None:
    server_port, gcs_port = free_udp_port(), free_udp_port()
    vehicle = FakeVehicle()
    server = GcsServer(
        f"udpin:127.0.0.1:{server_port}",
        vehicle,
        default_target_url=f"udpout:127.0.0.1:{gcs_port}",
        max_mission_items=50,
    )
    harness = ServerHarness(server, vehicle)
    client = GcsClient(f"udpin:127.0.0.1:{gcs_port}", timeout_s=3.0, retry_s=0.1)
    try:
        client.wait_heartbeat(5.0)
        client.upload_mission(_route(50))
        with pytest.raises(MissionUploadError) as err:
            client.upload_mission(_route(51))
        assert err.value.result is MissionResult.NO_SPACE and "limit 50" in err.value.text
        assert vehicle.missions[MissionType.MISSION] == _route(50)
    finally:
        client.close()
        harness.stop()


def test_late_accepted_ack_of_an_upload_does_not_abort_a_download(link) -> None:
    """A duplicated or reordered MISSION_ACK(ACCEPTED) of the previous upload may arrive mid-download."""
    harness, client = link
    route = _route(20)
    client.upload_mission(route)
    stop = threading.Event()

    def inject() -> None:  # the vehicle's own link repeats the upload's ACK, as a duplicating link would
        while not stop.is_set():
            with harness.locked():
                harness.server.mav.mission_ack_send(255, 0, int(MissionResult.ACCEPTED), int(MissionType.MISSION))
            time.sleep(0.002)

    thread = threading.Thread(target=inject, daemon=True)
    thread.start()
    try:
        assert client.download_mission() == route
    finally:
        stop.set()
        thread.join()
