"""The compiled lockstep answer: written in place as pymavlink reads it (and as the codec writes it), read in
place with the edge checks (time echoed, motors finite and in [0, 1]); anything else is left to the decoder."""

from __future__ import annotations

import math

import numpy as np
import pytest

from mavlink_bridge.contract.wire import ActuatorCommand
from mavlink_bridge.lockstep.answer_kernel import (
    A_ARMED,
    A_GRIPPER_RELEASE,
    A_MOTORS,
    ANSWER_INVALID,
    ANSWER_OK,
    ANSWER_OTHER,
    ANSWER_STALE,
    N_ANSWER,
    AnswerWriter,
    read_answer,
)
from mavlink_bridge.wire.codec import AUTOPILOT_COMPONENT_ID, AUTOPILOT_SYSTEM_ID, Encoder, Heartbeat, make_mavlink

CASES = [
    ActuatorCommand(4000, (0.5, 0.25, 0.125, 1.0), True),
    ActuatorCommand(123_456_789, (0.1, 0.2, 0.3, 0.4), True, True),
    ActuatorCommand(0, (0.0, 0.0, 0.0, 0.0), False),  # truncated to one payload byte
    ActuatorCommand(8000, (0.3, 0.0, 0.0, 0.0), False, False, False),
]


@pytest.mark.parametrize("cmd", CASES)
def test_written_answer_is_what_pymavlink_and_the_codec_see(cmd: ActuatorCommand) -> None:
    writer, enc = AnswerWriter(AUTOPILOT_SYSTEM_ID, AUTOPILOT_COMPONENT_ID), Encoder()
    for _ in range(3):  # the sequence counters advance alike
        n = writer.write(cmd.time_us, cmd.motor_cmd, cmd.armed, cmd.gripper_release, cmd.lockstep)
        assert bytes(writer.view[:n]) == enc.actuators(cmd)
    (msg,) = make_mavlink(255, 0).parse_buffer(bytes(writer.view[:n]))
    assert msg.get_type() == "HIL_ACTUATOR_CONTROLS" and msg.time_usec == cmd.time_us
    assert list(msg.controls[:4]) == [float(np.float32(u)) for u in cmd.motor_cmd] and (msg.mode == 128) == cmd.armed
    assert (msg.controls[8] == 1.0) == cmd.gripper_release and (msg.flags == 1) == cmd.lockstep


def _read(datagram: bytes, expected_time_us: int) -> tuple[int, np.ndarray]:
    data = np.zeros(65535, dtype=np.uint8)
    data[: len(datagram)] = np.frombuffer(datagram, dtype=np.uint8)
    out = np.full(N_ANSWER, -1.0)
    return read_answer(data, len(datagram), expected_time_us, out, np.zeros(96, dtype=np.uint8)), out


def test_read_answer_applies_the_edge_checks() -> None:
    enc = Encoder()
    result, out = _read(enc.actuators(ActuatorCommand(4000, (0.5, 0.25, 0.0, 1.0), True, True)), 4000)
    assert result == ANSWER_OK and list(out[A_MOTORS : A_MOTORS + 4]) == [0.5, 0.25, 0.0, 1.0]
    assert out[A_ARMED] == 1.0 and out[A_GRIPPER_RELEASE] == 1.0
    result, out = _read(enc.actuators(ActuatorCommand(0, (0.0,) * 4, False)), 0)  # truncated payload
    assert result == ANSWER_OK and out[A_ARMED] == 0.0 and out[A_GRIPPER_RELEASE] == 0.0
    assert _read(enc.actuators(ActuatorCommand(0, (0.5,) * 4, True)), 4000)[0] == ANSWER_STALE
    assert _read(enc.actuators(ActuatorCommand(8000, (0.5,) * 4, True)), 4000)[0] == ANSWER_INVALID
    assert _read(enc.actuators(ActuatorCommand(2**63, (0.5,) * 4, True)), 4000)[0] == ANSWER_INVALID
    for motors in ((math.nan, 0.5, 0.5, 0.5), (0.5, 1.5, 0.5, 0.5), (0.5, 0.5, -0.1, 0.5), (0.5, 0.5, 0.5, math.inf)):
        result, out = _read(enc.actuators(ActuatorCommand(4000, motors, True)), 4000)
        assert result == ANSWER_INVALID and out[A_MOTORS] == -1.0  # nothing written
    good = enc.actuators(ActuatorCommand(4000, (0.5,) * 4, True))
    bad_crc = good[:-1] + bytes([good[-1] ^ 1])
    for other in (bad_crc, good + good, good[:-3], enc.heartbeat(Heartbeat()), b"", b"\xfe" + good[1:]):
        assert _read(other, 4000)[0] == ANSWER_OTHER
