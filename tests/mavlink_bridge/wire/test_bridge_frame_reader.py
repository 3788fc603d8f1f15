"""The compiled lockstep reader (``mavlink_bridge.wire.frame_reader``) decodes exactly what the Python decoder does.

Every datagram is decoded twice, with ``Decoder()`` (compiled fast path, Python fallback) and with
``Decoder(compiled=False)``; messages (compared by ``repr``, so NaN and -0.0 count), ids and counters must
be identical, whether the compiled path took the datagram or handed it back.
"""

from __future__ import annotations

import math
import random

import pytest
from pymavlink.dialects.v20 import ardupilotmega as mav2

from mavlink_bridge.contract.wire import (
    ActuatorCommand,
    GpsSample,
    GroundTruth,
    ObstacleDetection,
    ObstacleShape,
    SensorSample,
)
from mavlink_bridge.wire import codec, frame_reader
from mavlink_bridge.wire.codec import Decoder, Encoder, Heartbeat

SPECIALS = (math.nan, math.inf, -math.inf, -0.0, 0.0, 1e-40, 3.4e38, -1e9)


def _x(rng: random.Random, scale: float = 10.0) -> float:
    """A float, now and then a special one (NaN, inf, -0, subnormal, out of range)."""
    return rng.choice(SPECIALS) if rng.random() < 0.05 else rng.uniform(-scale, scale)


def _v3(rng: random.Random, scale: float = 10.0) -> tuple[float, float, float]:
    return (_x(rng, scale), _x(rng, scale), _x(rng, scale))


def _messages(rng: random.Random, t_us: int) -> list[object]:
    """A lockstep-like set of messages (GPS and detections sometimes, sensor last)."""
    msgs: list[object] = []
    if rng.random() < 0.4:
        eph = rng.choice((0.8, math.inf, 1e9, 0.0))
        vel = (0.0, 0.0, 0.0) if rng.random() < 0.2 else _v3(rng, 400.0)
        msgs.append(GpsSample(t_us, rng.uniform(-90, 90), rng.uniform(-180, 180), _x(rng, 3e6), vel, eph, 1.2, 3, 12))
    q = (rng.uniform(-1, 1), rng.uniform(-1, 1), rng.uniform(-1, 1), rng.uniform(-1, 1))
    lat, lon = rng.uniform(-90, 90), rng.uniform(-180, 180)
    msgs.append(GroundTruth(t_us, q, _v3(rng), lat, lon, _x(rng, 3e6), _v3(rng, 400.0), _v3(rng, 400.0)))
    for k in range(rng.choice((0, 0, 1, 3))):
        shape = rng.choice(list(ObstacleShape))
        msgs.append(ObstacleDetection(t_us - t_us % 1000, k, _v3(rng, 30.0), abs(_x(rng, 5.0)), shape))
    msgs.append(SensorSample(t_us, _v3(rng), _v3(rng), _v3(rng, 1.0), _x(rng, 1100.0), _x(rng, 500.0), _x(rng)))
    return msgs


def _encode(enc: Encoder, msgs: list[object]) -> bytes:
    return b"".join(enc.encode(m) for m in msgs)  # type: ignore[arg-type]


def _both(data: bytes) -> tuple[Decoder, Decoder, list[object], list[object]]:
    compiled, python = Decoder(), Decoder(compiled=False)
    return compiled, python, compiled.decode(data), python.decode(data)


def _assert_same(data: bytes) -> list[object]:
    compiled, python, got, want = _both(data)
    assert repr(got) == repr(want)
    assert [type(m) for m in got] == [type(m) for m in want]
    assert compiled.stats == python.stats
    assert (compiled.last_system_id, compiled.last_component_id) == (python.last_system_id, python.last_component_id)
    return got


def test_layouts_match_the_dialect() -> None:
    for msg_id, crc, size in (
        (frame_reader._ID_SENSOR, frame_reader._CRC_SENSOR, frame_reader._LEN_SENSOR),
        (frame_reader._ID_GPS, frame_reader._CRC_GPS, frame_reader._LEN_GPS),
        (frame_reader._ID_TRUTH, frame_reader._CRC_TRUTH, frame_reader._LEN_TRUTH),
        (frame_reader._ID_DETECTION, frame_reader._CRC_DETECTION, frame_reader._LEN_DETECTION),
        (frame_reader._ID_ACTUATORS, frame_reader._CRC_ACTUATORS, frame_reader._LEN_ACTUATORS),
    ):
        cls = mav2.mavlink_map[msg_id]
        assert (cls.crc_extra, cls.unpacker.size) == (crc, size), cls.name
    assert frame_reader._MAV_FRAME_BODY_FRD == mav2.MAV_FRAME_BODY_FRD
    assert mav2.MAVLink_hil_sensor_message.unpacker.format == "<QfffffffffffffIB"
    assert mav2.MAVLink_hil_gps_message.unpacker.format == "<QiiiHHHhhhHBBBH"
    assert mav2.MAVLink_hil_state_quaternion_message.unpacker.format == "<Q4ffffiiihhhHHhhh"
    assert mav2.MAVLink_obstacle_distance_3d_message.unpacker.format == "<IfffffHBB"
    assert mav2.MAVLink_hil_actuator_controls_message.unpacker.format == "<QQ16fB"


def test_lockstep_frames_take_the_compiled_path_and_match_python() -> None:
    rng = random.Random(7)
    enc = Encoder(1, 250)
    out = frame_reader.new_out()
    for k in range(400):
        msgs = _messages(rng, 1_000_000 + 4000 * k)
        data = _encode(enc, msgs)
        assert frame_reader.read_values(data, out) > 0  # the fast path took it
        got = _assert_same(data)
        assert len(got) == len(msgs)


def test_actuator_answers_match_python() -> None:
    rng = random.Random(3)
    enc = Encoder()
    for k in range(300):
        motors = (_x(rng, 1.0), _x(rng, 1.0), _x(rng, 1.0), _x(rng, 1.0))
        cmd = ActuatorCommand(4000 * k, motors, rng.random() < 0.8, rng.random() < 0.3, rng.random() < 0.9)
        data = enc.actuators(cmd)
        assert len(_assert_same(data)) == 1
        assert len(_assert_same(data + enc.actuators(cmd))) == 2  # long enough for the compiled path


def test_truncated_and_extended_payloads() -> None:
    enc = Encoder()
    zero = SensorSample(4000, (1.0, 0.0, 0.0), (0.0, 0.0, 0.0), (0.0, 0.0, 0.0), 0.0, 0.0, 0.0)
    truth = GroundTruth(4000, (1.0, 0.0, 0.0, 0.0), (0.0,) * 3, 0.0, 0.0, 0.0, (0.0,) * 3, (0.0,) * 3)
    data = enc.truth(truth) + enc.sensor(zero)
    assert len(data) < 2 * 12 + frame_reader._LEN_TRUTH + frame_reader._LEN_SENSOR  # MAVLink 2 truncation
    assert len(_assert_same(data)) == 2
    # a payload longer than the message we know (a newer dialect's extension): the extra bytes are skipped
    payload = mav2.MAVLink_hil_actuator_controls_message(7, tuple([0.5] * 16), 128, 1).pack(mav2.MAVLink(None, 1, 1))
    longer = bytearray(payload[:-2])
    longer[1] += 3
    longer += b"\x01\x02\x03"
    crc = codec._crc_mcrf4xx(codec._HIL_ACTUATORS.crc_extra, codec._crc_mcrf4xx(bytes(longer[1:])))
    longer += crc.to_bytes(2, "little")
    assert len(_assert_same(bytes(longer) * 2)) == 2


@pytest.mark.parametrize(
    "mangle",
    [
        pytest.param(lambda d: d[:-1], id="truncated-tail"),
        pytest.param(lambda d: d[:20] + bytes([d[20] ^ 0xFF]) + d[21:], id="bad-crc"),
        pytest.param(lambda d: b"\x00\x01garbage" + d, id="garbage-first"),
        pytest.param(lambda d: d + b"\xfd\x01", id="garbage-last"),
        pytest.param(lambda d: Encoder().heartbeat(Heartbeat()) + d, id="heartbeat"),
        pytest.param(lambda d: d + bytes(mav2.MAVLink_system_time_message(1, 2).pack(mav2.MAVLink(None))), id="other"),
        pytest.param(
            lambda d: (
                bytes(mav2.MAVLink_system_time_message(1, 2).pack(mav2.MAVLink(None, 1, 1), force_mavlink1=True)) + d
            ),
            id="mavlink1",
        ),
        pytest.param(lambda d: d[:2] + b"\x01" + d[3:] + bytes(13), id="signed-flag"),
        pytest.param(lambda d: d[:2] + b"\x02" + d[3:], id="unknown-incompat-flag"),
    ],
)
def test_anything_unusual_falls_back_to_python_with_the_same_result(mangle) -> None:  # type: ignore[no-untyped-def]
    enc = Encoder(1, 250)
    data = mangle(_encode(enc, _messages(random.Random(1), 4000)))
    assert frame_reader.read_values(data, frame_reader.new_out()) == frame_reader.FALLBACK
    _assert_same(data)


def test_detection_in_another_frame_is_ignored_like_python() -> None:
    enc = Encoder()
    det = enc.detection(ObstacleDetection(4000, 1, (1.0, 2.0, 3.0), 1.0))
    other = bytearray(det[:-2])
    other[10 + 27] = mav2.MAV_FRAME_LOCAL_NED
    crc = codec._crc_mcrf4xx(codec._OBSTACLE_3D.crc_extra, codec._crc_mcrf4xx(bytes(other[1:])))
    data = bytes(other) + crc.to_bytes(2, "little") + det
    assert frame_reader.read_values(data, frame_reader.new_out()) == frame_reader.FALLBACK
    got = _assert_same(data)
    assert len(got) == 1


def test_empty_and_random_bytes_never_raise() -> None:
    rng = random.Random(5)
    _assert_same(b"")
    for _ in range(300):
        _assert_same(bytes(rng.getrandbits(8) for _ in range(rng.randint(1, 300))))
