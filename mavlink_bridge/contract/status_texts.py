"""The STATUSTEXT words two sides parse (SPEC §2): the autopilot writes them, the ground station and campaigns
read them. Defined here once; the autopilot builds its texts with these functions and the tools test with the
prefixes, so a reworded text cannot silently stop being recognised.

- ``Failsafe: <what>: <why>`` (``FAILSAFE_PREFIX``): a failsafe fired (``GEOFENCE_PREFIX``: a fence breach, even
  when GF_ACTION only warns). A mission during which one fired failed.
- ``Bypassed item <seq>: <why>`` (``BYPASSED_PREFIX``): a mission item flown around instead of reached.
- ``Reached item <seq>``: a mission item reached.
"""

from __future__ import annotations

from collections.abc import Iterable

FAILSAFE_PREFIX = "Failsafe:"
GEOFENCE_PREFIX = "Failsafe: geofence"
BYPASSED_PREFIX = "Bypassed item"
REACHED_PREFIX = "Reached item"


def failsafe_text(what: str, why: str) -> str:
    """``Failsafe: <what>: <why>`` (``what`` e.g. ``geofence breach``, ``position lost (no GPS for 2.0 s)``)."""
    return f"{FAILSAFE_PREFIX} {what}: {why}"


def bypassed_text(seq: int, why: str) -> str:
    """``Bypassed item <seq>: <why>``."""
    return f"{BYPASSED_PREFIX} {seq}: {why}"


def reached_text(seq: int) -> str:
    """``Reached item <seq>``."""
    return f"{REACHED_PREFIX} {seq}"


def is_failsafe(text: str) -> bool:
    return text.startswith(FAILSAFE_PREFIX)


def is_geofence_breach(text: str) -> bool:
    return text.startswith(GEOFENCE_PREFIX)


def is_bypassed(text: str) -> bool:
    return text.startswith(BYPASSED_PREFIX)


def bypassed_seq(text: str) -> int | None:
    """The item number of a ``Bypassed item <seq>: ...`` text (None for any other text)."""
    if not is_bypassed(text):
        return None
    head = text[len(BYPASSED_PREFIX) :].split(":", 1)[0].strip()
    return int(head) if head.isdigit() else None


def first_failsafe(texts: Iterable[str]) -> str:
    """The first failsafe text among ``texts`` (empty when none fired)."""
    return next((t for t in texts if is_failsafe(t)), "")


def failsafe_in(reason: str) -> str:
    """The failsafe text quoted inside a longer reason (``"failsafe during the mission: Failsafe: ..."``), else ''."""
    at = reason.find(FAILSAFE_PREFIX)
    return reason[at:] if at >= 0 else ""
