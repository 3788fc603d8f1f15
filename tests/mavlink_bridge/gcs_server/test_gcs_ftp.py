"""MAVLink FTP over an empty file system: every request gets the answer a real server would give, at once.

The expected reply layout is written out here from the MAVLink FTP spec (not imported from the module), so a
wrong header in ``mavlink_bridge.gcs_server.ftp`` fails these tests.
"""

from __future__ import annotations

import os
import struct
import time

import pytest
from gcs_fakes import served_fake_vehicle

from mavlink_bridge.gcs_server.ftp import ftp_reply

os.environ.setdefault("MAVLINK20", "1")
from pymavlink import mavutil

mavutil.set_dialect("common")
M = mavutil.mavlink

# seq_number u16, session u8, opcode u8, size u8, req_opcode u8, burst_complete u8, padding u8, offset u32
SPEC_HEADER = "<HBBBBBBI"
ACK, NAK = 128, 129
INVALID_SESSION, UNKNOWN_COMMAND, FILE_PROTECTED, FILE_NOT_FOUND = 4, 7, 9, 10


def _request(opcode: int, seq: int = 7, session: int = 3, path: bytes = b"") -> bytes:
    head = struct.pack(SPEC_HEADER, seq, session, opcode, len(path), 0, 0, 0, 0)
    return (head + path).ljust(251, b"\x00")


def _parse(reply: bytes) -> tuple[int, int, int, int, int, bytes]:
    seq, session, opcode, size, req_opcode, _, _, _ = struct.unpack_from(SPEC_HEADER, reply)
    return seq, session, opcode, size, req_opcode, reply[12 : 12 + size]


@pytest.mark.parametrize(
    ("opcode", "answer", "error"),
    [
        (2, ACK, None),  # ResetSessions
        (1, NAK, INVALID_SESSION),  # TerminateSession: there are no sessions
        (5, NAK, INVALID_SESSION),  # ReadFile
        (15, NAK, INVALID_SESSION),  # BurstReadFile
        (7, NAK, INVALID_SESSION),  # WriteFile
        (3, NAK, FILE_NOT_FOUND),  # ListDirectory
        (4, NAK, FILE_NOT_FOUND),  # OpenFileRO (MAVProxy: @PARAM/param.pck)
        (11, NAK, FILE_NOT_FOUND),  # OpenFileWO
        (8, NAK, FILE_NOT_FOUND),  # RemoveFile
        (10, NAK, FILE_NOT_FOUND),  # RemoveDirectory
        (12, NAK, FILE_NOT_FOUND),  # TruncateFile
        (13, NAK, FILE_NOT_FOUND),  # Rename
        (14, NAK, FILE_NOT_FOUND),  # CalcFileCRC32
        (6, NAK, FILE_PROTECTED),  # CreateFile: read-only
        (9, NAK, FILE_PROTECTED),  # CreateDirectory
        (42, NAK, UNKNOWN_COMMAND),
    ],
)
def test_each_request_gets_the_empty_file_system_answer(opcode: int, answer: int, error: int | None) -> None:
    reply = ftp_reply(_request(opcode, path=b"@PARAM/param.pck"))
    assert reply is not None and len(reply) == 251
    seq, session, op, size, req_opcode, data = _parse(reply)
    assert (seq, session, op, req_opcode) == (8, 3, answer, opcode)
    assert (size, data) == ((0, b"") if error is None else (1, bytes((error,))))


def test_sequence_wraps_and_acks_naks_and_runts_get_no_reply() -> None:
    reply = ftp_reply(_request(4, seq=0xFFFF))
    assert reply is not None and _parse(reply)[0] == 0
    assert ftp_reply(_request(ACK)) is None and ftp_reply(_request(NAK)) is None and ftp_reply(_request(0)) is None
    assert ftp_reply(b"\x01\x00\x04") is None  # shorter than a header


def test_a_client_opening_the_parameter_file_is_refused_over_the_link() -> None:
    with served_fake_vehicle() as (_, server, harness, conn):
        conn.mav.heartbeat_send(M.MAV_TYPE_GCS, M.MAV_AUTOPILOT_INVALID, 0, 0, 0)
        request = _request(4, seq=11, session=0, path=b"@PARAM/param.pck?withdefaults=1")
        conn.mav.file_transfer_protocol_send(0, 1, 1, list(request))
        deadline = time.monotonic() + 10.0
        msg = None
        while msg is None and time.monotonic() < deadline:
            msg = conn.recv_match(type="FILE_TRANSFER_PROTOCOL", blocking=True, timeout=0.5)
        assert msg is not None, "no FTP reply"
        assert (msg.target_system, msg.target_component) == (255, 190)
        seq, _, op, size, req_opcode, data = _parse(bytes(msg.payload))
        assert (seq, op, req_opcode, size, data) == (12, NAK, 4, 1, bytes((FILE_NOT_FOUND,)))
        with harness.locked():
            assert server.stats.ftp_requests == 1
