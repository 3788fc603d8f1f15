"""The lockstep answer (HIL_ACTUATOR_CONTROLS) written and read in one compiled call each, in preallocated arrays.

``write_answer`` writes the autopilot's answer into a preallocated datagram buffer (MAVLink 2, trailing-zero
truncation, CRC; the bytes of ``codec.Encoder.actuators``), so each step sends from the same buffer without
building a payload. ``read_answer`` checks a received datagram in place (one unsigned MAVLink 2
HIL_ACTUATOR_CONTROLS, CRC, the frame time echoed, motors finite and in [0, 1]) and writes the values the
simulator applies into a preallocated array (``A_*`` indices). Anything else returns ``ANSWER_OTHER`` and the
caller runs the Python decoder (HEARTBEATs, MAVLink 1, signed frames, garbage: counted there as before).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from mavlink_bridge.wire.frame_reader import _accumulate_crc_extra, _crc_x25
from mavlink_bridge.wire.frame_writer import SCRATCH_LEN, _finish, _put_f32, _put_int

_ID_ACTUATORS, _CRC_ACTUATORS, _LEN_ACTUATORS = 93, 47, 81  # checked against pymavlink by the tests
_GRIPPER_CHANNEL = 8
_MODE_ARMED = 128
_FLAG_LOCKSTEP = 1
_TWO_POW_53 = 2**53
#: Bytes of an answer buffer: header, full payload, CRC, float32 scratch.
ANSWER_BUFFER_LEN = 10 + _LEN_ACTUATORS + 2 + SCRATCH_LEN

# read_answer results
ANSWER_OTHER = 0  # not a single plain HIL_ACTUATOR_CONTROLS: decode it in Python
ANSWER_OK = 1  # the answer to the expected frame, values in ``out``
ANSWER_STALE = 2  # an answer to an older frame
ANSWER_INVALID = 3  # stamped ahead of the frame, or motors NaN / outside [0, 1]

# out array (float64)
A_MOTORS = 0  # 4, in [0, 1]
A_ARMED = 4  # 1.0 or 0.0
A_GRIPPER_RELEASE = 5  # 1.0 or 0.0
N_ANSWER = 6


@njit(cache=True)
def write_answer(
    buf: np.ndarray,
    time_us: int,
    m0: float,
    m1: float,
    m2: float,
    m3: float,
    armed: bool,
    gripper_release: bool,
    lockstep: bool,
    seq: int,
    system_id: int,
    component_id: int,
) -> int:
    """HIL_ACTUATOR_CONTROLS into ``buf`` (``ANSWER_BUFFER_LEN``); returns the datagram length.

    The motors come as four scalars: numba types a tuple argument element by element on every call.
    """
    scratch = buf[buf.shape[0] - SCRATCH_LEN :]
    f32 = scratch.view(np.float32)
    p = 10
    _put_int(buf, p, time_us, 8)
    _put_int(buf, p + 8, _FLAG_LOCKSTEP if lockstep else 0, 8)
    _put_f32(buf, p + 16, m0, f32, scratch)
    _put_f32(buf, p + 20, m1, f32, scratch)
    _put_f32(buf, p + 24, m2, f32, scratch)
    _put_f32(buf, p + 28, m3, f32, scratch)
    for k in range(4, 16):
        _put_f32(buf, p + 16 + 4 * k, 1.0 if k == _GRIPPER_CHANNEL and gripper_release else 0.0, f32, scratch)
    buf[p + 80] = _MODE_ARMED if armed else 0
    return _finish(buf, 0, seq, system_id, component_id, _ID_ACTUATORS, _CRC_ACTUATORS, _LEN_ACTUATORS)


@njit(cache=True)
def read_answer(data: np.ndarray, n: int, expected_time_us: int, out: np.ndarray, payload: np.ndarray) -> int:
    """Check ``data[:n]`` as the answer to the frame at ``expected_time_us``; see the module docstring.

    ``payload``: a preallocated uint8 scratch of at least 88 bytes (8-byte aligned; zero-padded payload).
    """
    if n < 12 or n > data.shape[0] or data[0] != 0xFD or data[2] != 0:
        return ANSWER_OTHER
    plen = int(data[1])
    msg_id = int(data[7]) | (int(data[8]) << 8) | (int(data[9]) << 16)
    if msg_id != _ID_ACTUATORS or 10 + plen + 2 != n:
        return ANSWER_OTHER
    crc = _accumulate_crc_extra(_crc_x25(data, 1, 10 + plen, 0xFFFF), _CRC_ACTUATORS)
    if (int(data[10 + plen]) | (int(data[11 + plen]) << 8)) != crc:
        return ANSWER_OTHER
    take = min(plen, _LEN_ACTUATORS)
    for j in range(take):
        payload[j] = data[10 + j]
    for j in range(take, _LEN_ACTUATORS):
        payload[j] = 0
    t = payload[:8].view(np.uint64)[0]
    if t >= _TWO_POW_53:
        return ANSWER_INVALID
    t_us = int(t)
    if t_us < expected_time_us:
        return ANSWER_STALE
    if t_us > expected_time_us:
        return ANSWER_INVALID
    controls = payload[16:80].view(np.float32)
    for k in range(4):
        u = controls[k]
        if not (0.0 <= u <= 1.0):  # NaN fails too
            return ANSWER_INVALID
    for k in range(4):
        out[A_MOTORS + k] = controls[k]
    out[A_ARMED] = 1.0 if payload[80] & _MODE_ARMED else 0.0
    out[A_GRIPPER_RELEASE] = 1.0 if controls[_GRIPPER_CHANNEL] >= 0.5 else 0.0
    return ANSWER_OK


class AnswerWriter:
    """One sender's answers in place: ``write`` fills ``buffer`` and returns the datagram's length."""

    __slots__ = ("buffer", "component_id", "seq", "system_id", "view")

    def __init__(self, system_id: int, component_id: int) -> None:
        self.buffer = np.zeros(ANSWER_BUFFER_LEN, dtype=np.uint8)
        self.view = memoryview(self.buffer)
        self.system_id = system_id
        self.component_id = component_id
        self.seq = 0

    def write(
        self, time_us: int, motors: tuple[float, float, float, float], armed: bool, gripper: bool, lockstep: bool
    ) -> int:
        """The answer's bytes into ``buffer``; their length (send ``view[:length]``)."""
        seq = self.seq
        self.seq = (seq + 1) & 0xFF
        m = motors
        return write_answer(
            self.buffer,
            time_us,
            m[0],
            m[1],
            m[2],
            m[3],
            armed,
            gripper,
            lockstep,
            seq,
            self.system_id,
            self.component_id,
        )
