"""The sim's lockstep datagram written in one numba call (SPEC §4): the implementation of the sim's encoding.

``FrameWriter`` writes the datagram from the flat float64 sensor-values array the simulator fills (laid out
by ``mavlink_bridge.contract.sensor_values``) into a preallocated buffer: HIL_GPS (when due),
HIL_STATE_QUATERNION, OBSTACLE_DISTANCE_3D (per detection), HIL_SENSOR last; MAVLink 2 header, one sequence
counter, trailing-zero truncation and CRC-16/MCRF4XX with crc_extra as ``codec.Encoder._frame``. Integer
conversions follow the codec: round half to even, saturation at the wire range, NaN -> 0 (or "unknown"),
the course-over-ground rule. A finite value too large for a float32 field raises ``OverflowError`` as
``struct.pack`` does.

``tests/sim/test_sim_frame_writer.py`` decodes its datagrams with pymavlink (the oracle: CRCs, layouts, scaling)
and checks NaN/inf, saturation and truncation.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from numba import njit

from mavlink_bridge.contract.frames import DEG_E7
from mavlink_bridge.contract.sensor_values import (
    D_OBSTACLE_ID,
    D_POS_FRD,
    D_RADIUS,
    D_SHAPE,
    D_TIME_US,
    N_DET,
    N_VALUES,
    V_ACCEL_FRD,
    V_ACCEL_TRUTH_FRD,
    V_ALT_AMSL,
    V_GPS_ALT_AMSL,
    V_GPS_EPH,
    V_GPS_EPV,
    V_GPS_FIX_TYPE,
    V_GPS_LAT_DEG,
    V_GPS_LON_DEG,
    V_GPS_SATELLITES,
    V_GPS_VEL_NED,
    V_LAT_DEG,
    V_LON_DEG,
    V_PRESSURE_ALT,
    V_PRESSURE_HPA,
    V_Q_NED_FRD,
    V_TEMPERATURE,
    V_VEL_NED,
)
from mavlink_bridge.contract.wire import ObstacleDetection
from mavlink_bridge.wire.codec import (
    _HIL_GPS,
    _HIL_SENSOR,
    _HIL_STATE_Q,
    _MG_PER_M_S2,
    _OBSTACLE_3D,
    HIL_SENSOR_FIELDS_ALL,
    MAV_FRAME_BODY_FRD,
    SIM_COMPONENT_ID,
    SIM_SYSTEM_ID,
)

# the payload layouts this writer hard-codes (wire order); a different pymavlink fails here, not on the wire
_FORMATS = {
    "HIL_SENSOR": (_HIL_SENSOR, "<QfffffffffffffIB"),
    "HIL_GPS": (_HIL_GPS, "<QiiiHHHhhhHBBBH"),
    "HIL_STATE_QUATERNION": (_HIL_STATE_Q, "<Q4ffffiiihhhHHhhh"),
    "OBSTACLE_DISTANCE_3D": (_OBSTACLE_3D, "<IfffffHBB"),
}
for _name, (_lay, _fmt) in _FORMATS.items():
    if _lay.payload.format != _fmt:  # pragma: no cover
        raise ImportError(f"{_name}: payload layout {_lay.payload.format} is not the {_fmt} frame_writer writes")

_HEADER_LEN = 10
#: longest datagram without detections: 3 headers + CRCs, full payloads
_BASE_LEN = 3 * (_HEADER_LEN + 2) + _HIL_GPS.payload.size + _HIL_STATE_Q.payload.size + _HIL_SENSOR.payload.size
_DETECTION_LEN = _HEADER_LEN + 2 + _OBSTACLE_3D.payload.size
# message ids, crc extras, full payload lengths (numba globals are compile-time constants)
_ID_SENSOR, _CRC_SENSOR, _LEN_SENSOR = _HIL_SENSOR.msg_id, _HIL_SENSOR.crc_extra[0], _HIL_SENSOR.payload.size
_ID_GPS, _CRC_GPS, _LEN_GPS = _HIL_GPS.msg_id, _HIL_GPS.crc_extra[0], _HIL_GPS.payload.size
_ID_STATE, _CRC_STATE, _LEN_STATE = _HIL_STATE_Q.msg_id, _HIL_STATE_Q.crc_extra[0], _HIL_STATE_Q.payload.size
_ID_OBST, _CRC_OBST, _LEN_OBST = _OBSTACLE_3D.msg_id, _OBSTACLE_3D.crc_extra[0], _OBSTACLE_3D.payload.size
_FIELDS_ALL = HIL_SENSOR_FIELDS_ALL
_FRAME_BODY_FRD = MAV_FRAME_BODY_FRD
_DEG_E7 = DEG_E7
_MG = _MG_PER_M_S2
_RAD_TO_DEG = 180.0 / math.pi  # math.degrees (same bits, checked by the tests)
_U16_UNKNOWN = 0xFFFF

# ints array (int64): inputs and the sequence counter (in/out)
I_TIME_US = 0
I_SEQ = 1
I_GPS_DUE = 2
I_SYSTEM_ID = 3
I_COMPONENT_ID = 4
N_INTS = 5
SCRATCH_LEN = 4


@njit(cache=True)
def buffer_len(n_detections: int) -> int:
    """Bytes of a frame buffer for ``n_detections`` detections (the longest datagram plus scratch)."""
    return _BASE_LEN + n_detections * _DETECTION_LEN + SCRATCH_LEN


@njit(cache=True)
def _sat(x: float, lo: int, hi: int) -> int:
    """``codec._sat``: round half to even, saturate to [lo, hi]; NaN -> 0 (or lo)."""
    if x != x:
        return 0 if lo <= 0 <= hi else lo
    if x >= hi:
        return hi
    if x <= lo:
        return lo
    return int(np.rint(x))


@njit(cache=True)
def _put_int(buf: np.ndarray, at: int, value: int, nbytes: int) -> None:
    """Little-endian two's complement of ``value`` in ``nbytes`` bytes."""
    for k in range(nbytes):
        buf[at + k] = (value >> (8 * k)) & 0xFF


@njit(cache=True)
def _put_f32(buf: np.ndarray, at: int, x: float, f32: np.ndarray, f32_bytes: np.ndarray) -> None:
    """IEEE float32 of ``x`` (rounded to nearest, as ``struct`` 'f'); a finite ``x`` out of range raises."""
    f32[0] = x
    if math.isinf(f32[0]) and not math.isinf(x):
        raise OverflowError("float too large to pack with f format")
    buf[at] = f32_bytes[0]
    buf[at + 1] = f32_bytes[1]
    buf[at + 2] = f32_bytes[2]
    buf[at + 3] = f32_bytes[3]


@njit(cache=True)
def _crc_accumulate(crc: int, b: int) -> int:
    tmp = b ^ (crc & 0xFF)
    tmp = (tmp ^ (tmp << 4)) & 0xFF
    return ((crc >> 8) ^ (tmp << 8) ^ (tmp << 3) ^ (tmp >> 4)) & 0xFFFF


@njit(cache=True)
def _finish(buf: np.ndarray, at: int, seq: int, sys_id: int, comp_id: int, msg_id: int, crc_extra: int, n: int) -> int:
    """Header, truncation and CRC of the frame whose full ``n``-byte payload is at ``at + 10``; returns its end."""
    start = at + _HEADER_LEN
    plen = n
    while plen > 1 and buf[start + plen - 1] == 0:  # MAVLink 2 drops trailing zeros (one byte stays)
        plen -= 1
    buf[at] = 0xFD
    buf[at + 1] = plen
    buf[at + 2] = 0
    buf[at + 3] = 0
    buf[at + 4] = seq & 0xFF
    buf[at + 5] = sys_id
    buf[at + 6] = comp_id
    buf[at + 7] = msg_id & 0xFF
    buf[at + 8] = (msg_id >> 8) & 0xFF
    buf[at + 9] = (msg_id >> 16) & 0xFF
    end = start + plen
    crc = 0xFFFF
    for k in range(at + 1, end):
        crc = _crc_accumulate(crc, buf[k])
    crc = _crc_accumulate(crc, crc_extra)
    buf[end] = crc & 0xFF
    buf[end + 1] = crc >> 8
    return end + 2


@njit(cache=True)
def write_frame(buf: np.ndarray, v: np.ndarray, ints: np.ndarray, det: np.ndarray) -> int:
    """The lockstep datagram of one control step into ``buf``; returns its length (``ints[I_SEQ]`` advances).

    ``v``: the ``V_*`` values (``N_VALUES``); ``ints``: the ``I_*`` integers; ``det`` (k, ``N_DET``): the detections
    (``D_*`` columns). The last ``SCRATCH_LEN`` bytes of ``buf`` are scratch (float32 conversion).
    """
    scratch = buf[buf.shape[0] - SCRATCH_LEN :]
    f32 = scratch.view(np.float32)
    f32b = scratch
    if buf.shape[0] < buffer_len(det.shape[0]):
        raise ValueError("frame buffer too small for the detections")
    if v.shape[0] < N_VALUES:
        raise ValueError("sensor values array shorter than N_VALUES")
    t_us = ints[I_TIME_US]
    seq = ints[I_SEQ]
    sys_id = ints[I_SYSTEM_ID]
    comp_id = ints[I_COMPONENT_ID]
    at = 0
    if ints[I_GPS_DUE] != 0:  # HIL_GPS, as codec.Encoder.gps
        p = at + _HEADER_LEN
        vn, ve, vd = v[V_GPS_VEL_NED], v[V_GPS_VEL_NED + 1], v[V_GPS_VEL_NED + 2]
        vn = vn if math.isfinite(vn) else 0.0
        ve = ve if math.isfinite(ve) else 0.0
        vd = vd if math.isfinite(vd) else 0.0
        speed_m_s = math.hypot(vn, ve)
        cog_deg = math.atan2(ve, vn) * _RAD_TO_DEG
        cog_cdeg = int(np.rint(cog_deg * 100.0)) % 36000 if speed_m_s > 0.0 else _U16_UNKNOWN
        eph, epv = v[V_GPS_EPH] * 100.0, v[V_GPS_EPV] * 100.0
        _put_int(buf, p, t_us, 8)
        _put_int(buf, p + 8, _sat(v[V_GPS_LAT_DEG] * _DEG_E7, -2147483648, 2147483647), 4)
        _put_int(buf, p + 12, _sat(v[V_GPS_LON_DEG] * _DEG_E7, -2147483648, 2147483647), 4)
        _put_int(buf, p + 16, _sat(v[V_GPS_ALT_AMSL] * 1000.0, -2147483648, 2147483647), 4)
        _put_int(buf, p + 20, _sat(eph, 0, _U16_UNKNOWN - 1) if math.isfinite(eph) else _U16_UNKNOWN, 2)
        _put_int(buf, p + 22, _sat(epv, 0, _U16_UNKNOWN - 1) if math.isfinite(epv) else _U16_UNKNOWN, 2)
        _put_int(buf, p + 24, _sat(speed_m_s * 100.0, 0, _U16_UNKNOWN - 1), 2)
        _put_int(buf, p + 26, _sat(vn * 100.0, -32768, 32767), 2)
        _put_int(buf, p + 28, _sat(ve * 100.0, -32768, 32767), 2)
        _put_int(buf, p + 30, _sat(vd * 100.0, -32768, 32767), 2)
        _put_int(buf, p + 32, cog_cdeg, 2)
        buf[p + 34] = _sat(v[V_GPS_FIX_TYPE], 0, 255)
        buf[p + 35] = _sat(v[V_GPS_SATELLITES], 0, 255)
        buf[p + 36] = 0  # id
        buf[p + 37] = 0  # yaw (2 bytes)
        buf[p + 38] = 0
        at = _finish(buf, at, seq, sys_id, comp_id, _ID_GPS, _CRC_GPS, _LEN_GPS)
        seq += 1
    # HIL_STATE_QUATERNION, as codec._truth_payload (saturating)
    p = at + _HEADER_LEN
    _put_int(buf, p, t_us, 8)
    for k in range(7):  # q (4), rates (3)
        _put_f32(buf, p + 8 + 4 * k, v[V_Q_NED_FRD + k], f32, f32b)
    _put_int(buf, p + 36, _sat(v[V_LAT_DEG] * _DEG_E7, -2147483648, 2147483647), 4)
    _put_int(buf, p + 40, _sat(v[V_LON_DEG] * _DEG_E7, -2147483648, 2147483647), 4)
    _put_int(buf, p + 44, _sat(v[V_ALT_AMSL] * 1000.0, -2147483648, 2147483647), 4)
    vx = _sat(v[V_VEL_NED] * 100.0, -32768, 32767)
    vy = _sat(v[V_VEL_NED + 1] * 100.0, -32768, 32767)
    vz = _sat(v[V_VEL_NED + 2] * 100.0, -32768, 32767)
    speed_cm_s = min(int(np.rint(math.sqrt(float(vx * vx + vy * vy + vz * vz)))), 65535)
    _put_int(buf, p + 48, vx, 2)
    _put_int(buf, p + 50, vy, 2)
    _put_int(buf, p + 52, vz, 2)
    _put_int(buf, p + 54, speed_cm_s, 2)
    _put_int(buf, p + 56, speed_cm_s, 2)
    _put_int(buf, p + 58, _sat(v[V_ACCEL_TRUTH_FRD] * _MG, -32768, 32767), 2)
    _put_int(buf, p + 60, _sat(v[V_ACCEL_TRUTH_FRD + 1] * _MG, -32768, 32767), 2)
    _put_int(buf, p + 62, _sat(v[V_ACCEL_TRUTH_FRD + 2] * _MG, -32768, 32767), 2)
    at = _finish(buf, at, seq, sys_id, comp_id, _ID_STATE, _CRC_STATE, _LEN_STATE)
    seq += 1
    for j in range(det.shape[0]):  # OBSTACLE_DISTANCE_3D, as codec.Encoder.detection
        p = at + _HEADER_LEN
        _put_int(buf, p, (int(det[j, D_TIME_US]) // 1000) & 0xFFFFFFFF, 4)
        _put_f32(buf, p + 4, det[j, D_POS_FRD], f32, f32b)
        _put_f32(buf, p + 8, det[j, D_POS_FRD + 1], f32, f32b)
        _put_f32(buf, p + 12, det[j, D_POS_FRD + 2], f32, f32b)
        _put_f32(buf, p + 16, 0.0, f32, f32b)
        _put_f32(buf, p + 20, det[j, D_RADIUS], f32, f32b)
        _put_int(buf, p + 24, int(det[j, D_OBSTACLE_ID]) & 0xFFFF, 2)
        buf[p + 26] = int(det[j, D_SHAPE])
        buf[p + 27] = _FRAME_BODY_FRD
        at = _finish(buf, at, seq, sys_id, comp_id, _ID_OBST, _CRC_OBST, _LEN_OBST)
        seq += 1
    # HIL_SENSOR, as codec.Encoder.sensor
    p = at + _HEADER_LEN
    _put_int(buf, p, t_us, 8)
    for k in range(9):  # accel, gyro, mag
        _put_f32(buf, p + 8 + 4 * k, v[V_ACCEL_FRD + k], f32, f32b)
    _put_f32(buf, p + 44, v[V_PRESSURE_HPA], f32, f32b)
    _put_f32(buf, p + 48, 0.0, f32, f32b)  # differential pressure
    _put_f32(buf, p + 52, v[V_PRESSURE_ALT], f32, f32b)
    _put_f32(buf, p + 56, v[V_TEMPERATURE], f32, f32b)
    _put_int(buf, p + 60, _FIELDS_ALL, 4)
    buf[p + 64] = 0  # id
    at = _finish(buf, at, seq, sys_id, comp_id, _ID_SENSOR, _CRC_SENSOR, _LEN_SENSOR)
    ints[I_SEQ] = (seq + 1) & 0xFF
    return at


def detection_rows(detections: Sequence[ObstacleDetection]) -> np.ndarray:
    """(k, ``N_DET``) rows of ``detections`` for ``write_frame``."""
    rows = np.zeros((len(detections), N_DET))
    for j, d in enumerate(detections):
        rows[j, D_POS_FRD : D_POS_FRD + 3] = d.pos_frd_m
        rows[j, D_RADIUS] = d.radius_m
        rows[j, D_TIME_US] = d.time_us
        rows[j, D_OBSTACLE_ID] = d.obstacle_id
        rows[j, D_SHAPE] = int(d.shape)
    return rows


class FrameWriter:
    """One sender's lockstep datagrams (its own sequence counter), from a sensor-values array filled by the sim.

    ``write`` packs into the preallocated ``buffer`` in one compiled call and returns the datagram's bytes.
    """

    __slots__ = ("buffer", "ints", "no_detections")

    def __init__(self, system_id: int = SIM_SYSTEM_ID, component_id: int = SIM_COMPONENT_ID) -> None:
        self.ints = np.zeros(N_INTS, dtype=np.int64)
        self.ints[I_SYSTEM_ID] = system_id
        self.ints[I_COMPONENT_ID] = component_id
        self.buffer = np.zeros(buffer_len(0), dtype=np.uint8)
        self.no_detections = np.zeros((0, N_DET))

    @property
    def seq(self) -> int:
        """Sequence number of the next frame (0-255)."""
        return int(self.ints[I_SEQ])

    def detections(self, detections: Sequence[ObstacleDetection]) -> np.ndarray:
        """``detection_rows`` (``no_detections`` when empty), growing ``buffer`` to hold them."""
        if not detections:
            return self.no_detections
        if self.buffer.shape[0] < buffer_len(len(detections)):
            self.buffer = np.zeros(buffer_len(len(detections)), dtype=np.uint8)
        return detection_rows(detections)

    def write(
        self, values: np.ndarray, time_us: int, gps_due: bool, detections: Sequence[ObstacleDetection] = ()
    ) -> bytes:
        """The datagram of ``values`` (``N_VALUES`` long) at ``time_us``: HIL_GPS (if ``gps_due``),
        HIL_STATE_QUATERNION, OBSTACLE_DISTANCE_3D per detection, HIL_SENSOR last."""
        ints = self.ints
        ints[I_TIME_US] = time_us
        ints[I_GPS_DUE] = gps_due
        det = self.detections(detections) if detections else self.no_detections
        n = write_frame(self.buffer, values, ints, det)
        return self.buffer[:n].tobytes()
