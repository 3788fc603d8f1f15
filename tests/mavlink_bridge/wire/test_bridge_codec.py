"""Codec contract: bytes identical to pymavlink's, round trips with wire units, garbage never raises."""

from __future__ import annotations

import math
import random
import struct

import numpy as np
import pytest
from pymavlink.dialects.v20 import ardupilotmega as mav2

from mavlink_bridge.contract.frames import GRAVITY_M_S2
from mavlink_bridge.contract.wire import (
    GRIPPER_CHANNEL,
    ActuatorCommand,
    GpsSample,
    GroundTruth,
    ObstacleDetection,
    ObstacleShape,
    SensorSample,
)
from mavlink_bridge.wire.codec import HIL_SENSOR_FIELDS_ALL, Decoder, Encoder, Heartbeat, make_mavlink

F32 = np.float32


def f32(v: float) -> float:
    return float(F32(v))


SENSOR = SensorSample(123_456_789, (0.1, -0.2, -9.81), (0.01, -0.02, 3.5), (0.21, -0.01, 0.43), 1013.25, 12.5, 21.0)
GPS = GpsSample(4_000_000, 30.2635123, 120.1233456, 25.123, (3.21, -1.5, 0.42), 0.8, 1.25, 3, 12)
TRUTH = GroundTruth(
    4_000_000,
    (0.9238795, 0.0, 0.0, 0.3826834),
    (0.1, -0.2, 0.3),
    30.2635123,
    120.1233456,
    22.345,
    (5.01, -2.02, -0.33),
    (0.5, -0.25, -9.80665),
)
DETECTION = ObstacleDetection(4_000_000, 7, (6.5, -1.25, 0.5), 2.5, ObstacleShape.CYLINDER)
COMMAND = ActuatorCommand(4_000_000, (0.1, 0.55, 0.6, 1.0), armed=True, gripper_release=True)


def _decode_one(data: bytes) -> object:
    dec = Decoder()
    msgs = dec.decode(data)
    assert len(msgs) == 1, (msgs, dec.stats)
    return msgs[0]


def _pymavlink_bytes(msg: mav2.MAVLink_message, system_id: int, component_id: int) -> bytes:
    mav = mav2.MAVLink(None, srcSystem=system_id, srcComponent=component_id)
    return bytes(msg.pack(mav))


def test_bytes_identical_to_pymavlink_for_every_message() -> None:
    enc = Encoder(1, 1)  # seq 0 for the first frame, like a fresh pymavlink MAVLink
    ours = enc.sensor(SENSOR)
    ref = mav2.MAVLink_hil_sensor_message(
        SENSOR.time_us, 0.1, -0.2, -9.81, 0.01, -0.02, 3.5, 0.21, -0.01, 0.43, 1013.25, 0.0, 12.5, 21.0,
        HIL_SENSOR_FIELDS_ALL, 0,
    )  # fmt: skip
    assert ours == _pymavlink_bytes(ref, 1, 1)

    cases: list[tuple[bytes, mav2.MAVLink_message]] = [
        (
            Encoder(1, 1).actuators(COMMAND),
            mav2.MAVLink_hil_actuator_controls_message(
                COMMAND.time_us, [0.1, 0.55, 0.6, 1.0, 0, 0, 0, 0, 1.0, 0, 0, 0, 0, 0, 0, 0], 128, 1
            ),
        ),
        (
            Encoder(1, 1).heartbeat(Heartbeat(base_mode=0x81, custom_mode=4 << 16)),
            mav2.MAVLink_heartbeat_message(
                mav2.MAV_TYPE_QUADROTOR, mav2.MAV_AUTOPILOT_PX4, 0x81, 4 << 16, mav2.MAV_STATE_STANDBY, 3
            ),
        ),
        (
            Encoder(1, 1).detection(DETECTION),
            mav2.MAVLink_obstacle_distance_3d_message(4000, 2, mav2.MAV_FRAME_BODY_FRD, 7, 6.5, -1.25, 0.5, 0.0, 2.5),
        ),
    ]
    for ours_bytes, ref_msg in cases:
        assert ours_bytes == _pymavlink_bytes(ref_msg, 1, 1), ref_msg.get_type()


def test_pymavlink_decodes_our_frames_with_wire_units() -> None:
    enc = Encoder(1, 51)
    mav = mav2.MAVLink(None)
    sensor, gps, truth = (
        mav.parse_buffer(enc.sensor(SENSOR))[0],
        mav.parse_buffer(enc.gps(GPS))[0],
        mav.parse_buffer(enc.truth(TRUTH))[0],
    )
    assert sensor.get_srcComponent() == 51
    assert sensor.fields_updated == HIL_SENSOR_FIELDS_ALL
    assert (sensor.xacc, sensor.zgyro, sensor.abs_pressure) == (f32(0.1), f32(3.5), f32(1013.25))
    assert (gps.lat, gps.lon, gps.alt) == (302635123, 1201233456, 25123)
    assert (gps.vn, gps.ve, gps.vd, gps.eph, gps.epv, gps.vel) == (321, -150, 42, 80, 125, round(math.hypot(321, 150)))
    assert gps.cog == round(math.degrees(math.atan2(-1.5, 3.21)) * 100) % 36000
    assert (truth.vx, truth.vy, truth.vz) == (501, -202, -33)
    assert truth.alt == 22345
    assert truth.zacc == round(-9.80665 / GRAVITY_M_S2 * 1000)
    assert truth.attitude_quaternion == pytest.approx(list(TRUTH.q_ned_frd), abs=1e-7)


def test_round_trip_every_wire_message() -> None:
    enc = Encoder()
    s = _decode_one(enc.sensor(SENSOR))
    assert s == SensorSample(
        SENSOR.time_us,
        tuple(f32(v) for v in SENSOR.accel_frd_m_s2),
        tuple(f32(v) for v in SENSOR.gyro_frd_rad_s),
        tuple(f32(v) for v in SENSOR.mag_frd_gauss),
        f32(1013.25),
        f32(12.5),
        f32(21.0),
    )
    g = _decode_one(enc.gps(GPS))
    assert isinstance(g, GpsSample)
    assert (g.time_us, g.fix_type, g.satellites_visible) == (GPS.time_us, 3, 12)
    assert g.lat_deg == pytest.approx(GPS.lat_deg, abs=1e-7) and g.lon_deg == pytest.approx(GPS.lon_deg, abs=1e-7)
    assert g.alt_amsl_m == pytest.approx(GPS.alt_amsl_m, abs=1e-3)
    assert g.vel_ned_m_s == pytest.approx(GPS.vel_ned_m_s, abs=0.005)
    assert (g.eph_m, g.epv_m) == pytest.approx((0.8, 1.25))
    t = _decode_one(enc.truth(TRUTH))
    assert isinstance(t, GroundTruth)
    assert t.time_us == TRUTH.time_us
    assert t.q_ned_frd == pytest.approx(TRUTH.q_ned_frd, abs=1e-7)
    assert t.rate_frd_rad_s == pytest.approx(TRUTH.rate_frd_rad_s, abs=1e-7)
    assert (t.lat_deg, t.lon_deg) == pytest.approx((TRUTH.lat_deg, TRUTH.lon_deg), abs=1e-7)
    assert t.alt_amsl_m == pytest.approx(TRUTH.alt_amsl_m, abs=5e-4)
    assert t.vel_ned_m_s == pytest.approx(TRUTH.vel_ned_m_s, abs=0.005)
    assert t.accel_frd_m_s2 == pytest.approx(TRUTH.accel_frd_m_s2, abs=0.5e-3 * GRAVITY_M_S2)
    d = _decode_one(enc.detection(DETECTION))
    assert d == DETECTION  # exact in float32 and at ms resolution
    c = _decode_one(enc.actuators(COMMAND))
    assert c == ActuatorCommand(COMMAND.time_us, tuple(f32(v) for v in COMMAND.motor_cmd), True, True, True)
    hb = Heartbeat(base_mode=0x81, custom_mode=(3 << 16) | (4 << 24))
    assert _decode_one(enc.heartbeat(hb)) == hb


def test_round_trip_extremes_saturate_instead_of_raising() -> None:
    enc = Encoder()
    big = GroundTruth(
        2**64 - 1,
        (1.0, 0.0, 0.0, 0.0),
        (1e6, -1e6, math.inf),
        math.nan,
        -400.0,
        1e12,
        (1e3, -1e3, math.nan),
        (400.0, -math.inf, 0.0),
    )
    t = _decode_one(enc.truth(big))
    assert isinstance(t, GroundTruth)
    assert t.time_us == 2**64 - 1
    assert t.vel_ned_m_s == (327.67, -327.68, 0.0)
    assert t.lat_deg == 0.0 and t.lon_deg == -214.7483648 and t.alt_amsl_m == 2147483.647
    assert t.accel_frd_m_s2[0] == pytest.approx(32767 * GRAVITY_M_S2 / 1000)
    assert t.accel_frd_m_s2[1] == pytest.approx(-32768 * GRAVITY_M_S2 / 1000)
    assert t.rate_frd_rad_s[2] == math.inf  # floats stay floats (sim/autopilot sanitise)
    gps = GpsSample(0, 91.0, -181.0, -1e9, (math.nan, 0.0, 1e9), math.inf, -5.0, 300, -1)
    g = _decode_one(enc.gps(gps))
    assert isinstance(g, GpsSample)
    assert g.eph_m == math.inf and g.epv_m == 0.0 and g.fix_type == 255 and g.satellites_visible == 0
    assert g.vel_ned_m_s == (0.0, 0.0, 327.67)
    zero = ActuatorCommand(0, (0.0, 0.0, 0.0, 0.0), armed=False, gripper_release=False, lockstep=False)
    assert _decode_one(enc.actuators(zero)) == zero  # all-zero payload is truncated to 1 byte and re-padded
    nan_cmd = ActuatorCommand(1, (math.nan, -1.0, 2.0, math.inf), armed=True)
    c = _decode_one(enc.actuators(nan_cmd))
    assert isinstance(c, ActuatorCommand) and math.isnan(c.motor_cmd[0]) and c.motor_cmd[1:] == (-1.0, 2.0, math.inf)


def test_decoder_accepts_mavlink1_and_signed_frames_from_pymavlink() -> None:
    v1 = mav2.MAVLink(None, srcSystem=3, srcComponent=4)
    msg = mav2.MAVLink_hil_actuator_controls_message(99, [0.5] * 4 + [0.0] * 4 + [0.9] + [0.0] * 7, 128, 1)
    v1_bytes = bytes(msg.pack(v1, force_mavlink1=True))
    assert v1_bytes[0] == 0xFE
    dec = Decoder()
    (c,) = dec.decode(v1_bytes)
    assert c == ActuatorCommand(99, (0.5, 0.5, 0.5, 0.5), True, True, True)
    assert (dec.last_system_id, dec.last_component_id) == (3, 4)
    signer = make_mavlink(1, 1, signing_key=bytes(range(32)))
    signed = bytes(mav2.MAVLink_heartbeat_message(2, 12, 0, 0, 3, 3).pack(signer))
    (hb,) = dec.decode(signed)
    assert hb == Heartbeat(2, 12, 0, 0, 3) and dec.stats.signed == 1


def test_several_frames_per_datagram_in_order_and_unmapped_messages_ignored() -> None:
    enc = Encoder()
    other = bytes(mav2.MAVLink_system_time_message(1, 2).pack(mav2.MAVLink(None)))
    data = enc.gps(GPS) + other + enc.truth(TRUTH) + enc.sensor(SENSOR)
    dec = Decoder()
    msgs = dec.decode(data)
    assert [type(m) for m in msgs] == [GpsSample, GroundTruth, SensorSample]
    assert dec.stats.ignored == 1 and dec.stats.malformed == 0


def test_obstacle_in_another_frame_is_ignored() -> None:
    other_frame = mav2.MAVLink_obstacle_distance_3d_message(1, 0, mav2.MAV_FRAME_LOCAL_NED, 1, 1.0, 2.0, 3.0, 0.0, 1.0)
    dec = Decoder()
    assert dec.decode(bytes(other_frame.pack(mav2.MAVLink(None)))) == []
    assert dec.stats.ignored == 1


def test_garbage_truncated_and_corrupted_bytes_never_raise() -> None:
    rng = random.Random(1234)
    enc = Encoder()
    good = enc.gps(GPS) + enc.truth(TRUTH) + enc.detection(DETECTION) + enc.sensor(SENSOR) + enc.actuators(COMMAND)
    dec = Decoder()
    for _ in range(3000):
        kind = rng.randrange(4)
        if kind == 0:
            data = bytes(rng.randrange(256) for _ in range(rng.randrange(0, 300)))
        elif kind == 1:
            data = good[: rng.randrange(len(good))]
        elif kind == 2:
            buf = bytearray(good)
            for _ in range(rng.randrange(1, 6)):
                buf[rng.randrange(len(buf))] = rng.randrange(256)
            data = bytes(buf)
        else:  # magic bytes and plausible headers with nonsense after them
            data = bytes([0xFD, rng.randrange(256), rng.randrange(4), 0, 0, 1, 1, 107, 0, 0]) + b"\xfe" * rng.randrange(
                9
            )
        for msg in dec.decode(data):
            assert type(msg) in (GpsSample, GroundTruth, ObstacleDetection, SensorSample, ActuatorCommand, Heartbeat)
    assert dec.stats.malformed > 1000
    # a corrupted frame is dropped but the intact frames after it still decode
    buf = bytearray(good)
    buf[20] ^= 0xFF  # inside the first (HIL_GPS) frame
    msgs = Decoder().decode(bytes(buf))
    assert [type(m) for m in msgs] == [GroundTruth, ObstacleDetection, SensorSample, ActuatorCommand]


def test_gripper_channel_threshold() -> None:
    mav = mav2.MAVLink(None)
    for value, release in ((0.49, False), (0.5, True), (-1.0, False), (math.nan, False)):
        controls = [0.0] * 16
        controls[GRIPPER_CHANNEL] = value
        data = bytes(mav2.MAVLink_hil_actuator_controls_message(1, controls, 0, 0).pack(mav))
        (c,) = Decoder().decode(data)
        assert c.gripper_release is release and c.armed is False and c.lockstep is False


def test_make_mavlink_rejects_bad_key() -> None:
    with pytest.raises(ValueError, match="32 bytes"):
        make_mavlink(1, 1, signing_key=b"short")


def test_sequence_number_wraps() -> None:
    enc = Encoder()
    seqs = [struct.unpack_from("<B", enc.heartbeat(Heartbeat()), 4)[0] for _ in range(300)]
    assert seqs[:3] == [0, 1, 2] and seqs[256] == 0 and seqs[299] == 43
