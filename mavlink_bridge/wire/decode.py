"""Decoding lockstep datagrams: MAVLink 1/2 bytes -> the typed wire contract; never raises on input.

Malformed, truncated or random bytes are counted in ``DecoderStats`` and dropped.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from mavlink_bridge.contract.frames import DEG_E7, GRAVITY_M_S2
from mavlink_bridge.contract.wire import (
    ACTUATOR_FLAG_LOCKSTEP,
    ACTUATOR_MODE_ARMED,
    ActuatorCommand,
    GpsSample,
    GroundTruth,
    ObstacleDetection,
    ObstacleShape,
    SensorSample,
)
from mavlink_bridge.wire.framing import (
    _ACTUATORS_PAYLOAD,
    _HEARTBEAT,
    _HIL_ACTUATORS,
    _HIL_GPS,
    _HIL_SENSOR,
    _HIL_STATE_Q,
    _IFLAG_SIGNED,
    _KNOWN,
    _OBSTACLE_3D,
    _PAD,
    _SIGNATURE_LEN,
    _UINT16_UNKNOWN,
    _V1_HEADER,
    _V1_HEADER_LEN,
    _V1_MAGIC,
    _V2_HEADER_IN,
    _V2_HEADER_LEN,
    _V2_MAGIC,
    MAV_FRAME_BODY_FRD,
    Heartbeat,
    WireMessage,
    _crc_mcrf4xx,
)
from mavlink_bridge.wire.traffic_codec import ADSB_VEHICLE, UTM_GLOBAL_POSITION, decode_adsb, decode_utm


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
    ADSB_VEHICLE.msg_id: decode_adsb,
    UTM_GLOBAL_POSITION.msg_id: decode_utm,
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


class _TruthBuilder:
    """Plain twin of :class:`GroundTruth` (same slots), filled by attribute and re-classed: building a frozen
    slotted dataclass costs a descriptor call per field, every frame (``autopilot.estimation.truth._StateBuilder``
    explains the pattern)."""

    __slots__ = GroundTruth.__slots__


class _SensorBuilder:
    """Plain twin of :class:`SensorSample` (see :class:`_TruthBuilder`)."""

    __slots__ = SensorSample.__slots__


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
            from mavlink_bridge.wire import frame_reader  # here, not at the top: it imports numba (GCS tools need not)

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
                t = _TruthBuilder()
                t.time_us = int(v[k + 1])
                t.q_ned_frd = (v[k + 2], v[k + 3], v[k + 4], v[k + 5])
                t.rate_frd_rad_s = (v[k + 6], v[k + 7], v[k + 8])
                t.lat_deg, t.lon_deg, t.alt_amsl_m = v[k + 9], v[k + 10], v[k + 11]
                t.vel_ned_m_s = (v[k + 12], v[k + 13], v[k + 14])
                t.accel_frd_m_s2 = (v[k + 15], v[k + 16], v[k + 17])
                t.__class__ = GroundTruth  # type: ignore[assignment]
                out.append(t)  # type: ignore[arg-type]
                k += 18
            elif kind == 1.0:  # KIND_SENSOR
                s = _SensorBuilder()
                s.time_us = int(v[k + 1])
                s.accel_frd_m_s2 = (v[k + 2], v[k + 3], v[k + 4])
                s.gyro_frd_rad_s = (v[k + 5], v[k + 6], v[k + 7])
                s.mag_frd_gauss = (v[k + 8], v[k + 9], v[k + 10])
                s.abs_pressure_hpa, s.pressure_alt_m, s.temperature_degc = v[k + 11], v[k + 12], v[k + 13]
                s.__class__ = SensorSample  # type: ignore[assignment]
                out.append(s)  # type: ignore[arg-type]
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
