"""Compiled fast path of ``codec.Decoder`` for lockstep datagrams (SPEC §4).

Per control step the autopilot decodes HIL_STATE_QUATERNION + HIL_SENSOR (+ HIL_GPS at 10 Hz,
+ OBSTACLE_DISTANCE_3D) and the simulator decodes one HIL_ACTUATOR_CONTROLS. In Python the
framing, the two CRC calls and the ``struct`` unpacking of each message cost more than building
the wire dataclass itself, so one numba kernel (``read_rows``) checks every frame of the datagram
and writes each message's decoded, already-scaled fields as one float64 row; ``codec.Decoder``
then only builds the dataclasses from those rows.

The kernel takes only the common, well-formed case: unsigned MAVLink 2 frames of exactly the
messages above (OBSTACLE_DISTANCE_3D in MAV_FRAME_BODY_FRD), each with a valid CRC, filling the
datagram. For anything else (MAVLink 1, signatures, other messages, garbage, bad CRC, a truncated
tail, more messages than ``VALUES_LEN`` has room for) it returns ``FALLBACK`` and the decoder runs its Python
loop over the whole datagram, so counters and results are the same either way.
``tests/mavlink_bridge/wire/test_bridge_frame_reader.py`` checks it against the Python decoders bit for bit.

Scaling is the same floating-point operations as the Python decoders (``x / 1e7``, ``x / 1000.0``,
``x * g`` with the same ``g``), so the results are identical, not just close.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from mavlink_bridge.contract.frames import DEG_E7, GRAVITY_M_S2

#: Message kinds (the code before each message's values).
KIND_SENSOR = 1
KIND_GPS = 2
KIND_TRUTH = 3
KIND_DETECTION = 4
KIND_ACTUATORS = 5
#: Room for decoded values in the ``out`` buffer: 16 messages of the longest kind, then system and component id.
VALUES_LEN = 16 * 18 + 2
#: ``out`` also holds the zero-padded payload being read (88 bytes = 11 float64) after the values, so a call
#: allocates nothing.
_SCRATCH_FLOATS = 11
OUT_LEN = VALUES_LEN + _SCRATCH_FLOATS
#: ``read_values`` result when the datagram needs the Python decoder.
FALLBACK = -1

# message id, crc_extra and full payload length (pymavlink ardupilotmega dialect; checked by the tests)
_ID_SENSOR, _CRC_SENSOR, _LEN_SENSOR = 107, 108, 65
_ID_GPS, _CRC_GPS, _LEN_GPS = 113, 124, 39
_ID_TRUTH, _CRC_TRUTH, _LEN_TRUTH = 115, 4, 64
_ID_DETECTION, _CRC_DETECTION, _LEN_DETECTION = 11037, 130, 28
_ID_ACTUATORS, _CRC_ACTUATORS, _LEN_ACTUATORS = 93, 47, 81
_MAV_FRAME_BODY_FRD = 12
_GRIPPER_CHANNEL = 8
_UINT16_UNKNOWN = 0xFFFF
_TWO_POW_53 = 2**53
_G_PER_MG = GRAVITY_M_S2 / 1000.0  # the Python decoder's ``g``


@njit(cache=True)
def _crc_x25(data: np.ndarray, start: int, end: int, crc: int) -> int:
    """CRC-16/MCRF4XX (MAVLink X.25) of ``data[start:end]`` continuing from ``crc``."""
    for i in range(start, end):
        tmp = (int(data[i]) ^ crc) & 0xFF
        tmp = (tmp ^ (tmp << 4)) & 0xFF
        crc = ((crc >> 8) ^ (tmp << 8) ^ (tmp << 3) ^ (tmp >> 4)) & 0xFFFF
    return crc


@njit(cache=True)
def _accumulate_crc_extra(crc: int, extra: int) -> int:
    tmp = (extra ^ crc) & 0xFF
    tmp = (tmp ^ (tmp << 4)) & 0xFF
    return ((crc >> 8) ^ (tmp << 8) ^ (tmp << 3) ^ (tmp >> 4)) & 0xFFFF


@njit(cache=True)
def read_values(data: bytes, out: np.ndarray) -> int:
    """Decode every frame of ``data`` into ``out`` (1-D float64): per message its kind code then its
    fields; after the last message the system and component id of the last frame. Returns the number
    of values written before those two ids, or ``FALLBACK``.

    Field layouts (times are exact integers as float64):
    sensor: t, ax, ay, az, gx, gy, gz, mx, my, mz, abs_pressure, pressure_alt, temperature;
    gps: t, lat_deg, lon_deg, alt_m, vn, ve, vd, eph_m, epv_m, fix_type, satellites;
    truth: t, qw, qx, qy, qz, p, q, r, lat_deg, lon_deg, alt_m, vx, vy, vz, ax, ay, az;
    detection: t_us, obstacle_id, x, y, z, radius_m, sensor_type;
    actuators: t, flags, c0, c1, c2, c3, gripper, mode.
    """
    n = len(data)
    # one zero-padded payload at the tail of out (8-byte aligned; MAVLink 2 orders fields by size: all aligned)
    scratch = out[VALUES_LEN:].view(np.uint8)
    u64 = scratch.view(np.uint64)
    f32 = scratch.view(np.float32)
    i32 = scratch.view(np.int32)
    u32 = scratch.view(np.uint32)
    i16 = scratch.view(np.int16)
    u16 = scratch.view(np.uint16)
    k = 0  # next value in out
    i = 0
    system_id = component_id = 0
    if n == 0:
        return FALLBACK
    while i < n:
        if n - i < 12 or data[i] != 0xFD or data[i + 2] != 0 or k + 20 > VALUES_LEN:
            return FALLBACK
        plen = int(data[i + 1])
        msg_id = int(data[i + 7]) | (int(data[i + 8]) << 8) | (int(data[i + 9]) << 16)
        if msg_id == _ID_SENSOR:
            extra, size, kind = _CRC_SENSOR, _LEN_SENSOR, KIND_SENSOR
        elif msg_id == _ID_TRUTH:
            extra, size, kind = _CRC_TRUTH, _LEN_TRUTH, KIND_TRUTH
        elif msg_id == _ID_GPS:
            extra, size, kind = _CRC_GPS, _LEN_GPS, KIND_GPS
        elif msg_id == _ID_ACTUATORS:
            extra, size, kind = _CRC_ACTUATORS, _LEN_ACTUATORS, KIND_ACTUATORS
        elif msg_id == _ID_DETECTION:
            extra, size, kind = _CRC_DETECTION, _LEN_DETECTION, KIND_DETECTION
        else:
            return FALLBACK
        end = i + 10 + plen
        if end + 2 > n:
            return FALLBACK
        crc = _accumulate_crc_extra(_crc_x25(data, i + 1, end, 0xFFFF), extra)
        if (int(data[end]) | (int(data[end + 1]) << 8)) != crc:
            return FALLBACK
        take = min(plen, size)
        for j in range(take):
            scratch[j] = data[i + 10 + j]
        for j in range(take, size):
            scratch[j] = 0
        out[k] = kind
        if kind != KIND_DETECTION:  # all but OBSTACLE_DISTANCE_3D start with time_usec (uint64)
            t = u64[0]
            if t >= _TWO_POW_53:
                return FALLBACK
            out[k + 1] = float(t)
        if kind == KIND_SENSOR:  # <Q f*13 I B: diff pressure, fields_updated and id are not read
            for j in range(9):
                out[k + 2 + j] = f32[2 + j]
            out[k + 11] = f32[11]  # abs_pressure
            out[k + 12] = f32[13]  # pressure_alt
            out[k + 13] = f32[14]  # temperature
        elif kind == KIND_TRUTH:  # <Q 4f f f f i i i h h h H H h h h
            for j in range(7):
                out[k + 2 + j] = f32[2 + j]
            out[k + 9] = i32[9] / DEG_E7
            out[k + 10] = i32[10] / DEG_E7
            out[k + 11] = i32[11] / 1000.0
            out[k + 12] = i16[24] / 100.0
            out[k + 13] = i16[25] / 100.0
            out[k + 14] = i16[26] / 100.0
            out[k + 15] = i16[29] * _G_PER_MG
            out[k + 16] = i16[30] * _G_PER_MG
            out[k + 17] = i16[31] * _G_PER_MG
        elif kind == KIND_GPS:  # <Q i i i H H H h h h H B B B H
            out[k + 2] = i32[2] / DEG_E7
            out[k + 3] = i32[3] / DEG_E7
            out[k + 4] = i32[4] / 1000.0
            out[k + 5] = i16[13] / 100.0
            out[k + 6] = i16[14] / 100.0
            out[k + 7] = i16[15] / 100.0
            eph, epv = u16[10], u16[11]
            out[k + 8] = np.inf if eph == _UINT16_UNKNOWN else eph / 100.0
            out[k + 9] = np.inf if epv == _UINT16_UNKNOWN else epv / 100.0
            out[k + 10] = scratch[34]
            out[k + 11] = scratch[35]
        elif kind == KIND_ACTUATORS:  # <Q Q 16f B
            out[k + 2] = float(u64[1] & 0xFF)  # flags: only the lockstep bit is read
            for j in range(4):
                out[k + 3 + j] = f32[4 + j]
            out[k + 7] = f32[4 + _GRIPPER_CHANNEL]
            out[k + 8] = scratch[80]
        else:  # detection: <I f f f f f H B B
            if scratch[27] != _MAV_FRAME_BODY_FRD:
                return FALLBACK
            out[k + 1] = float(u32[0]) * 1000.0
            out[k + 2] = u16[12]
            out[k + 3] = f32[1]
            out[k + 4] = f32[2]
            out[k + 5] = f32[3]
            out[k + 6] = np.float64(f32[5]) - np.float64(f32[4])  # in double, as the Python decoder
            out[k + 7] = scratch[26]
        k += 1 + _field_count(kind)
        system_id, component_id = data[i + 5], data[i + 6]
        i = end + 2
    out[k] = system_id
    out[k + 1] = component_id
    return k


@njit(cache=True)
def _field_count(kind: int) -> int:
    """Values after the kind code (see ``read_values``)."""
    if kind == KIND_SENSOR:
        return 13
    if kind == KIND_TRUTH:
        return 17
    if kind == KIND_GPS:
        return 11
    if kind == KIND_ACTUATORS:
        return 8
    return 7


def new_out() -> np.ndarray:
    """The ``out`` buffer ``read_values`` writes (one per decoder)."""
    return np.zeros(OUT_LEN)
