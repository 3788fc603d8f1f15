"""Telemetry streams: a mode, arming or landed-state change goes out at once, after the position it happened at."""

from __future__ import annotations

import dataclasses
import os

import pytest
from gcs_fakes import FakeVehicle

from mavlink_bridge.contract.vehicle_api import FlightMode
from mavlink_bridge.gcs_server.telemetry_streams import TelemetryStreams

os.environ.setdefault("MAVLINK20", "1")
from pymavlink import mavutil

mavutil.set_dialect("common")
M = mavutil.mavlink


class _Capture:
    """What a MAVLink sender writes, one message per write."""

    def __init__(self) -> None:
        self.frames: list[bytes] = []

    def write(self, data: bytes) -> None:
        self.frames.append(bytes(data))


def _published(streams: TelemetryStreams, capture: _Capture, snapshot) -> list[str]:  # type: ignore[no-untyped-def]
    capture.frames.clear()
    streams.publish(snapshot)
    parser = M.MAVLink(None)
    return [parser.parse_char(frame).get_type() for frame in capture.frames]


def test_a_state_change_is_sent_at_once_after_its_position() -> None:
    capture = _Capture()
    streams = TelemetryStreams(M.MAVLink(capture, srcSystem=1, srcComponent=1))
    vehicle = FakeVehicle()
    first = _published(streams, capture, vehicle.snapshot(0))  # everything is due at t = 0
    assert {"HEARTBEAT", "LOCAL_POSITION_NED", "GLOBAL_POSITION_INT", "ATTITUDE"} <= set(first)
    assert _published(streams, capture, vehicle.snapshot(4_000)) == []  # 4 ms later nothing is due
    loiter = vehicle.snapshot(8_000)
    mission = dataclasses.replace(loiter, mode=FlightMode.AUTO_MISSION)
    sent = _published(streams, capture, mission)
    assert sent == ["LOCAL_POSITION_NED", "GLOBAL_POSITION_INT", "HEARTBEAT", "EXTENDED_SYS_STATE"]
    assert streams.set_interval(M.MAVLINK_MSG_ID_GLOBAL_POSITION_INT, -1)  # a GCS turned that stream off
    armed = dataclasses.replace(vehicle.snapshot(12_000), mode=FlightMode.AUTO_MISSION, armed=not mission.armed)
    assert _published(streams, capture, armed) == ["LOCAL_POSITION_NED", "HEARTBEAT", "EXTENDED_SYS_STATE"]


def test_estimator_status_carries_the_estimators_report() -> None:
    from mavlink_bridge.contract.vehicle_api import EstimatorFlags, EstimatorReport

    capture = _Capture()
    streams = TelemetryStreams(M.MAVLink(capture, srcSystem=1, srcComponent=1))
    vehicle = FakeVehicle()
    assert "ESTIMATOR_STATUS" not in _published(streams, capture, vehicle.snapshot(0))  # no report: not sent
    flags = EstimatorFlags.ATTITUDE | EstimatorFlags.POS_HORIZ_ABS
    report = EstimatorReport(flags, 0.1, float("nan"), 0.3, 0.4, 0.5, 0.6)
    capture.frames.clear()
    streams.publish(dataclasses.replace(vehicle.snapshot(1_000_000), estimator=report))
    parser = M.MAVLink(None)
    msgs = [parser.parse_char(frame) for frame in capture.frames]
    (msg,) = [m for m in msgs if m.get_type() == "ESTIMATOR_STATUS"]
    assert msg.flags == int(flags) and msg.pos_horiz_ratio == 0.0  # NaN (not fused) goes out as 0
    assert (msg.vel_ratio, msg.mag_ratio, msg.pos_horiz_accuracy) == pytest.approx((0.1, 0.4, 0.5))
