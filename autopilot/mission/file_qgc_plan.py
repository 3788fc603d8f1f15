"""QGroundControl ``.plan`` JSON: SimpleItems (DO_JUMP targets are doJumpId = seq + 1) and the geoFence."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

from autopilot.geofence.fence import circle_fence_items, polygon_fence_items
from autopilot.mission.file_common import MissionFileError, fence_shapes, jump_shift, leading_speed
from autopilot.mission.plan import DEFAULT_VEHICLE, MissionPlan
from mavlink_bridge.contract.frames import GeoPoint
from mavlink_bridge.contract.mav_enums import MavCmd
from mavlink_bridge.contract.vehicle_api import MissionItem

_NAN = float("nan")


def _json_num(v: float) -> float | None:
    return None if math.isnan(v) else v


def _plan_num(v: Any, path: Path, idx: int, field: str) -> float:
    if v is None:
        return _NAN
    if isinstance(v, bool) or not isinstance(v, int | float):
        raise MissionFileError(
            path, f"expected a number or null, got {v!r}", section="mission", item_index=idx, field=field
        )
    return float(v)


def write_plan(plan: MissionPlan, path: Path) -> None:
    items_json = []
    for item in plan.items:
        it = jump_shift(item, +1)
        params = [it.param1, it.param2, it.param3, it.param4, it.x_lat_deg, it.y_lon_deg, it.z_alt_m]
        items_json.append(
            {
                "type": "SimpleItem",
                "autoContinue": it.autocontinue,
                "command": it.command,
                "doJumpId": item.seq + 1,
                "frame": it.frame,
                "params": [_json_num(p) for p in params],
            }
        )
    circles, polygons = [], []
    for first, verts in fence_shapes(plan.fence):
        inclusion = first.command in (MavCmd.NAV_FENCE_CIRCLE_INCLUSION, MavCmd.NAV_FENCE_POLYGON_VERTEX_INCLUSION)
        if first.command in (MavCmd.NAV_FENCE_CIRCLE_INCLUSION, MavCmd.NAV_FENCE_CIRCLE_EXCLUSION):
            circle = {"center": [first.x_lat_deg, first.y_lon_deg], "radius": first.param1}
            circles.append({"circle": circle, "inclusion": inclusion, "version": 1})
        else:
            polygons.append({"inclusion": inclusion, "polygon": [list(v) for v in verts], "version": 1})
    cruise = plan.speed_m_s if plan.speed_m_s is not None else 5.0
    doc = {
        "fileType": "Plan",
        "groundStation": "quadsitl",
        "version": 1,
        "mission": {
            "version": 2,
            "firmwareType": 12,  # MAV_AUTOPILOT_PX4
            "vehicleType": 2,  # MAV_TYPE_QUADROTOR
            "cruiseSpeed": cruise,
            "hoverSpeed": cruise,
            "plannedHomePosition": [plan.home.lat_deg, plan.home.lon_deg, plan.home.alt_amsl_m],
            "items": items_json,
        },
        "geoFence": {"version": 2, "circles": circles, "polygons": polygons},
        "rallyPoints": {"version": 2, "points": []},
        "quadsitl": {"name": plan.name, "vehicle": plan.vehicle, "speed_m_s": plan.speed_m_s, "world": plan.world},
    }
    path.write_text(json.dumps(doc, indent=2) + "\n")


def read_plan(path: Path) -> MissionPlan:
    try:
        doc = json.loads(path.read_text())
    except json.JSONDecodeError as exc:
        raise MissionFileError(
            path, f"not valid JSON: {exc.msg} (column {exc.colno})", line=exc.lineno, fix="save the plan again from QGC"
        ) from None
    if not isinstance(doc, dict) or doc.get("fileType") != "Plan":
        raise MissionFileError(path, "not a QGroundControl plan (fileType must be 'Plan')", field="fileType")
    mission = doc.get("mission")
    if not isinstance(mission, dict):
        raise MissionFileError(path, "missing 'mission' object", field="mission")
    home_l = mission.get("plannedHomePosition")
    if not (isinstance(home_l, list) and len(home_l) == 3 and all(isinstance(v, int | float) for v in home_l)):
        raise MissionFileError(path, "expected [lat, lon, alt_amsl]", field="mission.plannedHomePosition")
    home = GeoPoint(float(home_l[0]), float(home_l[1]), float(home_l[2]))
    items: list[MissionItem] = []
    for idx, it in enumerate(mission.get("items") or []):
        if not isinstance(it, dict) or it.get("type") != "SimpleItem":
            kind = it.get("type") if isinstance(it, dict) else type(it).__name__
            raise MissionFileError(
                path,
                f"unsupported item type {kind!r} (only SimpleItem; convert complex items in QGC)",
                section="mission",
                item_index=idx,
                field="type",
            )
        params = it.get("params")
        if not isinstance(params, list) or len(params) != 7:
            raise MissionFileError(
                path, "expected a list of 7 numbers", section="mission", item_index=idx, field="params"
            )
        for key in ("command", "frame"):
            if not isinstance(it.get(key), int) or isinstance(it.get(key), bool):
                raise MissionFileError(
                    path, f"expected an integer, got {it.get(key)!r}", section="mission", item_index=idx, field=key
                )
        p = [_plan_num(v, path, idx, f"params[{k}]") for k, v in enumerate(params)]
        auto = it.get("autoContinue", True)
        item = MissionItem(idx, it["command"], it["frame"], p[0], p[1], p[2], p[3], p[4], p[5], p[6], bool(auto))
        items.append(jump_shift(item, -1))
    fence: list[MissionItem] = []
    geofence = doc.get("geoFence") or {}
    try:
        for poly in geofence.get("polygons", []):
            verts = [(float(a), float(b)) for a, b in poly["polygon"]]
            fence += polygon_fence_items(len(fence), verts, inclusion=bool(poly.get("inclusion", True)))
        for circ in geofence.get("circles", []):
            (lat, lon), radius = circ["circle"]["center"], circ["circle"]["radius"]
            fence += circle_fence_items(
                len(fence), float(lat), float(lon), float(radius), inclusion=bool(circ.get("inclusion", True))
            )
    except (KeyError, TypeError, ValueError) as exc:
        raise MissionFileError(path, f"malformed zone: {exc!r}", section="geoFence") from None
    extra = doc.get("quadsitl") if isinstance(doc.get("quadsitl"), dict) else {}
    world = extra.get("world")
    return MissionPlan(
        str(extra.get("name") or path.stem),
        home,
        items,
        fence,
        leading_speed(items),
        str(extra.get("vehicle") or DEFAULT_VEHICLE),
        world if isinstance(world, dict) else None,
    )
