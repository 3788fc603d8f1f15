"""Why a simulated vehicle stopped (SPEC §5, STYLE 6): an enum, never a bare bool."""

from __future__ import annotations

from enum import IntEnum


class EndReason(IntEnum):
    """Run status of one vehicle; anything but ``RUNNING`` freezes the vehicle's state."""

    RUNNING = 0
    COMPLETED = 1
    STOPPED = 2
    COLLISION = 3
    GROUND_IMPACT = 4
    AUTOPILOT_LOST = 5
    NONFINITE_STATE = 6
