"""Monitor: a fake vehicle speaking standard MAVLink (pymavlink) -> monitor -> Rerun recording (issue 7)."""

from __future__ import annotations

import math
import socket
from pathlib import Path

import numpy as np
import pytest
from pymavlink.dialects.v20 import common as mavlink2

from autopilot.telemetry import entities as ent
from autopilot.telemetry.recording_reader import read_recording
from autopilot.telemetry.sinks import RerunSink, SinkKind, open_recording
from mavlink_bridge.gcs_client.telemetry_listener import StatusTextEvent, TelemetryListener, VehicleHeartbeat
from tools.monitor import TIMELINE, MonitorRecorder, main

PX4_AUTO_MISSION = (4 << 16) | (4 << 24)


class _FakeVehicle:
    """Sends standard MAVLink 2 from system 7 (an arbitrary vehicle, not our autopilot) over UDP."""

    def __init__(self, port: int) -> None:
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.addr = ("127.0.0.1", port)
        self.mav = mavlink2.MAVLink(None, srcSystem=7, srcComponent=1)

    def send(self, msg: object) -> None:
        self.sock.sendto(msg.pack(self.mav), self.addr)  # type: ignore[attr-defined]

    def close(self) -> None:
        self.sock.close()


def _flight(vehicle: _FakeVehicle, n: int) -> list[tuple[float, float, float]]:
    mav = vehicle.mav
    armed = mavlink2.MAV_MODE_FLAG_SAFETY_ARMED | mavlink2.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED
    vehicle.send(mav.heartbeat_encode(2, 12, armed, PX4_AUTO_MISSION, 4))  # quadrotor, PX4
    attitudes = []
    for k in range(n):
        t_ms = 1000 + 20 * k
        att = (0.1 * math.sin(k / 5), 0.05, 1.0 + 0.01 * k)
        attitudes.append(att)
        vehicle.send(mav.attitude_encode(t_ms, *att, 0.0, 0.0, 0.0))
        vehicle.send(mav.local_position_ned_encode(t_ms, 0.5 * k, 0.1 * k, -10.0, 1.0, 0.0, 0.0))
        vehicle.send(mav.global_position_int_encode(t_ms, 302635000, 1201233000, 22000, 10000, 0, 0, 0, 9000))
    vehicle.send(mav.mission_current_encode(2))
    vehicle.send(mav.mission_item_reached_encode(1))
    vehicle.send(mav.statustext_encode(6, b"Payload released"))
    return attitudes


def test_listener_decodes_and_survives_garbage(udp_port: int) -> None:
    port = udp_port
    with TelemetryListener(f"udpin:127.0.0.1:{port}") as listener:
        vehicle = _FakeVehicle(port)
        vehicle.sock.sendto(b"\xfd\x09garbage that is not mavlink", vehicle.addr)
        _flight(vehicle, 3)
        vehicle.close()
        events = []
        for _ in range(50):
            events += listener.poll(0.1)
            if any(isinstance(e, StatusTextEvent) for e in events):
                break
    hb = next(e for e in events if isinstance(e, VehicleHeartbeat))
    assert (hb.system_id, hb.armed, hb.mode) == (7, True, "MISSION")  # pymavlink names PX4 AUTO.MISSION "MISSION"
    assert [e.text for e in events if isinstance(e, StatusTextEvent)] == ["Payload released"]


def test_monitor_records_attitude_position_and_statustext(udp_port: int, tmp_path: Path) -> None:
    port = udp_port
    path = tmp_path / "monitor.rrd"
    listener = TelemetryListener(f"udpin:127.0.0.1:{port}")
    rec = open_recording(RerunSink(SinkKind.SAVE, str(path)))
    recorder = MonitorRecorder(rec)
    vehicle = _FakeVehicle(port)
    n = 40
    attitudes = _flight(vehicle, n)
    vehicle.close()
    for _ in range(100):  # bounded: stop as soon as the last message (the STATUSTEXT) has been logged
        for event in listener.poll(0.1):
            recorder.handle(event)
        if recorder.counts.get("StatusTextEvent"):
            break
    recorder.close()
    listener.close()
    r = read_recording(path, timeline=TIMELINE)
    att = r.scalars(ent.MON_ATT)
    np.testing.assert_allclose(att.values, np.degrees(attitudes), atol=1e-4)  # float32 on the wire
    np.testing.assert_array_equal(att.t_us, 1000 * (1000 + 20 * np.arange(n)))
    pos = r.scalars(ent.MON_POS).values
    np.testing.assert_allclose(pos[-1], [0.5 * (n - 1), 0.1 * (n - 1), -10.0], atol=1e-4)
    np.testing.assert_allclose(r.scalars(ent.MON_ALT).values[:, 0], 10.0)
    texts = [t for _, _, t in r.text_log()]
    assert "Payload released" in texts
    assert "sys 7: armed" in texts and "sys 7: mode MISSION" in texts
    assert "sys 7: mission item 1 reached" in texts and "sys 7: mission item 2 current" in texts
    assert len(r.translations(ent.MON_VEHICLE).t_us) == n


def test_monitor_cli_rejects_bad_options(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["--rerun", "bogus"]) == 2
    assert main(["--connect", "tcp:1.2.3.4:5"]) == 2
    assert "monitor:" in capsys.readouterr().err
