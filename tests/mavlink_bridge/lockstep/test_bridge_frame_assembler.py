"""The lockstep's frame assembly without a socket (``FrameAssembler``): what the client and the in-process
flights both build frames with."""

from __future__ import annotations

import dataclasses
import math

import pytest

from mavlink_bridge.contract.traffic import AdsbEmitterType, TrafficReport, TrafficSource
from mavlink_bridge.contract.wire import GroundTruth, ObstacleDetection, ObstacleShape, SensorSample
from mavlink_bridge.lockstep import MAX_FRAME_STEP_US, FrameAssembler, LockstepFrame, encode_frame
from mavlink_bridge.wire.codec import SIM_COMPONENT_ID, SIM_SYSTEM_ID, Encoder, Heartbeat
from mavlink_bridge.wire.traffic_codec import MAV_COMP_ID_ADSB, MAV_TYPE_ADSB

ENC = Encoder(SIM_SYSTEM_ID, SIM_COMPONENT_ID)
FRAME_PERIOD_US = 4000
HELI = TrafficReport(TrafficSource.MANNED, 0xA1B2C3, "HELI1", AdsbEmitterType.ROTOCRAFT, 47.4, 8.5, 528.0, 0, 0, 0, 0)
QUAD = TrafficReport(TrafficSource.UAV, 3, "", AdsbEmitterType.UAV, 47.4, 8.5, 498.5, 1.0, -2.0, 0.5, 12_000)


def make_frame(k: int) -> LockstepFrame:
    t = k * FRAME_PERIOD_US
    sensor = SensorSample(t, (0.0, 0.0, -9.8), (0.0, 0.0, 0.0), (0.2, 0.0, 0.4), 1013.0, 1.0 + k, 20.0)
    truth = GroundTruth(t, (1.0, 0.0, 0.0, 0.0), (0.0, 0.0, 0.0), 30.0, 120.0, 10.0, (0.0, 0.0, 0.0), (0, 0, 0))
    return LockstepFrame(sensor, None, truth)


def _datagram(k: int, *, t_us: int | None = None, q: tuple = (1.0, 0.0, 0.0, 0.0), **fields: object) -> bytes:
    frame = make_frame(k)
    t = frame.time_us if t_us is None else t_us
    sensor = dataclasses.replace(frame.sensor, time_us=t)
    truth = dataclasses.replace(frame.truth, time_us=t, q_ned_frd=q)
    return encode_frame(ENC, dataclasses.replace(LockstepFrame(sensor, None, truth, frame.detections), **fields))


def test_frames_in_order_come_out_once_and_out_of_order_ones_are_counted() -> None:
    resent: list[int] = []
    a = FrameAssembler(lambda: resent.append(1))
    first = a.absorb(_datagram(0))
    assert first is not None and first.time_us == 0 and a.heard
    assert a.absorb(_datagram(0)) is None and a.duplicates == 1  # the frame being worked on, again
    a.answered(0)
    assert a.absorb(_datagram(0)) is None and a.reanswered == 1 and resent == [1]  # answered: re-send the answer
    assert a.absorb(_datagram(1)) is not None
    a.answered(FRAME_PERIOD_US)
    assert a.absorb(_datagram(0)) is None and a.stale == 1
    assert a.absorb(_datagram(2, t_us=FRAME_PERIOD_US + MAX_FRAME_STEP_US + 1)) is None and a.future == 1
    assert a.absorb(_datagram(2, t_us=2**63)) is None and a.future == 2
    assert a.absorb(_datagram(2, q=(math.nan, 0.0, 0.0, 0.0))) is None and a.invalid == 1
    assert a.absorb(ENC.sensor(make_frame(3).sensor)) is None and a.incomplete == 1  # truth of another time
    assert a.absorb(b"\x00garbage") is None and not a.heard and a.decoder.stats.malformed > 0
    assert a.absorb(_datagram(2)) is not None and a.frames == 3
    a.restart()  # a restarted sim: any first time again
    assert a.absorb(_datagram(0)) is not None and a.frames == 4


def test_detections_and_traffic_ride_with_their_frame_and_adsb_gets_its_time() -> None:
    a = FrameAssembler()
    det = ObstacleDetection(0, 1, (5.0, 0.0, 0.0), 1.0, ObstacleShape.SPHERE)
    receiver = Encoder(SIM_SYSTEM_ID, MAV_COMP_ID_ADSB)
    beat = receiver.heartbeat(Heartbeat(MAV_TYPE_ADSB, 8, 0, 0, 4))
    frame = a.frame(beat + _datagram(3, detections=(dataclasses.replace(det, time_us=3 * FRAME_PERIOD_US),),
                                     traffic=(HELI, QUAD)))  # fmt: skip
    assert len(frame.detections) == 1 and a.traffic_receiver_t_us == frame.time_us
    heli, quad = frame.traffic
    assert heli.t_us == frame.time_us and quad.t_us == QUAD.t_us  # ADS-B has no time: the frame's
    nxt = a.frame(_datagram(4))
    assert nxt.detections == () and nxt.traffic == ()  # nothing carried over to the next frame


def test_frame_says_why_a_datagram_made_no_frame() -> None:
    a = FrameAssembler()
    a.frame(_datagram(0))
    with pytest.raises(RuntimeError, match="made no frame \\(1 duplicate\\)"):
        a.frame(_datagram(0))
    with pytest.raises(RuntimeError, match="no HIL_SENSOR"):
        FrameAssembler().frame(ENC.truth(make_frame(0).truth))
