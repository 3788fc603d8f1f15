"""MAVLink 2 message signing for the GCS and API links (SPEC §10).

A link with a key signs everything it sends. When signing is *required*, incoming
messages that are unsigned or carry a wrong signature (bad HMAC, replayed timestamp)
are rejected by the parser and counted; they are never acted on. Keys are 32 bytes:
given as 64 hex digits, or any other text is hashed with SHA-256 (the MAVProxy
``signing setup PASSPHRASE`` convention), so every tool derives the same key.
"""

from __future__ import annotations

import hashlib
import time
from enum import Enum

from pymavlink.dialects.v20 import common as mavlink2

#: Signing timestamps count 10 µs ticks since 2015-01-01T00:00:00Z (MAVLink spec).
_SIGNING_EPOCH_UNIX_S = 1420070400
SIGNATURE_BLOCK_LEN = mavlink2.MAVLINK_SIGNATURE_BLOCK_LEN


class SigningKeyError(ValueError):
    """A signing key could not be derived from the text given."""


class RejectReason(Enum):
    """Why the parser dropped a datagram's packet."""

    UNSIGNED = "unsigned"
    BAD_SIGNATURE = "bad_signature"
    MALFORMED = "malformed"


def signing_key_from_text(text: str) -> bytes:
    """A 32-byte key: 64 hex digits are taken literally, other text is SHA-256 hashed."""
    text = text.strip()
    if not text:
        raise SigningKeyError("the signing key is empty")
    if len(text) == 64:
        try:
            return bytes.fromhex(text)
        except ValueError:
            pass
    return hashlib.sha256(text.encode("utf-8")).digest()


def signing_timestamp_now(wall_time_unix_s: float | None = None) -> int:
    """The current signing timestamp (10 µs ticks since 2015-01-01)."""
    now = time.time() if wall_time_unix_s is None else wall_time_unix_s
    return max(0, int((now - _SIGNING_EPOCH_UNIX_S) * 1e5))


def enable_signing(mav: mavlink2.MAVLink, key: bytes, *, require_incoming: bool, link_id: int = 0) -> None:
    """Sign outgoing packets with ``key``; if ``require_incoming``, unsigned/badly signed input is rejected.

    Without ``require_incoming`` every packet is accepted (unsigned, or with a signature that
    does not verify), so a keyed link still talks to an unkeyed peer.
    """
    if len(key) != 32:
        raise SigningKeyError(f"a MAVLink signing key has 32 bytes, got {len(key)}")
    mav.signing.secret_key = bytes(key)
    mav.signing.sign_outgoing = True
    mav.signing.link_id = link_id & 0xFF
    mav.signing.timestamp = signing_timestamp_now()
    mav.signing.allow_unsigned_callback = None if require_incoming else _accept_unsigned


def _accept_unsigned(_mav: mavlink2.MAVLink, _msg_id: int) -> bool:
    return True


def classify_bad_data(msg: mavlink2.MAVLink_bad_data) -> RejectReason:
    """Tell a signature rejection (unsigned vs wrongly signed) from a malformed packet."""
    reason = str(getattr(msg, "reason", ""))
    if "signature" not in reason.lower():
        return RejectReason.MALFORMED
    data = bytes(msg.data)
    signed = len(data) > 2 and data[0] == mavlink2.PROTOCOL_MARKER_V2 and bool(data[2] & mavlink2.MAVLINK_IFLAG_SIGNED)
    return RejectReason.BAD_SIGNATURE if signed else RejectReason.UNSIGNED
