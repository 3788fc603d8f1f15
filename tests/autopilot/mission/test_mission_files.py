"""Mission files: YAML v1 / QGC WPL 110 / .plan round trips, and bad files refused naming item and field."""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest

from autopilot.geofence.fence import geofence_from_items
from autopilot.mission.files import MissionFileError, load_mission_file, save_mission_file
from autopilot.mission.plan import items_match
from mavlink_bridge.contract.frames import LocalNedFrame
from mavlink_bridge.contract.mav_enums import GripperAction, MavCmd, MavFrame
from mavlink_bridge.contract.vehicle_api import MissionType

FULL_YAML = """
name: city_block_delivery
home: {lat_deg: 30.2635, lon_deg: 120.1233, alt_m: 12.0}
vehicle: delivery650
speed_m_s: 5.0
mission:
  - takeoff: {alt_m: 10}
  - waypoint: {north_m: 40, east_m: 0, alt_m: 10, accept_radius_m: 1.0}
  - waypoint: {lat_deg: 30.2640, lon_deg: 120.1240, alt_m: 15, hold_s: 2, yaw_deg: 90}
  - pattern: {type: line, spacing_m: 5.0, length_m: 20}
  - payload_release: {}
  - loiter: {seconds: 3}
  - speed: {m_s: 3}
  - jump: {to_entry: 1, repeat: 2}
  - delay: {seconds: 2}
  - return_to_launch: {}
  - land: {}
fence:
  - exclusion_circle: {north_m: 60, east_m: 10, radius_m: 8}
  - exclusion_polygon: [[80, -5], [80, 5], [90, 5], [90, -5]]
  - inclusion_circle: {north_m: 0, east_m: 0, radius_m: 300}
world:
  obstacles:
    - cylinder: {north_m: 20, east_m: 1, radius_m: 3, height_m: 25}
  payload_kg: 1.0
"""


def line_pattern(ptype: str, spacing_m: float, params: dict) -> list[tuple[float, float, float]]:
    """Stand-in for autopilot.flight_tasks.trajectories: a straight line east at 12 m."""
    assert ptype == "line"
    n = int(params["length_m"] / spacing_m)
    return [(50.0, k * spacing_m, 12.0) for k in range(n + 1)]


def write(tmp_path: Path, text: str, name: str = "m.yaml") -> Path:
    p = tmp_path / name
    p.write_text(text)
    return p


def load(path: Path):
    return load_mission_file(path, expander=line_pattern)


def test_yaml_items_match_the_schema(tmp_path: Path) -> None:
    plan = load(write(tmp_path, FULL_YAML))
    cmds = [it.command for it in plan.items]
    assert cmds == [
        MavCmd.DO_CHANGE_SPEED,  # speed_m_s
        MavCmd.NAV_TAKEOFF,
        MavCmd.NAV_WAYPOINT,
        MavCmd.NAV_WAYPOINT,
        *[MavCmd.NAV_WAYPOINT] * 5,  # pattern: 0, 5, ..., 20 m
        MavCmd.DO_GRIPPER,
        MavCmd.NAV_LOITER_TIME,
        MavCmd.DO_CHANGE_SPEED,
        MavCmd.DO_JUMP,
        MavCmd.NAV_DELAY,
        MavCmd.NAV_RETURN_TO_LAUNCH,
        MavCmd.NAV_LAND,
    ]
    assert [it.seq for it in plan.items] == list(range(len(plan.items)))
    assert plan.name == "city_block_delivery" and plan.vehicle == "delivery650" and plan.speed_m_s == 5.0
    assert plan.world is not None and plan.world["payload_kg"] == 1.0
    frame = LocalNedFrame(plan.home)
    wp = plan.items[2]
    n, e, _ = frame.ned_from_geodetic(wp.x_lat_deg, wp.y_lon_deg, plan.home.alt_amsl_m)
    assert (n, e) == pytest.approx((40.0, 0.0), abs=1e-6)
    assert wp.param2 == 1.0 and wp.frame == MavFrame.GLOBAL_RELATIVE_ALT_INT and math.isnan(wp.param4)
    assert plan.items[3].param1 == 2.0 and plan.items[3].param4 == 90.0
    gripper = plan.items[9]
    assert gripper.param2 == GripperAction.RELEASE
    jump = plan.items[12]
    assert jump.param1 == 2.0 and jump.param2 == 2.0  # entry 1 (first waypoint) is item 2
    assert all(f.mission_type == MissionType.FENCE for f in plan.fence)
    fence = geofence_from_items(plan.fence, plan.home)
    assert len(fence.zones) == 3
    assert fence.violates((60.0, 10.0, -10.0)) and not fence.violates((0.0, 0.0, -10.0))


@pytest.mark.parametrize("ext", [".yaml", ".waypoints", ".txt", ".plan"])
def test_round_trip_is_exact(tmp_path: Path, ext: str) -> None:
    plan = load(write(tmp_path, FULL_YAML))
    out = tmp_path / f"out{ext}"
    save_mission_file(plan, out, allow_drop_fence=True)
    back = load(out)
    assert items_match(plan.items, back.items, deg_tol=0.0, tol=0.0)
    assert back.home == plan.home
    assert back.speed_m_s == plan.speed_m_s
    if ext == ".yaml":
        assert items_match(plan.fence, back.fence, deg_tol=0.0, tol=0.0)
        assert (back.name, back.vehicle, back.world) == (plan.name, plan.vehicle, plan.world)
    elif ext == ".plan":  # geoFence keeps polygons first, then circles
        zones = geofence_from_items(back.fence, back.home).zones
        kinds = sorted((type(z).__name__, z.inclusion) for z in zones)
        assert kinds == [("CircleZone", False), ("CircleZone", True), ("PolygonZone", False)]
        assert (back.name, back.vehicle, back.world) == (plan.name, plan.vehicle, plan.world)
    else:
        assert back.fence == []


def test_wpl_layout_has_home_line_and_shifted_jump(tmp_path: Path) -> None:
    plan = load(write(tmp_path, FULL_YAML))
    out = tmp_path / "m.waypoints"
    save_mission_file(plan, out, allow_drop_fence=True)
    lines = out.read_text().splitlines()
    assert lines[0] == "QGC WPL 110"
    home = lines[1].split("\t")
    assert home[:4] == ["0", "1", "0", "16"] and float(home[8]) == plan.home.lat_deg
    jump = lines[1 + 13].split("\t")  # item 12 is on file line 13
    assert jump[3] == str(int(MavCmd.DO_JUMP)) and float(jump[4]) == 3.0


def test_wpl_refuses_to_drop_a_fence_silently(tmp_path: Path) -> None:
    plan = load(write(tmp_path, FULL_YAML))
    with pytest.raises(MissionFileError, match="fence"):
        save_mission_file(plan, tmp_path / "m.waypoints")


def test_plan_json_is_qgc_shaped(tmp_path: Path) -> None:
    plan = load(write(tmp_path, FULL_YAML))
    out = tmp_path / "m.plan"
    save_mission_file(plan, out)
    doc = json.loads(out.read_text())
    assert doc["fileType"] == "Plan" and doc["mission"]["firmwareType"] == 12
    assert doc["mission"]["plannedHomePosition"] == [30.2635, 120.1233, 12.0]
    items = doc["mission"]["items"]
    assert all(it["type"] == "SimpleItem" and len(it["params"]) == 7 for it in items)
    assert items[1]["params"][3] is None  # NaN yaw written as null like QGC
    assert items[12]["command"] == MavCmd.DO_JUMP and items[12]["params"][0] == 3  # doJumpId of item 2
    assert len(doc["geoFence"]["polygons"]) == 1 and len(doc["geoFence"]["circles"]) == 2


def test_unknown_items_round_trip_through_yaml_as_mav_item(tmp_path: Path) -> None:
    text = """
home: {lat_deg: 47.0, lon_deg: 8.0, alt_m: 400.0}
mission:
  - takeoff: {alt_m: 10}
  - mav_item: {command: 16, frame: 3, param3: 2.5, lat_deg: 47.0001, lon_deg: 8.0001, alt_m: 20}
  - land: {}
"""
    plan = load(write(tmp_path, text))
    assert plan.items[1].frame == 3 and plan.items[1].param3 == 2.5
    save_mission_file(plan, tmp_path / "b.yaml")
    assert "mav_item" in (tmp_path / "b.yaml").read_text()
    assert items_match(load(tmp_path / "b.yaml").items, plan.items, deg_tol=0.0, tol=0.0)


BAD_CASES = [
    # (replacement mission entry, item index, field, message fragment)
    ("- waypoint: {lat_deg: 123.4, lon_deg: 8.0, alt_m: 10}", 1, "lat_deg", "outside [-90, 90]"),
    ("- waypoint: {lat_deg: 47.0, lon_deg: 200.0, alt_m: 10}", 1, "lon_deg", "outside [-180, 180]"),
    ("- waypoint: {north_m: .nan, east_m: 0, alt_m: 10}", 1, "north_m", "not a finite number"),
    ("- waypoint: {north_m: 10, east_m: 0}", 1, "alt_m", "missing required field"),
    ("- waypoint: {north_m: 10, east_m: 0, alt_m: 10, speed: 3}", 1, "speed", "unknown key"),
    ("- hover: {seconds: 3}", 1, "hover", "unknown mission entry"),
    ("- loiter: {seconds: -1}", 1, "seconds", "outside [0, 86400]"),
    ("- speed: {m_s: fast}", 1, "m_s", "expected a number"),
    ("- jump: {to_entry: 9, repeat: 1}", 1, "to_entry", "outside [0, 2]"),
]


@pytest.mark.parametrize(("entry", "index", "field", "fragment"), BAD_CASES)
def test_bad_yaml_names_item_and_field(tmp_path: Path, entry: str, index: int, field: str, fragment: str) -> None:
    text = f"""
home: {{lat_deg: 47.0, lon_deg: 8.0, alt_m: 400.0}}
mission:
  - takeoff: {{alt_m: 10}}
  {entry}
  - land: {{}}
"""
    path = write(tmp_path, text)
    with pytest.raises(MissionFileError) as info:
        load(path)
    msg = str(info.value)
    assert str(path) in msg and f"mission item {index}" in msg and f"field '{field}'" in msg and fragment in msg
    assert info.value.item_index == index and info.value.field == field


def test_bad_yaml_top_level_and_fence(tmp_path: Path) -> None:
    base = "home: {lat_deg: 47.0, lon_deg: 8.0, alt_m: 400.0}\nmission: []\n"
    with pytest.raises(MissionFileError, match=r"field 'mision'.*unknown top-level key"):
        load(write(tmp_path, base + "mision: []\n"))
    with pytest.raises(MissionFileError, match=r"home.*field 'lat_deg'.*missing"):
        load(write(tmp_path, "home: {lon_deg: 8.0, alt_m: 1}\n"))
    with pytest.raises(MissionFileError, match=r"fence item 0.*field 'radius_m'.*outside"):
        load(write(tmp_path, base + "fence:\n  - exclusion_circle: {north_m: 1, east_m: 2, radius_m: 0}\n"))
    with pytest.raises(MissionFileError, match=r"fence item 0.*at least 3"):
        load(write(tmp_path, base + "fence:\n  - exclusion_polygon: [[0, 0], [1, 1]]\n"))


def test_validation_after_parsing_names_the_item(tmp_path: Path) -> None:
    text = "home: {lat_deg: 47.0, lon_deg: 8.0, alt_m: 400.0}\nmission:\n  - takeoff: {alt_m: 500}\n"
    with pytest.raises(MissionFileError, match=r"mission item 0: field 'z_alt_m': altitude 500 m above home outside"):
        load(write(tmp_path, text))


def test_bad_wpl_and_plan_files(tmp_path: Path) -> None:
    with pytest.raises(MissionFileError, match="QGC WPL 110"):
        load(write(tmp_path, "hello\n", "a.waypoints"))
    bad_lat = "QGC WPL 110\n0\t1\t0\t16\t0\t0\t0\t0\t47\t8\t400\t1\n1\t0\t3\t16\t0\t0\t0\t0\t123.4\t8\t10\t1\n"
    with pytest.raises(MissionFileError, match=r"mission item 0: field 'x_lat_deg': latitude 123.4 outside"):
        load(write(tmp_path, bad_lat, "b.waypoints"))
    unknown = "QGC WPL 110\n0\t1\t0\t16\t0\t0\t0\t0\t47\t8\t400\t1\n1\t0\t3\t999\t0\t0\t0\t0\t47\t8\t10\t1\n"
    with pytest.raises(MissionFileError, match=r"field 'command'.*MAV_CMD 999 is not supported"):
        load(write(tmp_path, unknown, "c.txt"))
    nan_alt = "QGC WPL 110\n0\t1\t0\t16\t0\t0\t0\t0\t47\t8\t400\t1\n1\t0\t3\t16\t0\t0\t0\t0\t47\t8\tnan\t1\n"
    with pytest.raises(MissionFileError, match=r"field 'z_alt_m'.*nan"):
        load(write(tmp_path, nan_alt, "d.txt"))
    plan = {"fileType": "Plan", "mission": {"plannedHomePosition": [47, 8, 400], "items": [{"type": "ComplexItem"}]}}
    with pytest.raises(MissionFileError, match=r"mission item 0: field 'type'.*ComplexItem"):
        load(write(tmp_path, json.dumps(plan), "e.plan"))
    with pytest.raises(MissionFileError, match="unknown mission file extension"):
        load(write(tmp_path, "", "f.csv"))
