"""Parameter names and types on the wire, for both ends of the parameter protocol (float-only, SPEC §8)."""

from __future__ import annotations

from pymavlink.dialects.v20 import common as mavlink2

PARAM_TYPE_REAL32 = mavlink2.MAV_PARAM_TYPE_REAL32


def decode_param_id(raw: str | bytes) -> str:
    """The parameter name from a char[16] field (NUL padded, not necessarily terminated)."""
    if isinstance(raw, bytes):
        raw = raw.decode("ascii", errors="replace")
    return raw.split("\x00", 1)[0].strip()
