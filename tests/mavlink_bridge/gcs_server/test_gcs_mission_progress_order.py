"""MISSION_ITEM_REACHED goes out before the MISSION_CURRENT that moves past it (MAVSDK progress never steps back)."""

from __future__ import annotations

import os
import socket
from dataclasses import replace

from conftest import free_udp_port
from gcs_fakes import FakeVehicle

from mavlink_bridge.gcs_server.server import GcsServer

os.environ.setdefault("MAVLINK20", "1")
from pymavlink import mavutil

mavutil.set_dialect("common")
M = mavutil.mavlink


def test_reached_precedes_the_current_item_that_follows_it() -> None:
    gcs_port = free_udp_port()
    gcs = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    gcs.bind(("127.0.0.1", gcs_port))
    gcs.settimeout(0.2)
    vehicle = FakeVehicle()
    server = GcsServer(f"udpin:127.0.0.1:{free_udp_port()}", vehicle, default_target_url=f"udpout:127.0.0.1:{gcs_port}")
    try:
        base = vehicle.snapshot(4000)
        server.publish(replace(base, mission_seq_current=0, mission_count=3, mission_reached=[]))
        server.publish(replace(base, time_us=8000, mission_seq_current=1, mission_count=3, mission_reached=[0]))
        parser = M.MAVLink(None)
        order: list[tuple[str, int]] = []
        while True:
            try:
                data = gcs.recv(65536)
            except TimeoutError:
                break
            for msg in parser.parse_buffer(data) or []:
                if msg.get_type() == "MISSION_ITEM_REACHED":
                    order.append(("reached", msg.seq))
                elif msg.get_type() == "MISSION_CURRENT":
                    order.append(("current", msg.seq))
        assert ("reached", 0) in order and ("current", 1) in order
        assert order.index(("reached", 0)) < order.index(("current", 1))
    finally:
        server.close()
        gcs.close()
