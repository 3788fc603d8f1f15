"""Mission items against the geofence's zones without home (SPEC §7-§8, issue 22 item 4).

A positional item given in a global frame and a fence uploaded geodetically can be compared before the vehicle's
first fix: a waypoint inside an exclusion zone, or outside every inclusion group, is refused at upload whatever the
fix, with a reason that does not depend on home (the zone is named by its geodetic position). What needs home
(GF_MAX_HOR_DIST, ceilings over home, local-frame items, routes) stays in :mod:`autopilot.mission.feasibility`.

Both are projected on one tangent plane about the fence's first vertex; over the kilometres a fence spans the
projection moves a boundary by well under a millimetre.
"""

from __future__ import annotations

from collections.abc import Sequence

from autopilot.geofence.fence import FenceZone, GeoFence, GeoZone
from autopilot.mission.plan import uses_current_position
from autopilot.mission.validation import MissionIssue
from mavlink_bridge.contract.frames import GeoPoint, LocalNedFrame
from mavlink_bridge.contract.mav_enums import GLOBAL_FRAMES, POSITION_COMMANDS
from mavlink_bridge.contract.vehicle_api import MissionItem, MissionResult


def geo_zone_label(zone: GeoZone, index: int) -> str:
    """e.g. ``exclusion circle 2 (r 8 m at 47.397742, 8.545594)`` (``index`` counts zones from 1)."""
    kind = "inclusion" if zone.inclusion else "exclusion"
    if zone.radius_m > 0.0:
        lat, lon = zone.vertices_lat_lon_deg[0]
        return f"{kind} circle {index} (r {zone.radius_m:.0f} m at {lat:.6f}, {lon:.6f})"
    last = zone.first_item + len(zone.vertices_lat_lon_deg) - 1
    return f"{kind} polygon {index} ({len(zone.vertices_lat_lon_deg)} vertices, fence items {zone.first_item}-{last})"


def _outside_inclusion_m(pos_ned_m: tuple[float, float, float], zones: Sequence[FenceZone]) -> float:
    """Horizontal distance to the nearest inclusion zone the point lies outside of."""
    return min(z.boundary_distance_m(pos_ned_m) for z in zones if z.inclusion and not z.contains(pos_ned_m))


def zone_issue(items: Sequence[MissionItem], geo_fence: GeoFence) -> MissionIssue | None:
    """The first positional item in a global frame inside an exclusion zone or outside the inclusion zones, or None.

    Items at the vehicle's current position (lat = lon = 0) and items in local frames are left to the check about
    home. The reason names the item and the zone: ``item 3: inside exclusion circle 1 (r 8 m at 47.3981, 8.5456)``.
    """
    if not geo_fence.zones:
        return None
    ref_lat_deg, ref_lon_deg = geo_fence.zones[0].vertices_lat_lon_deg[0]
    ref = GeoPoint(ref_lat_deg, ref_lon_deg, 0.0)
    fence, frame = geo_fence.to_local(ref), LocalNedFrame(ref)
    labels = [geo_zone_label(z, k) for k, z in enumerate(geo_fence.zones, start=1)]
    for i, item in enumerate(items):
        if item.command not in POSITION_COMMANDS or item.frame not in GLOBAL_FRAMES or uses_current_position(item):
            continue
        n, e, _ = frame.ned_from_geodetic(item.x_lat_deg, item.y_lon_deg, 0.0)
        pos = (n, e, 0.0)
        for zone, label in zip(fence.zones, labels, strict=True):
            if not zone.inclusion and zone.contains(pos):
                return MissionIssue(MissionResult.INVALID_PARAM5_X, i, "x_lat_deg", f"item {i}: inside {label}")
        if any(z.inclusion for z in fence.zones) and fence.violates(pos):
            inclusions = ", ".join(lb for z, lb in zip(fence.zones, labels, strict=True) if z.inclusion)
            outside_m = _outside_inclusion_m(pos, fence.zones)
            return MissionIssue(
                MissionResult.INVALID_PARAM5_X,
                i,
                "x_lat_deg",
                f"item {i}: {outside_m:.0f} m outside the inclusion fence ({inclusions})",
            )
    return None
