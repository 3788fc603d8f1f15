"""Upload validation: one result code and a readable reason per kind of bad item; MIS_* limits; param schema."""

from __future__ import annotations

import math
from dataclasses import replace

import pytest

from autopilot.mission.validation import MissionLimits, check_mission, validate_mission
from autopilot.param_schema import all_param_specs, make_param_store, markdown_reference
from mavlink_bridge.contract.frames import GeoPoint, LocalNedFrame
from mavlink_bridge.contract.mav_enums import MavCmd, MavFrame
from mavlink_bridge.contract.vehicle_api import MissionItem, MissionResult, MissionType

HOME = GeoPoint(47.397742, 8.545594, 488.0)
REL = int(MavFrame.GLOBAL_RELATIVE_ALT_INT)


def good_mission() -> list[MissionItem]:
    g = LocalNedFrame(HOME).geodetic_from_ned(30.0, 10.0, 0.0)
    return [
        MissionItem(0, int(MavCmd.NAV_TAKEOFF), REL, param4=math.nan, z_alt_m=10.0),
        MissionItem(1, int(MavCmd.NAV_WAYPOINT), REL, 0.0, 2.0, 0.0, math.nan, g.lat_deg, g.lon_deg, 10.0),
        MissionItem(2, int(MavCmd.DO_GRIPPER), 2, 1.0, 0.0),
        MissionItem(3, int(MavCmd.DO_CHANGE_SPEED), 2, 1.0, 3.0, -1.0),
        MissionItem(4, int(MavCmd.DO_JUMP), 2, 1.0, 2.0),
        MissionItem(5, int(MavCmd.NAV_LOITER_TIME), REL, 3.0),
        MissionItem(6, int(MavCmd.NAV_DELAY), 2, 1.0, -1.0, -1.0, -1.0),
        MissionItem(7, int(MavCmd.NAV_RETURN_TO_LAUNCH), 2),
        MissionItem(8, int(MavCmd.NAV_LAND), REL, param4=math.nan),
    ]


def with_item(index: int, **changes: object) -> list[MissionItem]:
    items = good_mission()
    items[index] = replace(items[index], **changes)
    return items


def test_good_mission_and_empty_list_are_accepted() -> None:
    assert validate_mission(good_mission(), HOME) == (MissionResult.ACCEPTED, "")
    assert validate_mission([], HOME) == (MissionResult.ACCEPTED, "")


BAD = [
    (with_item(1, x_lat_deg=123.4), MissionResult.INVALID_PARAM5_X, "item 1: latitude 123.4 outside [-90, 90]"),
    (with_item(1, y_lon_deg=-181.0), MissionResult.INVALID_PARAM6_Y, "item 1: longitude -181 outside [-180, 180]"),
    (with_item(1, z_alt_m=math.nan), MissionResult.INVALID_PARAM7, "item 1: altitude (z) is nan"),
    (with_item(1, x_lat_deg=math.inf), MissionResult.INVALID_PARAM5_X, "item 1: latitude (x) is inf"),
    (with_item(3, param2=math.nan), MissionResult.INVALID_PARAM2, "item 3: param2 is nan"),
    (with_item(2, command=31000), MissionResult.UNSUPPORTED, "item 2: command MAV_CMD 31000 is not supported"),
    (with_item(1, frame=int(MavFrame.LOCAL_NED)), MissionResult.UNSUPPORTED_FRAME, "item 1: frame LOCAL_NED"),
    (with_item(4, seq=7), MissionResult.INVALID_SEQUENCE, "item 4: sequence number 7, expected 4"),
    (with_item(4, param1=9.0), MissionResult.INVALID_PARAM1, "item 4: DO_JUMP target 9 outside [0, 8]"),
    (with_item(4, param1=4.0), MissionResult.INVALID_PARAM1, "or the jump itself"),
    (with_item(4, param1=2.0), MissionResult.INVALID_PARAM1, "item 4: DO_JUMP loop 2..4 contains no navigation"),
    (with_item(4, param2=-3.0), MissionResult.INVALID_PARAM2, "repeat -3 must be an integer >= -1"),
    (with_item(1, z_alt_m=500.0), MissionResult.INVALID_PARAM7, "item 1: altitude 500 m above home outside [1, 120]"),
    (with_item(0, z_alt_m=0.2), MissionResult.INVALID_PARAM7, "item 0: altitude 0.2 m above home"),
    (with_item(3, param2=99.0), MissionResult.INVALID_PARAM2, "item 3: speed 99 m/s outside (0, 20]"),
    (with_item(2, param2=5.0), MissionResult.INVALID_PARAM2, "gripper action 5 must be 0 (release) or 1 (grab)"),
    (with_item(5, param1=-1.0), MissionResult.INVALID_PARAM1, "NAV_LOITER_TIME time -1 s must be >= 0"),
    (with_item(1, param2=-1.0), MissionResult.INVALID_PARAM2, "acceptance radius -1 m must be >= 0"),
    (with_item(1, x_lat_deg=48.0), MissionResult.INVALID_PARAM5_X, "m from home, more than the 10000 m allowed"),
    (with_item(1, mission_type=MissionType.FENCE), MissionResult.INVALID, "mission_type"),
]


@pytest.mark.parametrize(("items", "result", "fragment"), BAD)
def test_bad_items_are_refused_with_a_reason(items: list[MissionItem], result: MissionResult, fragment: str) -> None:
    got, reason = validate_mission(items, HOME)
    assert got == result
    assert fragment in reason


def test_nan_yaw_is_allowed_where_mavlink_allows_it() -> None:
    assert validate_mission(with_item(1, param4=math.nan), HOME)[0] == MissionResult.ACCEPTED
    assert validate_mission(with_item(2, param4=math.nan), HOME)[0] == MissionResult.INVALID_PARAM4


def test_too_many_items_and_limits_from_params() -> None:
    store = make_param_store()
    limits = MissionLimits.from_params(store)
    assert limits == MissionLimits()
    g = LocalNedFrame(HOME).geodetic_from_ned(5.0, 5.0, 0.0)
    big = [MissionItem(k, int(MavCmd.NAV_WAYPOINT), REL, 0, 0, 0, 0, g.lat_deg, g.lon_deg, 10.0) for k in range(600)]
    assert validate_mission(big, HOME, limits)[0] == MissionResult.ACCEPTED
    store.set("MIS_MAX_ITEMS", 500)
    result, reason = validate_mission(big, HOME, MissionLimits.from_params(store))
    assert result == MissionResult.NO_SPACE and reason == "mission has 600 items, at most 500 allowed"


def test_issue_names_index_and_field() -> None:
    issue = check_mission(with_item(1, y_lon_deg=math.nan), HOME)
    assert issue is not None and (issue.item_index, issue.field) == (1, "y_lon_deg")


def test_fence_lists_are_validated_as_zones() -> None:
    circle = MissionItem(0, int(MavCmd.NAV_FENCE_CIRCLE_EXCLUSION), 0, 10.0, 0, 0, 0, 47.3978, 8.5456, 0, True, 1)
    assert validate_mission([circle], HOME)[0] == MissionResult.ACCEPTED
    result, reason = validate_mission([replace(circle, param1=0.0)], HOME)
    assert result == MissionResult.INVALID and reason == "item 0: circle radius (param1) 0.0 must be > 0 m"
    vertex = MissionItem(0, int(MavCmd.NAV_FENCE_POLYGON_VERTEX_EXCLUSION), 0, 4.0, 0, 0, 0, 47.3978, 8.5456, 0)
    vertex = replace(vertex, mission_type=MissionType.FENCE)
    three = [replace(vertex, seq=k) for k in range(3)]
    result, reason = validate_mission(three, HOME)
    assert result == MissionResult.INVALID and "declares 4 vertices but only 3" in reason


def test_param_schema_names_are_unique_and_documented() -> None:
    specs = all_param_specs()
    names = [s.name for s in specs]
    assert len(names) == len(set(names))
    for required in ("MIS_ACC_RAD", "MIS_CRUISE_SPD", "MIS_RTL_ALT", "CA_RSAFE_M", "MPC_XY_VEL_MAX"):
        assert required in names
    assert all(s.description for s in specs)
    store = make_param_store()
    assert store.get("MIS_ACC_RAD") == 1.0
    md = markdown_reference()
    assert all(f"`{n}`" in md for n in names)
