"""The mission protocol over a link that duplicates and reorders datagrams (issue 22 item 7, SPEC §8, §10).

A late copy of the previous transfer's MISSION_ACK, a stale MISSION_REQUEST or a duplicated item must not end or
corrupt the transfer under way: only MAV_MISSION_OPERATION_CANCELLED cancels an upload, an item that arrives outside
a transfer is answered with an error ACK (so the GCS restarts instead of resending it unanswered), and the GCS takes
an ACK only as the answer to the transfer it belongs to.
"""

from __future__ import annotations

import os
import threading
import time

import pytest
from conftest import free_udp_port
from gcs_fakes import FakeVehicle, ServerHarness, waypoint

from mavlink_bridge.contract.vehicle_api import MissionResult, MissionType
from mavlink_bridge.gcs_client.client import GcsClient
from mavlink_bridge.gcs_client.errors import MissionDownloadError, MissionUploadError
from mavlink_bridge.gcs_server.server import GcsServer
from mavlink_bridge.wire.lossy import LossProfile, LossyUdpProxy
from mavlink_bridge.wire.mission_items import item_from_msg

os.environ.setdefault("MAVLINK20", "1")
from pymavlink import mavutil

mavutil.set_dialect("common")

ROUNDS = 5
ITEMS = 100


def _route(n: int, round_no: int) -> list:
    """A different route each round, so a stale item of an earlier round would show in the comparison."""
    return [waypoint(i, 1000 * i + 7 * round_no, -700 * i, 10.0 + (i + round_no) % 7) for i in range(n)]


@pytest.mark.parametrize("seed", [1, 2])
def test_100_item_mission_round_trips_five_times_over_a_duplicating_reordering_link(seed: int) -> None:
    """10 % duplicated + 10 % reordered each way (no drops, the product's default timeouts): every round's upload is
    accepted, the vehicle holds exactly that mission, and the download equals it."""
    server_port = free_udp_port()
    vehicle = FakeVehicle()
    harness = ServerHarness(GcsServer(f"udpin:127.0.0.1:{server_port}", vehicle), vehicle)
    profile = LossProfile(duplicate_p=0.10, reorder_p=0.10, seed=seed)
    try:
        with LossyUdpProxy(("127.0.0.1", server_port), profile) as proxy:
            host, port = proxy.listen_address
            with GcsClient(f"udpout:{host}:{port}", timeout_s=10.0) as client:
                client.wait_heartbeat(5.0)
                for round_no in range(ROUNDS):
                    route = _route(ITEMS, round_no)
                    started = time.monotonic()
                    client.upload_mission(route)
                    assert vehicle.missions[MissionType.MISSION] == route, f"round {round_no}"
                    assert client.download_mission() == route, f"round {round_no}"
                    assert time.monotonic() - started < 30.0, f"round {round_no} needed retries to the limit"
            stats = proxy.stats
        assert stats.duplicated > 100 and stats.reordered > 100  # the link really was impaired
        assert harness.server.stats.mission_uploads_failed == 0
        assert vehicle.replace_calls == ROUNDS  # one complete list per round, never a partial one
    finally:
        harness.stop()


def _raw(harness: ServerHarness, source_system: int):
    return mavutil.mavlink_connection(f"udpout:127.0.0.1:{harness.server.local_port}", source_system=source_system)


def _send_item(raw, seq: int, item) -> None:
    lat_e7, lon_e7 = round(item.x_lat_deg * 1e7), round(item.y_lon_deg * 1e7)
    raw.mav.mission_item_int_send(1, 1, seq, item.frame, item.command, 0, 1, 0, 1, 0, 0, lat_e7, lon_e7, item.z_alt_m)


def _upload_raw(raw, route: list, *, stray_ack_at: int = -1) -> object:
    """Upload ``route`` from a raw connection, answering every request; at request ``stray_ack_at`` first send a
    late copy of a download's MISSION_ACK(ACCEPTED). Returns the vehicle's final MISSION_ACK (or None)."""
    raw.mav.mission_count_send(1, 1, len(route), 0)
    deadline = time.monotonic() + 10.0
    while time.monotonic() < deadline:
        msg = raw.recv_match(type=["MISSION_REQUEST_INT", "MISSION_ACK"], blocking=True, timeout=0.5)
        if msg is None:
            continue
        if msg.get_type() == "MISSION_ACK":
            return msg
        if msg.seq == stray_ack_at:
            raw.mav.mission_ack_send(1, 1, int(MissionResult.ACCEPTED), 0)
            stray_ack_at = -1
        _send_item(raw, msg.seq, route[msg.seq])
    return None


def test_late_ack_of_a_download_does_not_cancel_the_next_upload(link_pair) -> None:
    """A copy of the GCS's last download ACK(ACCEPTED) arrives mid-upload: the upload goes on to the end."""
    harness, _client = link_pair
    raw = _raw(harness, 250)
    route = _route(10, 1)
    try:
        ack = _upload_raw(raw, route, stray_ack_at=2)
    finally:
        raw.close()
    assert ack is not None and ack.type == MissionResult.ACCEPTED
    assert harness.server.stats.mission_uploads_failed == 0
    assert harness.vehicle.missions[MissionType.MISSION] == route


def test_cancel_ack_still_cancels(link_pair) -> None:
    harness, client = link_pair
    old = _route(3, 0)
    client.upload_mission(old)
    raw = _raw(harness, 250)
    try:
        raw.mav.mission_count_send(1, 1, 20, 0)
        assert raw.recv_match(type="MISSION_REQUEST_INT", blocking=True, timeout=3.0) is not None
        raw.mav.mission_ack_send(1, 1, int(MissionResult.OPERATION_CANCELLED), 0)
        time.sleep(0.3)
    finally:
        raw.close()
    assert harness.server.stats.mission_uploads_failed == 1
    assert harness.vehicle.missions[MissionType.MISSION] == old


def test_item_outside_a_transfer_is_answered_with_an_error_ack(link_pair) -> None:
    """An item nobody asked for gets MISSION_ACK(ERROR), so the GCS restarts; a late copy of an item of the upload that
    just completed is not an error (nothing is answered) and the last one is answered with that upload's ACK again."""
    harness, _client = link_pair
    raw = _raw(harness, 250)
    route = _route(4, 0)
    try:
        assert _upload_raw(raw, route).type == MissionResult.ACCEPTED
        _send_item(raw, 1, route[1])  # a late duplicate
        assert raw.recv_match(type="MISSION_ACK", blocking=True, timeout=0.5) is None
        _send_item(raw, 3, route[3])  # the last item again: our ACK was lost
        ack = raw.recv_match(type="MISSION_ACK", blocking=True, timeout=3.0)
        assert ack is not None and ack.type == MissionResult.ACCEPTED
        _send_item(raw, 7, route[2])  # no transfer has an item 7
        ack = raw.recv_match(type="MISSION_ACK", blocking=True, timeout=3.0)
        assert ack is not None and ack.type == MissionResult.ERROR
    finally:
        raw.close()
    assert harness.vehicle.missions[MissionType.MISSION] == route


@pytest.fixture
def link_pair():
    """(harness, client) on loopback with the product's default transfer timeouts."""
    server_port, gcs_port = free_udp_port(), free_udp_port()
    vehicle = FakeVehicle()
    server = GcsServer(f"udpin:127.0.0.1:{server_port}", vehicle, default_target_url=f"udpout:127.0.0.1:{gcs_port}")
    harness = ServerHarness(server, vehicle)
    client = GcsClient(f"udpin:127.0.0.1:{gcs_port}", timeout_s=4.0, retry_s=0.1)
    client.wait_heartbeat(5.0)
    yield harness, client
    client.close()
    harness.stop()


class ScriptedVehicle:
    """A raw MAVLink vehicle in a thread for the GCS side: holds ``items``, answers downloads and uploads, and sends
    the extra MISSION_ACKs ``strays`` names before answering: {("request", seq) or ("item", seq): [results]}."""

    def __init__(
        self,
        gcs_port: int,
        items: list,
        strays: dict[tuple[str, int], list[MissionResult]],
        *,
        deaf_after: bool = False,
    ) -> None:
        self.items, self.strays = list(items), strays
        self.deaf_after = deaf_after  # after the scripted ACKs of an item, ignore every item (PX4 after a refusal)
        self.deaf = False
        self.counts_seen = 0
        self.raw = mavutil.mavlink_connection(f"udpout:127.0.0.1:{gcs_port}", source_system=1, source_component=1)
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)

    def __enter__(self) -> ScriptedVehicle:
        self._thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self._stop.set()
        self._thread.join(timeout=2.0)
        self.raw.close()

    def _strays(self, key: tuple[str, int]) -> bool:
        """Send the stray ACKs scripted for ``key`` (once); True if there were any."""
        results = self.strays.pop(key, [])
        for result in results:
            self.raw.mav.mission_ack_send(255, 0, int(result), 0)
        return bool(results)

    def _run(self) -> None:
        mav, upload, expected = self.raw.mav, [], 0
        next_heartbeat = 0.0
        while not self._stop.is_set():
            if time.monotonic() >= next_heartbeat:
                mav.heartbeat_send(2, 12, 0, 0, 3)
                next_heartbeat = time.monotonic() + 0.2
            msg = self.raw.recv_match(blocking=True, timeout=0.02)
            kind = msg.get_type() if msg is not None else ""
            if kind == "MISSION_REQUEST_LIST":
                mav.mission_count_send(255, 0, len(self.items), 0)
            elif kind == "MISSION_REQUEST_INT":
                self._strays(("request", msg.seq))
                it = self.items[msg.seq]
                lat_e7, lon_e7 = round(it.x_lat_deg * 1e7), round(it.y_lon_deg * 1e7)
                mav.mission_item_int_send(255, 0, msg.seq, it.frame, it.command, 0, 1, 0, 1, 0, 0, lat_e7, lon_e7,
                                          it.z_alt_m)  # fmt: skip
            elif kind == "MISSION_COUNT":
                self.counts_seen += 1
                upload, expected = [], msg.count
                mav.mission_request_int_send(255, 0, 0, 0)
            elif kind == "MISSION_ITEM_INT" and msg.seq == len(upload) < expected and not self.deaf:
                if self._strays(("item", msg.seq)):
                    self.deaf = self.deaf_after
                    continue  # scripted as "the vehicle forgot the upload" or refused it: no request follows
                upload.append(item_from_msg(msg))
                if len(upload) < expected:
                    mav.mission_request_int_send(255, 0, len(upload), 0)
                else:
                    self.items = upload
                    mav.mission_ack_send(255, 0, int(MissionResult.ACCEPTED), 0)


def _client(gcs_port: int) -> GcsClient:
    client = GcsClient(f"udpin:127.0.0.1:{gcs_port}", timeout_s=4.0, retry_s=0.1)
    client.wait_heartbeat(5.0)
    return client


def test_gcs_download_survives_a_stray_error_ack_and_believes_a_repeated_one() -> None:
    route = _route(6, 0)
    gcs_port = free_udp_port()
    with ScriptedVehicle(gcs_port, route, {("request", 2): [MissionResult.ERROR]}), _client(gcs_port) as client:
        assert client.download_mission() == route
    gcs_port = free_udp_port()
    twice = {("request", 2): [MissionResult.ERROR], ("request", 3): [MissionResult.INVALID_SEQUENCE] * 2}
    with (
        ScriptedVehicle(gcs_port, route, twice),
        _client(gcs_port) as client,
        pytest.raises(MissionDownloadError, match="item 3: INVALID_SEQUENCE"),
    ):
        client.download_mission()


def test_gcs_upload_restarts_when_the_vehicle_no_longer_knows_it() -> None:
    """The vehicle answers an item with ERROR twice (it timed out and has no transfer): the GCS sends the count again
    and the upload completes; a stray error ACK answered by the awaited request changes nothing."""
    route = _route(5, 0)
    gcs_port = free_udp_port()
    strays = {("item", 2): [MissionResult.ERROR], ("item", 3): [MissionResult.ERROR, MissionResult.ERROR]}
    with ScriptedVehicle(gcs_port, [], strays) as vehicle, _client(gcs_port) as client:
        client.upload_mission(route)
        assert vehicle.counts_seen == 2
        assert vehicle.items == route


def test_gcs_believes_an_error_ack_the_vehicle_does_not_follow_with_a_request() -> None:
    """PX4 answers a repeated last item after a refusal with silence: the refusal stands (not a timeout)."""
    route = _route(3, 0)
    gcs_port = free_udp_port()
    strays = {("item", 2): [MissionResult.INVALID_PARAM7]}
    with (
        ScriptedVehicle(gcs_port, [], strays, deaf_after=True) as vehicle,
        _client(gcs_port) as client,
        pytest.raises(MissionUploadError) as refused,
    ):
        client.upload_mission(route)
    assert refused.value.result is MissionResult.INVALID_PARAM7 and vehicle.counts_seen == 1
