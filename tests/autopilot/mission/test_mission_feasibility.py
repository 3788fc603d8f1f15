"""Upload-time feasibility (issue 13): items in no-fly zones, outside the inclusion fence or above the ceiling
are refused naming the item; crossing legs are accepted; a mission with no route is refused; uploads before
home are stored and checked once home is known."""

from __future__ import annotations

import math

from autopilot.geofence.fence import circle_fence_items, geofence_from_items, polygon_fence_items
from autopilot.mission.feasibility import FeasibilityLimits, check_feasibility, mission_legs
from autopilot.mission.uploads import UploadStore
from autopilot.mission.validation import MissionLimits
from mavlink_bridge.contract.frames import GeoPoint, LocalNedFrame
from mavlink_bridge.contract.mav_enums import MavCmd, MavFrame
from mavlink_bridge.contract.vehicle_api import MissionItem, MissionResult, MissionType

HOME = GeoPoint(47.397742, 8.545594, 488.0)
FRAME = LocalNedFrame(HOME)
REL = int(MavFrame.GLOBAL_RELATIVE_ALT_INT)


def _ll(n: float, e: float) -> tuple[float, float]:
    g = FRAME.geodetic_from_ned(n, e, 0.0)
    return g.lat_deg, g.lon_deg


def mission(*points: tuple[float, float, float]) -> list[MissionItem]:
    """Takeoff, a waypoint per (north, east, alt), RTL."""
    items = [MissionItem(0, int(MavCmd.NAV_TAKEOFF), REL, param4=math.nan, z_alt_m=10.0)]
    for n, e, alt in points:
        lat, lon = _ll(n, e)
        items.append(MissionItem(len(items), int(MavCmd.NAV_WAYPOINT), REL, 0.0, 2.0, 0.0, math.nan, lat, lon, alt))
    items.append(MissionItem(len(items), int(MavCmd.NAV_RETURN_TO_LAUNCH), 2))
    return items


def circle(n: float, e: float, r: float, *, inclusion: bool = False, seq: int = 0) -> list[MissionItem]:
    return circle_fence_items(seq, *_ll(n, e), r, inclusion=inclusion)


def wall(seq: int = 0) -> list[MissionItem]:
    """An exclusion polygon across the north axis at 60-65 m, 80 m wide."""
    return polygon_fence_items(seq, [_ll(60, -40), _ll(60, 40), _ll(65, 40), _ll(65, -40)], inclusion=False)


def test_a_leg_crossing_zones_is_accepted() -> None:
    fence = geofence_from_items(circle(40, 0, 8) + wall(1), HOME)
    assert check_feasibility(mission((100, 0, 15)), HOME, fence) is None


def test_waypoint_inside_an_exclusion_zone_is_refused_naming_item_and_zone() -> None:
    fence = geofence_from_items(circle(40, 0, 8), HOME)
    issue = check_feasibility(mission((20, 0, 10), (42, 3, 10)), HOME, fence)
    assert issue is not None and issue.item_index == 2 and issue.result is MissionResult.INVALID_PARAM5_X
    assert issue.reason.startswith("item 2: inside exclusion circle 1 (r 8 m at 40 N 0 E)")


def test_waypoint_outside_the_inclusion_fence_is_refused() -> None:
    fence = geofence_from_items(circle(0, 0, 500, inclusion=True), HOME)
    issue = check_feasibility(mission((900, 0, 20)), HOME, fence)
    assert issue is not None and issue.item_index == 1
    assert "900 m from home, outside the inclusion fence (inclusion circle 1" in issue.reason


def test_item_above_the_ceiling_is_refused() -> None:
    issue = check_feasibility(mission((50, 0, 130)), HOME, geofence_from_items([], HOME), FeasibilityLimits(120.0))
    assert issue is not None and issue.result is MissionResult.INVALID_PARAM7
    assert "item 1: altitude 130 m above home, over the 120 m ceiling (GF_MAX_VER_DIST)" in issue.reason
    takeoff_high = mission((10, 0, 20))
    takeoff_high[0] = MissionItem(0, int(MavCmd.NAV_TAKEOFF), REL, param4=math.nan, z_alt_m=150.0)
    assert check_feasibility(takeoff_high, HOME, geofence_from_items([], HOME), FeasibilityLimits(120.0)) is not None


def test_a_mission_with_no_route_is_refused_with_the_reason() -> None:
    walled_in = polygon_fence_items(
        0, [_ll(60, -200), _ll(60, 200), _ll(65, 200), _ll(65, -200)], inclusion=False
    ) + circle(0, 0, 150, inclusion=True, seq=4)
    fence = geofence_from_items(walled_in, HOME)
    issue = check_feasibility(mission((100, 0, 15)), HOME, fence)
    assert issue is not None and issue.result is MissionResult.INVALID and issue.item_index == 1
    assert issue.reason.startswith("item 1: no route from item 0 around the fence (no path")


def test_home_outside_the_fence_refuses_every_mission() -> None:
    fence = geofence_from_items(circle(0, 0, 5), HOME)
    issue = check_feasibility(mission((50, 0, 10)), HOME, fence)
    assert issue is not None and "home lies outside the geofence" in issue.reason


def test_legs_follow_takeoff_rtl_and_jumps() -> None:
    items = mission((50, 0, 10), (50, 50, 12))
    items.insert(3, MissionItem(3, int(MavCmd.DO_JUMP), 2, 1.0, 1.0))
    legs = mission_legs(items, HOME, FeasibilityLimits(rtl_alt_m=30.0))
    assert [(leg.from_seq, leg.to_seq) for leg in legs] == [(0, 1), (1, 2), (2, 1), (2, 4)]
    assert legs[0].start_ned_m == (0.0, 0.0, -10.0)
    assert legs[-1].goal_ned_m == (0.0, 0.0, -30.0)  # RTL at MIS_RTL_ALT


def test_uploads_before_home_are_stored_and_what_needs_home_is_checked_once_it_is_known() -> None:
    store = UploadStore()
    store.set_limits(FeasibilityLimits(ceiling_m=50.0), MissionLimits())
    assert store.upload(MissionType.FENCE, circle(40, 0, 8)) == (MissionResult.ACCEPTED, "")
    assert store.upload(MissionType.MISSION, mission((20, 0, 80))) == (MissionResult.ACCEPTED, "")  # ceiling: home
    assert not store.flyable  # no home yet
    assert "once home is known" in store.drain_texts()[-1].text
    store.set_home(HOME)
    assert not store.flyable and store.mission_issue.startswith("item 1: altitude 80 m above home, over the 50 m")
    assert store.drain_texts()[-1].text.startswith("Mission not flyable from home: item 1: altitude 80 m")
    store.set_limits(FeasibilityLimits(ceiling_m=120.0), MissionLimits())
    assert store.flyable and store.drain_texts()[-1].text == "Mission flyable with the new limits"
    assert store.upload(MissionType.FENCE, circle(20, 0, 8)) == (MissionResult.ACCEPTED, "")
    assert not store.flyable and store.drain_texts()[-1].text.startswith(
        "Mission not flyable with the new fence: item 1: inside exclusion circle 1"
    )
    assert store.upload(MissionType.FENCE, circle(40, 30, 8)) == (MissionResult.ACCEPTED, "")
    assert store.flyable and store.drain_texts()[-1].text == "Mission flyable with the new fence"
    result, reason = store.upload(MissionType.MISSION, mission((40, 31, 10)))
    assert result is MissionResult.INVALID_PARAM5_X and reason.startswith("item 1: inside exclusion circle 1")
    assert store.drain_texts()[-1].text.startswith("Mission refused: item 1")
    assert store.flyable  # the previous mission is kept


def _upload_with_and_without_home(
    fence: list[MissionItem], items: list[MissionItem]
) -> list[tuple[MissionResult, str]]:
    """The answers to the same FENCE then MISSION upload before the first fix and after it."""
    answers = []
    for home in (None, HOME):
        store = UploadStore()
        if home is not None:
            store.set_home(home)
        assert store.upload(MissionType.FENCE, fence) == (MissionResult.ACCEPTED, "")
        answers.append(store.upload(MissionType.MISSION, items))
        assert not store.mission and not store.flyable
    return answers


def test_waypoint_in_an_exclusion_zone_is_refused_before_and_after_the_first_fix_with_the_same_reason() -> None:
    lat, lon = _ll(40, 0)
    before, after = _upload_with_and_without_home(circle(40, 0, 8), mission((20, 0, 10), (41, 1, 10)))
    assert before == after
    assert before == (
        MissionResult.INVALID_PARAM5_X,
        f"item 2: inside exclusion circle 1 (r 8 m at {lat:.6f}, {lon:.6f})",
    )
    before, after = _upload_with_and_without_home(wall(), mission((62, 0, 10)))
    assert (
        before
        == after
        == (MissionResult.INVALID_PARAM5_X, "item 1: inside exclusion polygon 1 (4 vertices, fence items 0-3)")
    )


def test_waypoint_outside_the_inclusion_zones_is_refused_before_and_after_the_first_fix() -> None:
    before, after = _upload_with_and_without_home(circle(0, 0, 500, inclusion=True), mission((900, 0, 20)))
    assert before == after
    zone = f"inclusion circle 1 (r 500 m at {HOME.lat_deg:.6f}, {HOME.lon_deg:.6f})"
    assert before[1] == f"item 1: 400 m outside the inclusion fence ({zone})"


def test_a_fence_uploaded_after_the_mission_marks_it_not_flyable_before_the_fix() -> None:
    store = UploadStore()
    assert store.upload(MissionType.MISSION, mission((41, 1, 10))) == (MissionResult.ACCEPTED, "")
    assert store.upload(MissionType.FENCE, circle(40, 0, 8)) == (MissionResult.ACCEPTED, "")
    assert store.mission_issue.startswith("item 1: inside exclusion circle 1")
    assert store.drain_texts()[-1].text.startswith("Mission not flyable with the new fence: item 1: inside")
    store.set_home(HOME)
    assert not store.flyable and store.mission_issue.startswith("item 1: inside exclusion circle 1")


def test_bad_fence_is_refused_naming_the_item_before_home_too() -> None:
    store = UploadStore()
    bad = circle(40, 0, 8) + circle(10, 0, -3, seq=1)
    result, reason = store.upload(MissionType.FENCE, bad)
    assert result is MissionResult.INVALID and reason == "fence item 1: circle radius (param1) -3.0 must be > 0 m"
    assert store.drain_texts()[-1].text == f"Fence refused: {reason}"
    nan_vertex = wall()
    nan_vertex[2] = MissionItem(2, nan_vertex[2].command, nan_vertex[2].frame, 4.0, x_lat_deg=math.nan,
                                mission_type=MissionType.FENCE)  # fmt: skip
    result, reason = store.upload(MissionType.FENCE, nan_vertex)
    assert result is not MissionResult.ACCEPTED and reason.startswith("fence item 2:")
