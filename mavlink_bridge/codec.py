"""MAVLink 2 bytes <-> the typed wire contract of ``mavlink_bridge.contract.wire`` (SPEC §4).

The only place that converts the sim<->autopilot dataclasses to and from MAVLink. Message
layouts (ids, CRC extras, field order, struct formats) come from pymavlink's
``ardupilotmega`` dialect (a superset of ``common`` that also defines OBSTACLE_DISTANCE_3D);
framing is done here with precompiled ``struct`` objects and a C-speed CRC (``fastcrc``, a
dependency of pymavlink) because pymavlink's pure-Python CRC and parser cost ~25 µs / ~50 µs
per frame, which would dominate the lockstep loop. Payloads are unpacked in place from the
datagram (no copy unless MAVLink 2 truncated trailing zeros). ``tests/test_bridge_codec.py``
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
"""

from __future__ import annotations

import math
import struct
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from fastcrc import crc16 as _crc16
from pymavlink.dialects.v20 import ardupilotmega as _dialect

from mavlink_bridge.contract.frames import DEG_E7, GRAVITY_M_S2
from mavlink_bridge.contract.wire import (
    ACTUATOR_FLAG_LOCKSTEP,
    ACTUATOR_MODE_ARMED,
    GRIPPER_CHANNEL,
    ActuatorCommand,
    GpsSample,
    GroundTruth,
    ObstacleDetection,
    ObstacleShape,
    SensorSample,
)

#: HIL_SENSOR.fields_updated for a full sample: accel, gyro, mag (bits 0-8), abs pressure (9),
#: pressure alt (11), temperature (12); no differential pressure (10).
HIL_SENSOR_FIELDS_ALL = 0x1BFF
MAV_FRAME_BODY_FRD = _dialect.MAV_FRAME_BODY_FRD
MAV_TYPE_QUADROTOR = _dialect.MAV_TYPE_QUADROTOR
MAV_AUTOPILOT_PX4 = _dialect.MAV_AUTOPILOT_PX4
#: The system and component ids the simulator sends with (the autopilot is 1/1, SPEC §3).
SIM_SYSTEM_ID = 1
SIM_COMPONENT_ID = _dialect.MAV_COMP_ID_SYSTEM_CONTROL
AUTOPILOT_SYSTEM_ID = 1
AUTOPILOT_COMPONENT_ID = _dialect.MAV_COMP_ID_AUTOPILOT1

_HIL_CONTROLS_COUNT = 16
#: HIL_ACTUATOR_CONTROLS payload (time_usec, flags, controls[16], mode) with only the channels we send as
#: arguments: the motors (0-3) and the gripper; pad bytes are the zero floats of the unused channels.
_ACTUATORS_PAYLOAD = struct.Struct(
    f"<QQ4f{4 * (GRIPPER_CHANNEL - 4)}xf{4 * (_HIL_CONTROLS_COUNT - GRIPPER_CHANNEL - 1)}xB"
)
_UINT16_UNKNOWN = 0xFFFF


@dataclass(frozen=True, slots=True)
class Heartbeat:
    """A HEARTBEAT (the autopilot sends one to start the lockstep, SPEC §4)."""

    mav_type: int = MAV_TYPE_QUADROTOR
    autopilot: int = MAV_AUTOPILOT_PX4
    base_mode: int = 0
    custom_mode: int = 0
    system_status: int = _dialect.MAV_STATE_STANDBY


WireMessage = SensorSample | GpsSample | GroundTruth | ObstacleDetection | ActuatorCommand | Heartbeat


# --- CRC-16/MCRF4XX (X.25, the MAVLink checksum) at C speed -----------------------------------
# checksum = crc(crc_extra byte, crc(header without magic + payload)): two C calls per frame
_crc_mcrf4xx = _crc16.mcrf4xx  # (data, initial=0xFFFF) -> int


# --- message layouts from pymavlink ------------------------------------------------------------
@dataclass(frozen=True, slots=True)
class _Layout:
    msg_id: int
    crc_extra: bytes  # one byte
    payload: struct.Struct  # full MAVLink 2 payload, wire order
    id_lo16: int
    id_hi8: int


def _layout(cls: type) -> _Layout:
    return _Layout(cls.id, bytes((cls.crc_extra,)), cls.unpacker, cls.id & 0xFFFF, cls.id >> 16)


_HEARTBEAT = _layout(_dialect.MAVLink_heartbeat_message)
_HIL_SENSOR = _layout(_dialect.MAVLink_hil_sensor_message)
_HIL_GPS = _layout(_dialect.MAVLink_hil_gps_message)
_HIL_STATE_Q = _layout(_dialect.MAVLink_hil_state_quaternion_message)
_OBSTACLE_3D = _layout(_dialect.MAVLink_obstacle_distance_3d_message)
_HIL_ACTUATORS = _layout(_dialect.MAVLink_hil_actuator_controls_message)
#: crc_extra and full payload length of every message the dialect knows (CRC checks).
_KNOWN: dict[int, tuple[bytes, int]] = {
    msg_id: (bytes((cls.crc_extra,)), cls.unpacker.size) for msg_id, cls in _dialect.mavlink_map.items()
}
#: zero padding that restores a payload MAVLink 2 truncated by k trailing zero bytes: ``_PAD[k]``.
_PAD = tuple(bytes(k) for k in range(256))

_V2_HEADER = struct.Struct("<BBBBBBBHB")  # magic, len, incompat, compat, seq, sys, comp, id lo16, id hi8
_V2_HEADER_LEN = _V2_HEADER.size  # 10
_V2_HEADER_IN = struct.Struct("<xBBxxBBHB")  # what decoding reads: len, incompat, sys, comp, id lo16, id hi8
_V1_HEADER = struct.Struct("<BBBBBB")  # magic, len, seq, sys, comp, id
_V1_HEADER_LEN = _V1_HEADER.size  # 6
_CRC = struct.Struct("<H")
_V2_MAGIC = 0xFD
_V1_MAGIC = 0xFE
_IFLAG_SIGNED = 0x01
_SIGNATURE_LEN = 13


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
}


# --- decoding -----------------------------------------------------------------------------------
def _decode_heartbeat(buf: bytes, at: int) -> Heartbeat:
    custom_mode, mav_type, autopilot, base_mode, status, _version = _HEARTBEAT.payload.unpack_from(buf, at)
    return Heartbeat(mav_type, autopilot, base_mode, custom_mode, status)


def _decode_sensor(buf: bytes, at: int) -> SensorSample:
    t, ax, ay, az, gx, gy, gz, mx, my, mz, press, _diff, palt, temp, _fields, _id = _HIL_SENSOR.payload.unpack_from(
        buf, at
    )
    return SensorSample(t, (ax, ay, az), (gx, gy, gz), (mx, my, mz), press, palt, temp)


def _decode_gps(buf: bytes, at: int) -> GpsSample:
    t, lat, lon, alt, eph, epv, _vel, vn, ve, vd, _cog, fix, sats, _id, _yaw = _HIL_GPS.payload.unpack_from(buf, at)
    return GpsSample(
        t,
        lat / DEG_E7,
        lon / DEG_E7,
        alt / 1000.0,
        (vn / 100.0, ve / 100.0, vd / 100.0),
        math.inf if eph == _UINT16_UNKNOWN else eph / 100.0,
        math.inf if epv == _UINT16_UNKNOWN else epv / 100.0,
        fix,
        sats,
    )


def _decode_truth(buf: bytes, at: int) -> GroundTruth:
    t, qw, qx, qy, qz, p_, q_, r_, lat, lon, alt, vx, vy, vz, _ias, _tas, ax, ay, az = _HIL_STATE_Q.payload.unpack_from(
        buf, at
    )
    g = GRAVITY_M_S2 / 1000.0
    return GroundTruth(
        t,
        (qw, qx, qy, qz),
        (p_, q_, r_),
        lat / DEG_E7,
        lon / DEG_E7,
        alt / 1000.0,
        (vx / 100.0, vy / 100.0, vz / 100.0),
        (ax * g, ay * g, az * g),
    )


_SHAPES = {int(s): s for s in ObstacleShape}


def _decode_detection(buf: bytes, at: int) -> ObstacleDetection | None:
    t_ms, x, y, z, dmin, dmax, obstacle_id, sensor_type, frame = _OBSTACLE_3D.payload.unpack_from(buf, at)
    if frame != MAV_FRAME_BODY_FRD:
        return None
    return ObstacleDetection(
        t_ms * 1000, obstacle_id, (x, y, z), dmax - dmin, _SHAPES.get(sensor_type, ObstacleShape.UNKNOWN)
    )


def _decode_actuators(buf: bytes, at: int) -> ActuatorCommand:
    t, flags, c0, c1, c2, c3, gripper, mode = _ACTUATORS_PAYLOAD.unpack_from(buf, at)  # unused channels skipped
    return ActuatorCommand(t, (c0, c1, c2, c3), bool(mode & ACTUATOR_MODE_ARMED), gripper >= 0.5, bool(flags & 1))


_DECODERS: dict[int, Callable[[bytes, int], WireMessage | None]] = {
    _HEARTBEAT.msg_id: _decode_heartbeat,
    _HIL_SENSOR.msg_id: _decode_sensor,
    _HIL_GPS.msg_id: _decode_gps,
    _HIL_STATE_Q.msg_id: _decode_truth,
    _OBSTACLE_3D.msg_id: _decode_detection,
    _HIL_ACTUATORS.msg_id: _decode_actuators,
}
#: msg id -> (crc_extra, full payload length, decoder ``(buffer, offset)`` or None) for every message of the dialect.
_TABLE: dict[int, tuple[bytes, int, Callable[[bytes, int], WireMessage | None] | None]] = {
    msg_id: (crc_rev, size, _DECODERS.get(msg_id)) for msg_id, (crc_rev, size) in _KNOWN.items()
}


@dataclass(slots=True)
class DecoderStats:
    """Counters of a ``Decoder`` (mutable; read them, do not write)."""

    decoded: int = 0  # frames turned into wire messages
    ignored: int = 0  # valid MAVLink frames of messages the wire contract does not map
    malformed: int = 0  # bad CRC, truncated frames, runs of bytes that are not MAVLink
    signed: int = 0  # frames that carried a MAVLink 2 signature (accepted, not verified here)


class Decoder:
    """Whole UDP datagrams -> wire messages. Never raises on input.

    Each datagram is parsed on its own (UDP keeps messages whole; a truncated tail is
    not joined with the next datagram). MAVLink 1 and 2 frames are accepted; signatures
    are skipped (the lockstep link is local and unsigned; GCS links that require signing
    use ``make_mavlink``). ``last_system_id``/``last_component_id`` are those of the last
    valid frame.
    """

    __slots__ = ("_read_values", "_values", "last_component_id", "last_system_id", "stats")

    def __init__(self, *, compiled: bool = True) -> None:
        """``compiled``: try ``frame_reader.read_values`` (numba) first on each datagram; False: Python only."""
        self.stats = DecoderStats()
        self.last_system_id = -1
        self.last_component_id = -1
        self._values: np.ndarray | None = None
        self._read_values: Callable[[bytes, np.ndarray], int] | None = None
        if compiled:
            from mavlink_bridge import frame_reader  # here, not at the top: it imports numba (GCS tools need not)

            self._values = frame_reader.new_out()
            self._read_values = frame_reader.read_values
            self._read_values(b"", self._values)  # load the compiled kernel now, not on the first lockstep frame

    def decode(self, data: bytes) -> list[WireMessage]:
        """All wire messages in one datagram, in order."""
        values = self._values
        if values is not None and len(data) >= _COMPILED_MIN_BYTES:
            n = self._read_values(data, values)  # type: ignore[misc]
            if n > 0:
                return self._from_values(values[: n + 2].tolist())
        return self._decode_python(data)

    def _from_values(self, v: list[float]) -> list[WireMessage]:
        """The wire messages of ``frame_reader.read_values`` output (same values as the ``_decode_*`` functions)."""
        out: list[WireMessage] = []
        k, n = 0, len(v) - 2
        while k < n:
            kind = v[k]
            if kind == 3.0:  # KIND_TRUTH
                q, w = (v[k + 2], v[k + 3], v[k + 4], v[k + 5]), (v[k + 6], v[k + 7], v[k + 8])
                vel, acc = (v[k + 12], v[k + 13], v[k + 14]), (v[k + 15], v[k + 16], v[k + 17])
                out.append(GroundTruth(int(v[k + 1]), q, w, v[k + 9], v[k + 10], v[k + 11], vel, acc))
                k += 18
            elif kind == 1.0:  # KIND_SENSOR
                a, g, m = (
                    (v[k + 2], v[k + 3], v[k + 4]),
                    (v[k + 5], v[k + 6], v[k + 7]),
                    (v[k + 8], v[k + 9], v[k + 10]),
                )
                out.append(SensorSample(int(v[k + 1]), a, g, m, v[k + 11], v[k + 12], v[k + 13]))
                k += 14
            elif kind == 5.0:  # KIND_ACTUATORS
                motors = (v[k + 3], v[k + 4], v[k + 5], v[k + 6])
                armed, lockstep = (
                    bool(int(v[k + 8]) & ACTUATOR_MODE_ARMED),
                    bool(int(v[k + 2]) & ACTUATOR_FLAG_LOCKSTEP),
                )
                out.append(ActuatorCommand(int(v[k + 1]), motors, armed, v[k + 7] >= 0.5, lockstep))
                k += 9
            elif kind == 2.0:  # KIND_GPS
                vel = (v[k + 5], v[k + 6], v[k + 7])
                fix, sats = int(v[k + 10]), int(v[k + 11])
                out.append(GpsSample(int(v[k + 1]), v[k + 2], v[k + 3], v[k + 4], vel, v[k + 8], v[k + 9], fix, sats))
                k += 12
            else:  # KIND_DETECTION
                shape = _SHAPES.get(int(v[k + 7]), ObstacleShape.UNKNOWN)
                out.append(
                    ObstacleDetection(int(v[k + 1]), int(v[k + 2]), (v[k + 3], v[k + 4], v[k + 5]), v[k + 6], shape)
                )
                k += 8
        self.last_system_id = int(v[n])
        self.last_component_id = int(v[n + 1])
        self.stats.decoded += len(out)
        return out

    def _decode_python(self, data: bytes) -> list[WireMessage]:
        """``decode`` in Python: every MAVLink 1/2 frame, signatures skipped, garbage counted."""
        out: list[WireMessage] = []
        view = memoryview(data)
        n = len(data)
        i = 0
        decoded = ignored = signed = 0
        system_id = component_id = -1
        while i < n:
            magic = data[i]
            if magic == _V2_MAGIC and n - i >= _V2_HEADER_LEN + 2:
                plen, incompat, sys_id, comp_id, id_lo, id_hi = _V2_HEADER_IN.unpack_from(data, i)
                msg_id = id_lo | (id_hi << 16)
                start = i + _V2_HEADER_LEN
            elif magic == _V1_MAGIC and n - i >= _V1_HEADER_LEN + 2:
                _, plen, _, sys_id, comp_id, msg_id = _V1_HEADER.unpack_from(data, i)
                incompat = 0
                start = i + _V1_HEADER_LEN
            else:
                i = self._resync(data, i + 1)
                continue
            end = start + plen
            frame_end = end + 2 + (_SIGNATURE_LEN if incompat & _IFLAG_SIGNED else 0)
            entry = _TABLE.get(msg_id)
            if (
                entry is None
                or incompat & ~_IFLAG_SIGNED
                or frame_end > n
                or data[end] | (data[end + 1] << 8) != _crc_mcrf4xx(entry[0], _crc_mcrf4xx(view[i + 1 : end]))
            ):
                i = self._resync(data, i + 1)
                continue
            i = frame_end
            system_id, component_id = sys_id, comp_id
            if incompat:
                signed += 1
            _, size, fn = entry
            if fn is None:
                ignored += 1
                continue
            # in place when nothing was truncated (longer: extensions we do not read), else zero-padded
            msg = fn(data, start) if plen >= size else fn(data[start:end] + _PAD[size - plen], 0)
            if msg is None:
                ignored += 1
            else:
                decoded += 1
                out.append(msg)
        if system_id >= 0:
            self.last_system_id = system_id
            self.last_component_id = component_id
        stats = self.stats
        stats.decoded += decoded
        stats.ignored += ignored
        stats.signed += signed
        return out

    def _resync(self, data: bytes, start: int) -> int:
        """Skip to the next possible frame start; one malformed count per skipped run."""
        self.stats.malformed += 1
        v2 = data.find(b"\xfd", start)
        v1 = data.find(b"\xfe", start)
        if v2 < 0 and v1 < 0:
            return len(data)
        if v2 < 0 or (0 <= v1 < v2):
            return v1
        return v2


#: Shortest datagram handed to the compiled reader: calling a numba kernel costs about as much as the
#: Python loop spends on one message, so it only pays for two or more (a lockstep frame; measured with
#: callgrind: 40 k vs 49 k instructions for HIL_STATE_QUATERNION + HIL_SENSOR, 22 k vs 20 k for one
#: HIL_ACTUATOR_CONTROLS).
_COMPILED_MIN_BYTES = 128


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
