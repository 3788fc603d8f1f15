"""MAVLink 2 bytes <-> the typed wire contract of ``mavlink_bridge.contract.wire`` (SPEC §4).

The only place that converts the sim<->autopilot dataclasses to and from MAVLink. Message
layouts (ids, CRC extras, field order, struct formats) come from pymavlink's
``ardupilotmega`` dialect (a superset of ``common`` that also defines OBSTACLE_DISTANCE_3D);
framing is done here with precompiled ``struct`` objects and a C-speed CRC (``fastcrc``, a
dependency of pymavlink) because pymavlink's pure-Python CRC and parser cost ~25 µs / ~50 µs
per frame, which would dominate the lockstep loop. Payloads are unpacked in place from the
datagram (no copy unless MAVLink 2 truncated trailing zeros). ``tests/mavlink_bridge/wire/test_bridge_codec.py``
checks the bytes against pymavlink's.

Units on the wire (what PX4's simulator_mavlink expects):

============================  ==================================================================
HIL_SENSOR                    m/s², rad/s, gauss, hPa, m, °C; ``fields_updated`` = 0x1BFF
                              (accel, gyro, mag, abs pressure, pressure alt, temperature)
HIL_GPS                       lat/lon degE7, alt mm AMSL, eph/epv cm, vel/vn/ve/vd cm/s, cog cdeg
HIL_STATE_QUATERNION          q w-first (body FRD → NED), rad/s, degE7, mm, cm/s, accel mG
HIL_ACTUATOR_CONTROLS         controls[0..3] motors in [0, 1] (PX4 quad-x order),
                              controls[GRIPPER_CHANNEL] 1.0 release / 0.0 hold,
                              ``mode`` bit 128 armed, ``flags`` bit 0 lockstep,
                              ``time_usec`` echoes the HIL_SENSOR it answers
OBSTACLE_DISTANCE_3D          frame MAV_FRAME_BODY_FRD; x/y/z = nearest surface point (m, FRD);
                              ``sensor_type`` carries the ``ObstacleShape``; ``min_distance`` = 0
                              and ``max_distance`` = radius (radius = max − min);
                              ``time_boot_ms`` = time_us // 1000 (sim time, ms resolution)
============================  ==================================================================

Integers saturate at their wire range; a non-finite value becomes 0 (or "unknown" where
MAVLink defines one, e.g. eph = UINT16_MAX). Decoding never raises: malformed, truncated
or random bytes are counted in ``DecoderStats`` and dropped.

Encoding (``Encoder``) and ``make_mavlink`` (GCS/API links) live here; decoding in ``wire.decode``,
the framing both share (layouts, CRC, headers) in ``wire.framing``.
"""

from __future__ import annotations

import math
import struct
from collections.abc import Callable

from mavlink_bridge.contract.frames import DEG_E7, GRAVITY_M_S2
from mavlink_bridge.contract.traffic import OwnPositionReport, TrafficReport, TrafficSource
from mavlink_bridge.contract.wire import (
    ACTUATOR_FLAG_LOCKSTEP,
    ACTUATOR_MODE_ARMED,
    ActuatorCommand,
    GpsSample,
    GroundTruth,
    ObstacleDetection,
    SensorSample,
)
from mavlink_bridge.wire.decode import Decoder, DecoderStats
from mavlink_bridge.wire.framing import (
    _ACTUATORS_PAYLOAD,
    _CRC,
    _HEARTBEAT,
    _HIL_ACTUATORS,
    _HIL_GPS,
    _HIL_SENSOR,
    _HIL_STATE_Q,
    _OBSTACLE_3D,
    _UINT16_UNKNOWN,
    _V2_HEADER,
    _V2_MAGIC,
    AUTOPILOT_COMPONENT_ID,
    AUTOPILOT_SYSTEM_ID,
    HIL_SENSOR_FIELDS_ALL,
    MAV_AUTOPILOT_PX4,
    MAV_FRAME_BODY_FRD,
    MAV_TYPE_QUADROTOR,
    SIM_COMPONENT_ID,
    SIM_SYSTEM_ID,
    Heartbeat,
    WireMessage,
    _crc_mcrf4xx,
    _dialect,
    _Layout,
)
from mavlink_bridge.wire.traffic_codec import (
    ADSB_VEHICLE,
    UTM_GLOBAL_POSITION,
    adsb_payload,
    own_position_payload,
    utm_payload,
)

__all__ = [
    "AUTOPILOT_COMPONENT_ID",
    "AUTOPILOT_SYSTEM_ID",
    "HIL_SENSOR_FIELDS_ALL",
    "MAV_AUTOPILOT_PX4",
    "MAV_FRAME_BODY_FRD",
    "MAV_TYPE_QUADROTOR",
    "SIM_COMPONENT_ID",
    "SIM_SYSTEM_ID",
    "Decoder",
    "DecoderStats",
    "Encoder",
    "Heartbeat",
    "WireMessage",
    "make_mavlink",
]


def _finite(x: float) -> float:
    return x if math.isfinite(x) else 0.0


def _sat(x: float, lo: int, hi: int) -> int:
    """Round to the nearest integer and saturate to [lo, hi]; non-finite -> 0 (then clamped)."""
    if x != x:  # NaN
        return 0 if lo <= 0 <= hi else lo
    if x >= hi:
        return hi
    if x <= lo:
        return lo
    return round(x)


def _i16(x: float) -> int:
    return _sat(x, -32768, 32767)


def _i32(x: float) -> int:
    return _sat(x, -2147483648, 2147483647)


def _u16_or_unknown(x: float) -> int:
    """uint16 with UINT16_MAX meaning "unknown" (MAVLink convention)."""
    return _sat(x, 0, _UINT16_UNKNOWN - 1) if math.isfinite(x) else _UINT16_UNKNOWN


_MG_PER_M_S2 = 1000.0 / GRAVITY_M_S2


def _truth_payload(t: GroundTruth, i16: Callable[[float], int], i32: Callable[[float], int]) -> bytes:
    """HIL_STATE_QUATERNION payload; ``i16``/``i32`` round (fast path) or round and saturate."""
    q, w, v, a = t.q_ned_frd, t.rate_frd_rad_s, t.vel_ned_m_s, t.accel_frd_m_s2
    vx_cm_s, vy_cm_s, vz_cm_s = i16(v[0] * 100.0), i16(v[1] * 100.0), i16(v[2] * 100.0)
    speed_cm_s = min(round(math.sqrt(vx_cm_s * vx_cm_s + vy_cm_s * vy_cm_s + vz_cm_s * vz_cm_s)), 65535)
    to_mg = _MG_PER_M_S2
    return _HIL_STATE_Q.payload.pack(
        t.time_us,
        q[0],
        q[1],
        q[2],
        q[3],
        w[0],
        w[1],
        w[2],
        i32(t.lat_deg * DEG_E7),
        i32(t.lon_deg * DEG_E7),
        i32(t.alt_amsl_m * 1000.0),
        vx_cm_s,
        vy_cm_s,
        vz_cm_s,
        speed_cm_s,
        speed_cm_s,
        i16(a[0] * to_mg),
        i16(a[1] * to_mg),
        i16(a[2] * to_mg),
    )


class Encoder:
    """Typed message -> one MAVLink 2 frame (bytes), with its own sequence counter."""

    __slots__ = ("_seq", "component_id", "system_id")

    def __init__(self, system_id: int = AUTOPILOT_SYSTEM_ID, component_id: int = AUTOPILOT_COMPONENT_ID) -> None:
        self.system_id = system_id
        self.component_id = component_id
        self._seq = 0

    def _frame(self, layout: _Layout, payload: bytes) -> bytes:
        # MAVLink 2 drops trailing zero bytes of the payload (at least one byte stays).
        payload = payload.rstrip(b"\x00") or b"\x00"
        seq = self._seq
        self._seq = (seq + 1) & 0xFF
        body = (
            _V2_HEADER.pack(
                _V2_MAGIC, len(payload), 0, 0, seq, self.system_id, self.component_id, layout.id_lo16, layout.id_hi8
            )
            + payload
        )
        return body + _CRC.pack(_crc_mcrf4xx(layout.crc_extra, _crc_mcrf4xx(body[1:])))

    def heartbeat(self, hb: Heartbeat) -> bytes:
        """HEARTBEAT (MAVLink version 3)."""
        return self._frame(
            _HEARTBEAT,
            _HEARTBEAT.payload.pack(hb.custom_mode, hb.mav_type, hb.autopilot, hb.base_mode, hb.system_status, 3),
        )

    def sensor(self, s: SensorSample) -> bytes:
        """HIL_SENSOR (SI units, FRD; pressure in hPa, field in gauss)."""
        a, g, m = s.accel_frd_m_s2, s.gyro_frd_rad_s, s.mag_frd_gauss
        payload = _HIL_SENSOR.payload.pack(
            s.time_us,
            a[0],
            a[1],
            a[2],
            g[0],
            g[1],
            g[2],
            m[0],
            m[1],
            m[2],
            s.abs_pressure_hpa,
            0.0,
            s.pressure_alt_m,
            s.temperature_degc,
            HIL_SENSOR_FIELDS_ALL,
            0,
        )
        return self._frame(_HIL_SENSOR, payload)

    def gps(self, f: GpsSample) -> bytes:
        """HIL_GPS (degE7, mm, cm, cm/s, course over ground in cdeg)."""
        vn, ve, vd = (_finite(v) for v in f.vel_ned_m_s)
        speed_m_s = math.hypot(vn, ve)
        cog_cdeg = round(math.degrees(math.atan2(ve, vn)) * 100.0) % 36000 if speed_m_s > 0.0 else _UINT16_UNKNOWN
        payload = _HIL_GPS.payload.pack(
            f.time_us,
            _i32(f.lat_deg * DEG_E7),
            _i32(f.lon_deg * DEG_E7),
            _i32(f.alt_amsl_m * 1000.0),
            _u16_or_unknown(f.eph_m * 100.0),
            _u16_or_unknown(f.epv_m * 100.0),
            _sat(speed_m_s * 100.0, 0, _UINT16_UNKNOWN - 1),
            _i16(vn * 100.0),
            _i16(ve * 100.0),
            _i16(vd * 100.0),
            cog_cdeg,
            _sat(f.fix_type, 0, 255),
            _sat(f.satellites_visible, 0, 255),
            0,
            0,
        )
        return self._frame(_HIL_GPS, payload)

    def truth(self, t: GroundTruth) -> bytes:
        """HIL_STATE_QUATERNION (ground truth: degE7, mm, cm/s, mG)."""
        try:  # fast path: every integer field in range and finite
            payload = _truth_payload(t, round, round)
        except (struct.error, ValueError, OverflowError):
            payload = _truth_payload(t, _i16, _i32)
        return self._frame(_HIL_STATE_Q, payload)

    def detection(self, d: ObstacleDetection) -> bytes:
        """OBSTACLE_DISTANCE_3D (body FRD; shape in sensor_type; radius = max_distance − min_distance)."""
        p = d.pos_frd_m
        payload = _OBSTACLE_3D.payload.pack(
            (d.time_us // 1000) & 0xFFFFFFFF,
            p[0],
            p[1],
            p[2],
            0.0,
            d.radius_m,
            d.obstacle_id & 0xFFFF,
            int(d.shape),
            MAV_FRAME_BODY_FRD,
        )
        return self._frame(_OBSTACLE_3D, payload)

    def actuators(self, c: ActuatorCommand) -> bytes:
        """HIL_ACTUATOR_CONTROLS (motors on channels 0-3, gripper on GRIPPER_CHANNEL, the other channels 0)."""
        m = c.motor_cmd
        payload = _ACTUATORS_PAYLOAD.pack(
            c.time_us,
            ACTUATOR_FLAG_LOCKSTEP if c.lockstep else 0,
            m[0],
            m[1],
            m[2],
            m[3],
            1.0 if c.gripper_release else 0.0,
            ACTUATOR_MODE_ARMED if c.armed else 0,
        )
        return self._frame(_HIL_ACTUATORS, payload)

    def traffic(self, r: TrafficReport) -> bytes:
        """ADSB_VEHICLE (manned) or UTM_GLOBAL_POSITION (another vehicle), see ``traffic_codec``."""
        if r.source is TrafficSource.MANNED:
            return self._frame(ADSB_VEHICLE, adsb_payload(r))
        return self._frame(UTM_GLOBAL_POSITION, utm_payload(r))

    def own_position(self, r: OwnPositionReport) -> bytes:
        """UTM_GLOBAL_POSITION of the vehicle's own estimate and intent (``traffic_codec.own_position_payload``)."""
        return self._frame(UTM_GLOBAL_POSITION, own_position_payload(r))

    def encode(self, msg: WireMessage) -> bytes:
        """Any wire message -> one frame (dispatch on type)."""
        return _ENCODERS[type(msg)](self, msg)


_ENCODERS: dict[type, Callable[[Encoder, WireMessage], bytes]] = {
    Heartbeat: Encoder.heartbeat,
    SensorSample: Encoder.sensor,
    GpsSample: Encoder.gps,
    GroundTruth: Encoder.truth,
    ObstacleDetection: Encoder.detection,
    ActuatorCommand: Encoder.actuators,
    TrafficReport: Encoder.traffic,
}


def make_mavlink(
    system_id: int,
    component_id: int,
    *,
    signing_key: bytes | None = None,
    link_id: int = 0,
    allow_unsigned: Callable[[object, int], bool] | None = None,
) -> _dialect.MAVLink:
    """A pymavlink ``MAVLink`` protocol object (ardupilotmega dialect, MAVLink 2) for GCS/API links.

    With ``signing_key`` (32 bytes) outgoing frames are signed and incoming unsigned frames
    are rejected unless ``allow_unsigned(mav, msg_id)`` returns True (pymavlink semantics).
    Feed it datagrams with ``mav.parse_buffer(data)``; encode with ``msg.pack(mav)``.
    """
    mav = _dialect.MAVLink(None, srcSystem=system_id, srcComponent=component_id)
    mav.robust_parsing = True
    if signing_key is not None:
        if len(signing_key) != 32:
            raise ValueError("MAVLink 2 signing keys are 32 bytes")
        mav.signing.secret_key = signing_key
        mav.signing.link_id = link_id
        mav.signing.sign_outgoing = True
        mav.signing.allow_unsigned_callback = allow_unsigned
    return mav
