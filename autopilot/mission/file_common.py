"""What the mission file formats share: the error type, pattern expansion and item helpers."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import replace
from pathlib import Path
from typing import Any

from mavlink_bridge.contract.mav_enums import MavCmd, MavFrame
from mavlink_bridge.contract.vehicle_api import MissionItem

#: ``(type, spacing_m, params) -> [(north_m, east_m, alt_m), ...]``: expands a YAML ``pattern:`` entry.
PatternExpander = Callable[[str, float, dict[str, Any]], list[tuple[float, float, float]]]

_MISSION_FRAME = int(MavFrame.MISSION)


class MissionFileError(ValueError):
    """A mission file that cannot be read or written; one line naming the file, line, item, field and fix.

    ``FILE:LINE: mission item 3 (waypoint): field 'alt_m': expected a number, got 'ten'; fix: ...``
    """

    def __init__(
        self,
        path: str | Path,
        message: str,
        *,
        section: str = "",
        item_index: int | None = None,
        field: str = "",
        line: int | None = None,
        fix: str = "",
    ) -> None:
        where = [str(path) if line is None else f"{path}:{line}"]
        if section:
            where.append(section if item_index is None else f"{section} item {item_index}")
        if field:
            where.append(f"field '{field}'")
        text = ": ".join([*where, " ".join(message.split())])
        super().__init__(f"{text}; fix: {fix}" if fix else text)
        self.path = str(path)
        self.item_index = item_index
        self.field = field
        self.line = line


def expand_pattern(pattern_type: str, spacing_m: float, params: dict[str, Any]) -> list[tuple[float, float, float]]:
    """Default :data:`PatternExpander`: the control engineer's parametric trajectories (SPEC §6.5)."""
    from autopilot.flight_tasks.trajectories import make_trajectory  # heavy module, only needed by pattern entries

    return [(float(n), float(e), float(a)) for n, e, a in make_trajectory(pattern_type, **params).waypoints(spacing_m)]


def speed_item(speed_m_s: float) -> MissionItem:
    return MissionItem(0, int(MavCmd.DO_CHANGE_SPEED), _MISSION_FRAME, param1=1.0, param2=speed_m_s, param3=-1.0)


def jump_shift(item: MissionItem, delta: int) -> MissionItem:
    return replace(item, param1=item.param1 + delta) if item.command == MavCmd.DO_JUMP else item


def leading_speed(items: Sequence[MissionItem]) -> float | None:
    if items and items[0].command == MavCmd.DO_CHANGE_SPEED and items[0].param2 > 0.0:
        return items[0].param2
    return None


def fence_shapes(fence: Sequence[MissionItem]) -> list[tuple[MissionItem, list[tuple[float, float]]]]:
    """Group FENCE items into zones: (first item, [(lat, lon), ...]); circles have one vertex."""
    shapes = []
    i = 0
    while i < len(fence):
        item = fence[i]
        is_polygon = item.command in (
            MavCmd.NAV_FENCE_POLYGON_VERTEX_INCLUSION,
            MavCmd.NAV_FENCE_POLYGON_VERTEX_EXCLUSION,
        )
        count = max(int(item.param1), 1) if is_polygon else 1
        shapes.append((item, [(v.x_lat_deg, v.y_lon_deg) for v in fence[i : i + count]]))
        i += count
    return shapes
