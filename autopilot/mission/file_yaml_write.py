"""Writing a MissionPlan as the project's YAML v1: friendly entries where they read back exactly, else mav_item."""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path
from typing import Any

import yaml

from autopilot.mission.file_common import MissionFileError, fence_shapes, speed_item
from autopilot.mission.file_yaml_read import YamlReader
from autopilot.mission.plan import MissionPlan, items_match
from mavlink_bridge.contract.frames import LocalNedFrame
from mavlink_bridge.contract.mav_enums import GripperAction, MavCmd, MavFrame
from mavlink_bridge.contract.vehicle_api import MissionItem

_MISSION_FRAME = int(MavFrame.MISSION)


def _clean(d: dict[str, Any]) -> dict[str, Any]:
    return {k: v for k, v in d.items() if not (isinstance(v, float) and math.isnan(v))}


def _friendly_entry(item: MissionItem, seq_offset: int) -> dict[str, Any] | None:
    """The friendly YAML form of one item, or None when only ``mav_item`` can express it."""
    ll = {"lat_deg": item.x_lat_deg, "lon_deg": item.y_lon_deg}
    yaw = {"yaw_deg": item.param4}
    cmd = item.command
    if cmd == MavCmd.NAV_TAKEOFF:
        here = item.x_lat_deg == 0.0 and item.y_lon_deg == 0.0
        return {"takeoff": _clean({"alt_m": item.z_alt_m, **({} if here else ll), **yaw})}
    if cmd == MavCmd.NAV_WAYPOINT:
        body = {**ll, "alt_m": item.z_alt_m, "accept_radius_m": item.param2, "hold_s": item.param1, **yaw}
        return {"waypoint": _clean({k: v for k, v in body.items() if k not in ("accept_radius_m", "hold_s") or v})}
    if cmd == MavCmd.DO_GRIPPER:
        kind = "payload_release" if item.param2 == GripperAction.RELEASE else "payload_grab"
        return {kind: {} if item.param1 == 1.0 else {"gripper": item.param1}}
    if cmd == MavCmd.NAV_LOITER_TIME:
        here = item.x_lat_deg == 0.0 and item.y_lon_deg == 0.0
        return {"loiter": _clean({"seconds": item.param1, **({} if here else {**ll, "alt_m": item.z_alt_m}), **yaw})}
    if cmd == MavCmd.DO_CHANGE_SPEED:
        return {"speed": {"m_s": item.param2}}
    if cmd == MavCmd.NAV_DELAY:
        return {"delay": {"seconds": item.param1}}
    if cmd == MavCmd.DO_JUMP:
        return {"jump": {"to_entry": int(item.param1) - seq_offset, "repeat": int(item.param2)}}
    if cmd == MavCmd.NAV_RETURN_TO_LAUNCH:
        return {"return_to_launch": {}}
    if cmd == MavCmd.NAV_LAND:
        here = item.x_lat_deg == 0.0 and item.y_lon_deg == 0.0
        return {"land": _clean({**({} if here else ll), **yaw})}
    return None


def _raw_entry(item: MissionItem) -> dict[str, Any]:
    return {
        "mav_item": {
            "command": item.command,
            "frame": item.frame,
            "param1": item.param1,
            "param2": item.param2,
            "param3": item.param3,
            "param4": item.param4,
            "lat_deg": item.x_lat_deg,
            "lon_deg": item.y_lon_deg,
            "alt_m": item.z_alt_m,
            "autocontinue": item.autocontinue,
        }
    }


def _yaml_mission_entries(plan: MissionPlan, path: str | Path) -> list[dict[str, Any]]:
    items = list(plan.items)
    offset = 0
    if plan.speed_m_s is not None and items and items_match(items[:1], [replace(speed_item(plan.speed_m_s))]):
        items, offset = items[1:], 1
    frame = LocalNedFrame(plan.home)
    reader = YamlReader(path, _no_patterns)
    entries: list[dict[str, Any]] = []
    for item in items:
        entry = _friendly_entry(item, offset)
        if entry is not None:
            ((kind, body),) = entry.items()
            try:
                if kind == "jump":
                    back = [MissionItem(0, int(MavCmd.DO_JUMP), _MISSION_FRAME, param1=item.param1, param2=item.param2)]
                    exact = body["to_entry"] >= 0
                else:
                    back, exact = reader.entry(kind, body, frame), True
            except MissionFileError:
                back, exact = [], False
            if not (exact and items_match([replace(b, seq=item.seq) for b in back], [item], deg_tol=0.0, tol=0.0)):
                entry = None
        entries.append(entry if entry is not None else _raw_entry(item))
    return entries


def _no_patterns(pattern_type: str, spacing_m: float, params: dict[str, Any]) -> list[tuple[float, float, float]]:
    raise ValueError("patterns are not expanded while writing")


def _yaml_fence_entries(plan: MissionPlan) -> list[dict[str, Any]]:
    entries = []
    for first, verts in fence_shapes(plan.fence):
        inclusion = first.command in (MavCmd.NAV_FENCE_CIRCLE_INCLUSION, MavCmd.NAV_FENCE_POLYGON_VERTEX_INCLUSION)
        group = {"group": int(first.param2)} if inclusion and first.param2 else {}
        prefix = "inclusion" if inclusion else "exclusion"
        if first.command in (MavCmd.NAV_FENCE_CIRCLE_INCLUSION, MavCmd.NAV_FENCE_CIRCLE_EXCLUSION):
            body = {"lat_deg": first.x_lat_deg, "lon_deg": first.y_lon_deg, "radius_m": first.param1, **group}
            entries.append({f"{prefix}_circle": body})
        else:
            entries.append({f"{prefix}_polygon": {"vertices_lat_lon_deg": [list(v) for v in verts], **group}})
    return entries


def write_yaml(plan: MissionPlan, path: Path) -> None:
    doc: dict[str, Any] = {
        "name": plan.name,
        "home": {"lat_deg": plan.home.lat_deg, "lon_deg": plan.home.lon_deg, "alt_m": plan.home.alt_amsl_m},
    }
    if plan.vehicle:  # empty: not known (a downloaded mission): no line rather than a wrong name
        doc["vehicle"] = plan.vehicle
    if plan.speed_m_s is not None:
        doc["speed_m_s"] = plan.speed_m_s
    doc["mission"] = _yaml_mission_entries(plan, path)
    if plan.fence:
        doc["fence"] = _yaml_fence_entries(plan)
    if plan.world is not None:
        doc["world"] = plan.world
    path.write_text(yaml.safe_dump(doc, sort_keys=False, default_flow_style=None, width=120))
