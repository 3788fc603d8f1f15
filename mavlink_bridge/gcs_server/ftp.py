"""MAVLink FTP (FILE_TRANSFER_PROTOCOL) over an empty, read-only file system: every request answered at once.

The vehicle serves no files (no parameter file, logs or component metadata), and AUTOPILOT_VERSION does not
advertise MAV_PROTOCOL_CAPABILITY_FTP. Some clients try FTP anyway: MAVProxy fetches parameters through
``@PARAM/param.pck`` first and, with no answer, waits ~12 s for its FTP timeout before it falls back to
PARAM_REQUEST_LIST. Answering each request with the NAK a real server would give for an empty file system
lets such a client fall back at once.

Answers (MAVLink FTP spec): ResetSessions is acknowledged; TerminateSession, ReadFile, BurstReadFile and
WriteFile name a session that does not exist (InvalidSession); opening, listing, removing, renaming,
truncating or checksumming a path finds nothing (FileNotFound); creating a file or directory is refused
(FileProtected); any other opcode is UnknownCommand. ACK/NAK opcodes from a peer are ignored. A reply
echoes the request's session and opcode, with ``seq_number`` one more than the request's.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass

from pymavlink.dialects.v20 import common as mavlink2

#: FTP header: seq_number u16, session u8, opcode u8, size u8, req_opcode u8, burst_complete u8, padding u8,
#: offset u32; then up to 239 data bytes (251 in all).
_HEADER = struct.Struct("<HBBBBBBI")
PAYLOAD_LEN = 251

OP_TERMINATE_SESSION = 1
OP_RESET_SESSIONS = 2
OP_LIST_DIRECTORY = 3
OP_OPEN_FILE_RO = 4
OP_READ_FILE = 5
OP_CREATE_FILE = 6
OP_WRITE_FILE = 7
OP_REMOVE_FILE = 8
OP_CREATE_DIRECTORY = 9
OP_REMOVE_DIRECTORY = 10
OP_OPEN_FILE_WO = 11
OP_TRUNCATE_FILE = 12
OP_RENAME = 13
OP_CALC_FILE_CRC32 = 14
OP_BURST_READ_FILE = 15
OP_ACK = 128
OP_NAK = 129

ERR_INVALID_SESSION = 4
ERR_UNKNOWN_COMMAND = 7
ERR_FILE_PROTECTED = 9
ERR_FILE_NOT_FOUND = 10

#: request opcode -> NAK error code (None: ACK).
_ANSWERS: dict[int, int | None] = {
    OP_RESET_SESSIONS: None,
    OP_TERMINATE_SESSION: ERR_INVALID_SESSION,
    OP_READ_FILE: ERR_INVALID_SESSION,
    OP_BURST_READ_FILE: ERR_INVALID_SESSION,
    OP_WRITE_FILE: ERR_INVALID_SESSION,
    OP_LIST_DIRECTORY: ERR_FILE_NOT_FOUND,
    OP_OPEN_FILE_RO: ERR_FILE_NOT_FOUND,
    OP_OPEN_FILE_WO: ERR_FILE_NOT_FOUND,
    OP_REMOVE_FILE: ERR_FILE_NOT_FOUND,
    OP_REMOVE_DIRECTORY: ERR_FILE_NOT_FOUND,
    OP_TRUNCATE_FILE: ERR_FILE_NOT_FOUND,
    OP_RENAME: ERR_FILE_NOT_FOUND,
    OP_CALC_FILE_CRC32: ERR_FILE_NOT_FOUND,
    OP_CREATE_FILE: ERR_FILE_PROTECTED,
    OP_CREATE_DIRECTORY: ERR_FILE_PROTECTED,
}


@dataclass(slots=True)
class FtpStats:
    requests: int = 0
    ignored: int = 0  # too short to hold a header, or an ACK/NAK


def ftp_reply(request_payload: bytes) -> bytes | None:
    """The 251-byte reply payload to one FTP request payload, or None when it needs none."""
    if len(request_payload) < _HEADER.size:
        return None
    seq, session, opcode, _, _, _, _, _ = _HEADER.unpack_from(request_payload)
    if opcode == 0 or opcode >= OP_ACK:
        return None
    error = _ANSWERS.get(opcode, ERR_UNKNOWN_COMMAND)
    if error is None:
        head = _HEADER.pack((seq + 1) & 0xFFFF, session, OP_ACK, 0, opcode, 0, 0, 0)
        return head.ljust(PAYLOAD_LEN, b"\x00")
    head = _HEADER.pack((seq + 1) & 0xFFFF, session, OP_NAK, 1, opcode, 0, 0, 0)
    return (head + bytes((error,))).ljust(PAYLOAD_LEN, b"\x00")


class FtpProtocol:
    """Answers FILE_TRANSFER_PROTOCOL requests to ``mav`` (see module docstring)."""

    HANDLED = frozenset({"FILE_TRANSFER_PROTOCOL"})

    def __init__(self, mav: mavlink2.MAVLink) -> None:
        self.mav = mav
        self.stats = FtpStats()

    def handle(self, msg: mavlink2.MAVLink_message) -> None:
        payload = bytes(msg.payload)
        reply = ftp_reply(payload)
        if reply is None:
            self.stats.ignored += 1
            return
        self.stats.requests += 1
        self.mav.file_transfer_protocol_send(0, msg.get_srcSystem(), msg.get_srcComponent(), list(reply))
