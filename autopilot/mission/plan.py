"""A mission plan as data: home, MISSION items, FENCE items and the file-level settings (SPEC §8).

``MissionPlan`` is what the mission-file readers return and the writers take; the GCS script
uploads ``plan.items`` as mission_type MISSION and ``plan.fence`` as mission_type FENCE.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field, fields
from typing import Any

from mavlink_bridge.contract.frames import GeoPoint, LocalNedFrame, Vec3
from mavlink_bridge.contract.mav_enums import AMSL_FRAMES, CURRENT_POSITION_OK, MavCmd
from mavlink_bridge.contract.vehicle_api import MissionItem

#: Default vehicle config name when a file does not say.
DEFAULT_VEHICLE = "x500"


@dataclass(frozen=True)
class MissionPlan:
    """A whole mission file.

    ``items`` are mission_type MISSION (seq 0 is the first item, PX4 numbering), ``fence``
    are mission_type FENCE ``NAV_FENCE_*`` items. ``speed_m_s`` is the cruise speed the file
    asks for (also present as a leading DO_CHANGE_SPEED item so every GCS honours it), ``world``
    is the YAML ``world:`` section kept verbatim for the simulator (None when absent).
    """

    name: str
    home: GeoPoint
    items: list[MissionItem]
    fence: list[MissionItem] = field(default_factory=list)
    speed_m_s: float | None = None
    vehicle: str = DEFAULT_VEHICLE
    world: dict[str, Any] | None = None


def uses_current_position(item: MissionItem) -> bool:
    """True when the item's lat = lon = 0 means "at the vehicle's current position"."""
    return item.command in CURRENT_POSITION_OK and item.x_lat_deg == 0.0 and item.y_lon_deg == 0.0


def is_wpl_home_line(index: int, item: MissionItem, home: GeoPoint) -> bool:
    """True for an ArduPilot-style home entry sent as mission item 0 (MAVProxy's ``wp load``).

    MAVProxy uploads line 0 of a QGC WPL file (the home position, frame GLOBAL, altitude AMSL)
    as item 0. It is kept so a download equals the upload, passes validation although it sits
    on the ground, and completes at once in the executor: it is never flown to.
    """
    return (
        index == 0
        and item.command == MavCmd.NAV_WAYPOINT
        and item.frame in AMSL_FRAMES
        and abs(alt_rel_home_m(item, home)) < 1.0
    )


def alt_rel_home_m(item: MissionItem, home: GeoPoint) -> float:
    """The item's z as metres above home (AMSL frames are converted with ``home.alt_amsl_m``)."""
    if item.frame in AMSL_FRAMES:
        return item.z_alt_m - home.alt_amsl_m
    return item.z_alt_m


def item_position_ned(item: MissionItem, frame: LocalNedFrame) -> Vec3:
    """Local NED (m) of a positional item about ``frame.home``; down = -(altitude above home).

    The horizontal part is the exact tangent-plane position; the down component is the
    altitude above home (not the tangent-plane down, which would include Earth curvature).
    """
    n, e, _ = frame.ned_from_geodetic(item.x_lat_deg, item.y_lon_deg, frame.home.alt_amsl_m)
    return (n, e, -alt_rel_home_m(item, frame.home))


def _float_close(a: float, b: float, tol: float) -> bool:
    if math.isnan(a) or math.isnan(b):
        return math.isnan(a) and math.isnan(b)
    return abs(a - b) <= tol


def items_match(
    a: Sequence[MissionItem], b: Sequence[MissionItem], *, deg_tol: float = 1e-9, tol: float = 1e-6
) -> bool:
    """Item lists equal field by field: NaN equals NaN, lat/lon within ``deg_tol`` deg, other floats within ``tol``.

    The file formats here write floats with their shortest exact repr, so round trips are
    exact in practice; the tolerances cover MAVLink transport (degE7, float32 params).
    """
    if len(a) != len(b):
        return False
    for x, y in zip(a, b, strict=True):
        for f in fields(MissionItem):
            va, vb = getattr(x, f.name), getattr(y, f.name)
            if isinstance(va, float) or isinstance(vb, float):
                limit = deg_tol if f.name in ("x_lat_deg", "y_lon_deg") else tol
                if not _float_close(float(va), float(vb), limit):
                    return False
            elif va != vb:
                return False
    return True
