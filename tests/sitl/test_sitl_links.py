"""The real autopilot process: GCS and API links serve the same surface, both polled and both with telemetry;
``--signing-key``/``--require-signing`` reject an unsigned ARM on either link (SPEC §3, §10); the mission protocol
survives a GCS link that duplicates and reorders (issue 22)."""

from __future__ import annotations

from pathlib import Path

import pytest
from conftest import free_udp_port
from gcs_fakes import waypoint
from sitl_procs import logs, start_autopilot, start_sim, stop

from mavlink_bridge.contract.vehicle_api import CommandResult, FlightMode
from mavlink_bridge.gcs_client.client import GcsClient, GcsTimeoutError
from mavlink_bridge.wire.lossy import LossProfile, LossyUdpProxy
from mavlink_bridge.wire.signing import signing_key_from_text

pytestmark = [pytest.mark.sitl]

KEY_TEXT = "delivery-fleet-secret"
MAV_CMD_COMPONENT_ARM_DISARM = 400


def test_signed_gcs_and_api_links_of_the_real_process(tmp_path: Path) -> None:
    sim_port = free_udp_port()
    gcs, gcs_target, api, api_target = (free_udp_port() for _ in range(4))
    sim = start_sim(tmp_path, sim_port, "--speed", "4", "--duration-s", "600")
    ap = start_autopilot(
        tmp_path,
        sim_port,
        None,
        "--gcs", f"udpin:127.0.0.1:{gcs}", "--gcs-target", f"udpout:127.0.0.1:{gcs_target}",
        "--api", f"udpin:127.0.0.1:{api}", "--api-target", f"udpout:127.0.0.1:{api_target}",
        "--signing-key", KEY_TEXT, "--require-signing", "--connect-timeout-s", "120",
    )  # fmt: skip
    key = signing_key_from_text(KEY_TEXT)
    clients: list[GcsClient] = []
    try:
        for port in (gcs_target, api_target):  # unsigned: telemetry is readable, the ARM is dropped unanswered
            unsigned = GcsClient(f"udpin:127.0.0.1:{port}", timeout_s=1.0, retry_s=0.2)
            clients.append(unsigned)
            unsigned.wait_until(lambda s: s.gps_fix_type >= 3, 120.0)
            with pytest.raises(GcsTimeoutError):
                unsigned.command(MAV_CMD_COMPONENT_ARM_DISARM, 1.0)
        while clients:  # a UDP port has one owner (no address reuse): free them for the signed clients
            clients.pop().close()
        gcs_client = GcsClient(f"udpin:127.0.0.1:{gcs_target}", signing_key=key, timeout_s=5.0, retry_s=0.2)
        api_client = GcsClient(f"udpin:127.0.0.1:{api_target}", signing_key=key, timeout_s=5.0, retry_s=0.2)
        clients += [gcs_client, api_client]
        for client in (gcs_client, api_client):  # both links are polled and stream telemetry
            status = client.wait_until(lambda s: s.pos_ned_m is not None and s.sim_time_s is not None, 30.0)
            assert not status.armed, logs(tmp_path)  # nothing unsigned was executed
            assert client.get_param("MIS_TAKEOFF_ALT") == 10.0
        assert api_client.set_param("MIS_TAKEOFF_ALT", 6.0) == 6.0  # the API link changes what the GCS link sees
        assert gcs_client.get_param("MIS_TAKEOFF_ALT") == 6.0
        assert api_client.command(MAV_CMD_COMPONENT_ARM_DISARM, 1.0) is CommandResult.ACCEPTED
        gcs_client.wait_until(lambda s: s.armed, 10.0)
        gcs_client.takeoff(float("nan"))
        api_client.wait_until(lambda s: s.mode is FlightMode.AUTO_TAKEOFF, 10.0)
        alt = gcs_client.wait_until(lambda s: s.alt_rel_m is not None and s.alt_rel_m > 5.0, 60.0).alt_rel_m
        assert alt is not None and alt < 7.0  # MIS_TAKEOFF_ALT set over the API link
    finally:
        for client in clients:
            client.close()
        stop(ap)
        stop(sim)


def test_mission_round_trips_of_the_real_process_over_a_duplicating_reordering_gcs_link(tmp_path: Path) -> None:
    """Issue 22 item 7 against the autopilot process (its simulator not started: uploads need no fix): a 100-item
    mission uploaded and downloaded five times through a relay that duplicates 10 % and reorders 10 % of the
    datagrams each way; every round accepted and identical."""
    gcs, gcs_target = free_udp_port(), free_udp_port()
    ap = start_autopilot(
        tmp_path, free_udp_port(), None, "--gcs", f"udpin:127.0.0.1:{gcs}",
        "--gcs-target", f"udpout:127.0.0.1:{gcs_target}", "--connect-timeout-s", "120",
    )  # fmt: skip
    profile = LossProfile(duplicate_p=0.10, reorder_p=0.10, seed=4)
    try:
        with LossyUdpProxy(("127.0.0.1", gcs), profile) as proxy:
            host, port = proxy.listen_address
            with GcsClient(f"udpout:{host}:{port}", timeout_s=10.0) as client:
                client.wait_heartbeat(120.0)
                for round_no in range(5):
                    route = [waypoint(i, 1000 * i + round_no, -700 * i, 10.0 + (i + round_no) % 7) for i in range(100)]
                    client.upload_mission(route)
                    assert client.download_mission() == route, f"round {round_no}"
            assert proxy.stats.duplicated > 100 and proxy.stats.reordered > 100
    finally:
        rc = stop(ap)
    assert rc == 0, logs(tmp_path)
