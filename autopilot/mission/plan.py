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


@dataclass(frozen=True, slots=True)
class HomeTolerance:
    """How far (m) a WPL file's home line may lie from the estimated home and still be taken for it.

    The estimated home is the vehicle's position at a GPS fix, off by that fix's error: the tolerance is
    :data:`HOME_GATE` times the accuracy the GPS reports (eph, epv), and at least :data:`HOME_TOL_MIN_M`.
    """

    horiz_m: float = 1.0
    vert_m: float = 1.0

    @classmethod
    def from_gps(cls, eph_m: float, epv_m: float) -> HomeTolerance:
        """From the GPS accuracy the estimator reports with the state that set home (inf/NaN: no fix, the floor)."""

        def gate(acc_m: float) -> float:
            return max(HOME_TOL_MIN_M, HOME_GATE * acc_m) if math.isfinite(acc_m) else HOME_TOL_MIN_M

        return cls(gate(eph_m), gate(epv_m))


#: Reported GPS accuracies a home line may be off by (eph/epv are about one standard deviation).
HOME_GATE = 3.0
#: The smallest home-line tolerance (m): a truth estimator's home is exact, a file's numbers are rounded.
HOME_TOL_MIN_M = 1.0
#: The tolerance before any fix reported an accuracy.
DEFAULT_HOME_TOL = HomeTolerance()


def is_wpl_home_line(index: int, item: MissionItem, home: GeoPoint, tol: HomeTolerance = DEFAULT_HOME_TOL) -> bool:
    """True for an ArduPilot-style home entry sent as mission item 0 (MAVProxy's ``wp load``).

    MAVProxy uploads line 0 of a QGC WPL file (the home position, frame GLOBAL, altitude AMSL)
    as item 0. It is recognised when it lies at the estimated home within ``tol`` (the GPS accuracy
    at the fix that set home), horizontally and in altitude, whichever estimator flies. It is kept so a
    download equals the upload, passes validation although it sits on the ground, and completes at once
    in the executor: it is never flown to.
    """
    if index != 0 or item.command != MavCmd.NAV_WAYPOINT or item.frame not in AMSL_FRAMES:
        return False
    if abs(alt_rel_home_m(item, home)) > tol.vert_m:
        return False
    n, e, _ = LocalNedFrame(home).ned_from_geodetic(item.x_lat_deg, item.y_lon_deg, home.alt_amsl_m)
    return math.hypot(n, e) <= tol.horiz_m


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
