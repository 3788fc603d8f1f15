"""The mission's execution order and the positional route ahead of the current item (pure functions).

The executor's ``route_ahead`` and ``skip_to`` walk items in the order they would run: DO_JUMPs followed
while they have repeats left, DO items passed over, and the route stops at the first non-positional NAV item.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Iterator, Sequence

import numpy as np

from autopilot.mission.executor_types import MissionRoute
from mavlink_bridge.contract.frames import Vec3
from mavlink_bridge.contract.mav_enums import MavCmd
from mavlink_bridge.contract.vehicle_api import MissionItem

#: Positional items a detour may bypass (with a position).
SKIPPABLE = (MavCmd.NAV_WAYPOINT, MavCmd.NAV_LOITER_TIME)
#: Items that complete in the step they start (executed, never skipped).
DO_ITEMS = (MavCmd.DO_CHANGE_SPEED, MavCmd.DO_GRIPPER, MavCmd.DO_JUMP)


def execution_order(
    items: Sequence[MissionItem], jumps_done: Sequence[int], start: int, jumps: dict[int, int]
) -> Iterator[int]:
    """Item indices from ``start`` on as they would run: DO_JUMPs followed while they have repeats left
    (counts from ``jumps_done``, updated in ``jumps``); bounded, so a jump loop of DO items ends."""
    k = start
    for _ in range(4 * len(items) + 4):
        if not 0 <= k < len(items):
            return
        yield k
        item = items[k]
        if item.command == MavCmd.DO_JUMP:
            done = jumps.get(k, jumps_done[k])
            if item.param2 < 0 or done < item.param2:
                jumps[k] = done + 1
                k = int(item.param1)
                continue
        k += 1


def route_through(
    items: Sequence[MissionItem],
    pos_ned_m: Sequence[Vec3 | None],
    order: Iterable[int],
    min_length_m: float,
    max_points: int,
) -> MissionRoute:
    """The positional items along ``order`` (DO items passed over) until the path through them is at least
    ``min_length_m`` long or ``max_points`` are listed; stops at the first non-positional NAV item."""
    seqs: list[int] = []
    pts: list[Vec3] = []
    next_seq, length = -1, 0.0
    for k in order:
        item = items[k]
        if item.command in DO_ITEMS:
            continue
        pos = pos_ned_m[k]
        if item.command not in SKIPPABLE or pos is None:
            next_seq = k if seqs else -1
            break
        if pts:
            length += math.dist(pts[-1], pos)
        seqs.append(k)
        pts.append(pos)
        if length >= min_length_m or len(pts) >= max_points:
            break
    arr = np.array(pts, float).reshape(-1, 3)
    arr.flags.writeable = False
    return MissionRoute(tuple(seqs), arr, next_seq)


def next_position(items: Sequence[MissionItem], pos_ned_m: Sequence[Vec3 | None], order: Iterable[int]) -> Vec3 | None:
    """Position of the first waypoint/loiter along ``order`` with only DO items before it, else None."""
    for k in order:
        command = items[k].command
        if command in DO_ITEMS:
            continue
        if command in SKIPPABLE:
            return pos_ned_m[k]
        return None
    return None
