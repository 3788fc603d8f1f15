"""TrafficAvoidance.update: the actions of NAV_TRAFF_AVOID, texts, fences and altitude limits of the detour."""

from __future__ import annotations

import math

import numpy as np
import pytest
from traffic_kinematic import HOME, report

from autopilot.param_schema import make_param_store
from autopilot.planner.geometry import CircleZone
from autopilot.safety.failsafe import FailsafeAction, FailsafeKind
from autopilot.traffic import AvoidLimits, Maneuver, OwnShip, TrafficAction, TrafficAvoidance, TrafficParams
from autopilot.traffic.avoidance import RESAY_US
from mavlink_bridge.contract.traffic import TrafficSource

LIMITS = AvoidLimits(down_min_m=-120.0, down_max_m=-2.0)


def _own(t_us: int = 1_000_000, pos=(0.0, 0.0, -20.0), vel=(5.0, 0.0, 0.0), goal=(300.0, 0.0, -20.0)) -> OwnShip:  # type: ignore[no-untyped-def]
    return OwnShip(t_us, pos, vel, (goal,), 5.0, 2)


def _head_on(source: TrafficSource = TrafficSource.UAV, target_id: int = 1, alt_m: float = 20.0):  # type: ignore[no-untyped-def]
    return report(source, target_id, np.array((200.0, 1.0, -alt_m)), np.array((-5.0, 0.0, 0.0)), 1_000_000)


def _slow_head_on(alt_m: float = 20.0):  # type: ignore[no-untyped-def]
    """A UAV creeping toward the vehicle on its route (slower than a reciprocating vehicle: it will not move aside)."""
    return report(TrafficSource.UAV, 1, np.array((200.0, 1.0, -alt_m)), np.array((-0.9, 0.0, 0.0)), 1_000_000)


def _hovering(target_id: int = 1, alt_m: float = 20.0):  # type: ignore[no-untyped-def]
    """A UAV hovering on the route 60 m ahead (it will not move aside: the strategic detour's case)."""
    return report(TrafficSource.UAV, target_id, np.array((60.0, 1.0, -alt_m)), np.zeros(3), 1_000_000)


def _avoidance(action: TrafficAction) -> TrafficAvoidance:
    avoidance = TrafficAvoidance(TrafficParams(action=action), system_id=2)
    avoidance.set_home(HOME)
    return avoidance


def test_parameters_are_in_the_schema_with_px4_names() -> None:
    store = make_param_store()
    params = TrafficParams.from_store(store)
    assert params.action is TrafficAction.AVOID and params.horizon_s == 60.0
    assert (params.uav.hor_m, params.uav.ver_m, params.manned.hor_m, params.manned.ver_m) == (10, 5, 150, 30)
    store.set("NAV_TRAFF_AVOID", 1.0)
    assert TrafficParams.from_store(store).action is TrafficAction.WARN


def test_warn_only_warns() -> None:
    avoidance = _avoidance(TrafficAction.WARN)
    decision = avoidance.update(_own(), [_head_on()], LIMITS)
    assert [c.track.target_id for c in decision.conflicts] == [1]
    assert decision.resolution is None and decision.failsafe is None and decision.setpoint(1_000_000) is None
    (text,) = [t.text for t in decision.texts if "conflict" in t.text]
    assert text.startswith("Traffic conflict: UAV 1 in ") and "keep 10/5 m" in text
    assert not any("conflict" in t.text for t in avoidance.update(_own(1_100_000), [], LIMITS).texts)  # said once


def test_off_tracks_but_never_acts() -> None:
    decision = _avoidance(TrafficAction.OFF).update(_own(), [_head_on()], LIMITS)
    assert len(decision.tracks) == 1 and decision.conflicts == () and decision.texts == ()


@pytest.mark.parametrize(
    ("action", "failsafe"),
    [(TrafficAction.RETURN, FailsafeAction.RTL), (TrafficAction.LAND, FailsafeAction.LAND),
     (TrafficAction.HOLD, FailsafeAction.HOLD)],
)  # fmt: skip
def test_return_land_hold_are_commander_failsafes_once_per_conflict(action, failsafe) -> None:  # type: ignore[no-untyped-def]
    avoidance = _avoidance(action)
    decision = avoidance.update(_own(), [_head_on()], LIMITS)
    assert decision.failsafe is not None
    assert (decision.failsafe.kind, decision.failsafe.action) == (FailsafeKind.TRAFFIC, failsafe)
    assert avoidance.update(_own(1_100_000), [], LIMITS).failsafe is None
    assert _avoidance(action).update(_own(), [_head_on()], LIMITS, airborne=False).failsafe is None


def test_a_uav_flying_on_is_left_to_the_reactive_layer() -> None:
    """Both vehicles share a conflict between two flying quadsitl vehicles (ORCA, every step): no detour."""
    decision = _avoidance(TrafficAction.AVOID).update(_own(), [_head_on()], LIMITS)
    assert decision.conflicts and decision.resolution is None


def test_avoid_flies_a_detour_that_rejoins_the_route_and_says_so() -> None:
    decision = _avoidance(TrafficAction.AVOID).update(_own(), [_hovering()], LIMITS)
    res = decision.resolution
    assert res is not None and res.safe and res.maneuver is Maneuver.RIGHT
    assert any(t.text.startswith("Traffic: giving way to UAV 1: turn right") for t in decision.texts)
    start = decision.setpoint(1_000_000)
    assert start is not None and start[0] == pytest.approx((0.0, 0.0, -20.0))
    end = res.path.state_tuple(res.path.duration_s)[0]  # type: ignore[union-attr]
    assert end[1] == pytest.approx(0.0, abs=1e-6) and 0.0 < end[0] < 300.0  # back on the route, before the target
    assert decision.setpoint(1_000_000 + round(res.path.duration_s * 1e6) + 1) is None  # type: ignore[union-attr]


def test_outside_a_mission_avoid_only_warns() -> None:
    decision = _avoidance(TrafficAction.AVOID).update(_own(), [_head_on()], LIMITS, can_avoid=False)
    assert decision.resolution is None
    assert any("not in a mission, warning only" in t.text for t in decision.texts)


def test_stand_on_vehicle_keeps_its_route_until_last_resort() -> None:
    avoidance = TrafficAvoidance(TrafficParams(), system_id=1)
    avoidance.set_home(HOME)
    intruder = report(TrafficSource.UAV, 2, np.array((100.0, -100.0, -20.0)), np.array((0.0, 5.0, 0.0)), 1_000_000)
    decision = avoidance.update(_own(), [intruder], LIMITS)
    assert decision.conflicts and decision.conflicts[0].role.value == "standing on" and decision.resolution is None


def test_detour_respects_the_fence() -> None:
    """An exclusion zone right of the route: the detour goes another way and keeps the fence margin."""
    zone = CircleZone((100.0, 25.0), 12.0)
    limits = AvoidLimits(down_min_m=-120.0, down_max_m=-2.0, fences=(zone,), fence_margin_m=3.0)
    decision = _avoidance(TrafficAction.AVOID).update(_own(), [_slow_head_on()], limits)
    res = decision.resolution
    assert res is not None and res.maneuver is not Maneuver.RIGHT
    assert any("crosses the fence" in why for why in res.refused)
    assert any(t.text.endswith("(turn right: crosses the fence)") for t in decision.texts), decision.texts
    samples = res.path.sample(0.5)  # type: ignore[union-attr]
    assert all(math.hypot(p[0] - 100.0, p[1] - 25.0) > 15.0 for p in samples)


def test_detour_respects_the_altitude_floor_and_ceiling() -> None:
    """Low and under a ceiling: no descent below CA_MIN_AGL_M, no climb above the ceiling."""
    limits = AvoidLimits(down_min_m=-24.0, down_max_m=-2.0)
    own = _own(pos=(0.0, 0.0, -4.0), goal=(300.0, 0.0, -4.0))
    res = _avoidance(TrafficAction.AVOID).update(own, [_slow_head_on(alt_m=4.0)], limits).resolution
    assert res is not None and res.path is not None
    downs = res.path.sample(0.5)[:, 2]
    assert downs.max() <= -2.0 + 0.1 and downs.min() >= -24.0 - 0.1


def test_manned_traffic_gives_a_vertical_or_horizontal_escape_of_the_nmac_volume() -> None:
    heli = report(TrafficSource.MANNED, 0xA1B2C3, np.array((1500.0, 0.0, -40.0)), np.array((-40.0, 0.0, 0.0)),
                  1_000_000)  # fmt: skip
    decision = _avoidance(TrafficAction.AVOID).update(_own(), [heli], LIMITS)
    assert decision.conflicts[0].volume.hor_m == 150.0
    assert decision.resolution is not None and decision.resolution.safe


def test_parked_vehicles_at_the_depot_are_not_conflicts() -> None:
    parked = report(TrafficSource.UAV, 1, np.array((0.0, 8.0, 0.0)), np.zeros(3), 1_000_000)
    own = _own(pos=(0.0, 0.0, -3.0), vel=(0.0, 0.0, 0.5), goal=(0.0, 0.0, 0.0))
    assert _avoidance(TrafficAction.AVOID).update(own, [parked], LIMITS).conflicts == ()


def test_garbage_reports_are_said_once_per_interval() -> None:
    avoidance = _avoidance(TrafficAction.AVOID)
    bad = report(TrafficSource.UAV, 1, np.zeros(3), np.full(3, math.nan), 1_000_000)
    first = avoidance.update(_own(), [bad], LIMITS)
    assert first.rejected == ("traffic report UAV/1: position or velocity is not finite",)
    assert [t.text for t in first.texts] == [
        "Traffic report refused: traffic report UAV/1: position or velocity is not finite"
    ]
    assert avoidance.update(_own(1_500_000), [bad], LIMITS).texts == ()


def test_stale_track_in_conflict_is_dropped_and_said() -> None:
    avoidance = _avoidance(TrafficAction.WARN)
    avoidance.update(_own(), [_head_on()], LIMITS)
    later = avoidance.update(_own(7_000_000), [], LIMITS)
    assert later.tracks == () and any("track lost" in t.text for t in later.texts)


def test_a_hovering_uav_owns_the_column_below_it_and_is_passed_beside_not_under() -> None:
    """A UAV hovering over its drop point 7 m above the route (outside the 5 m half-height) may land at any
    moment: the vehicle below gives way even with the lower system id and passes beside it (seed 9 of the
    overtaking encounters: the overtaker passed under a vehicle that then landed on its way)."""
    avoidance = TrafficAvoidance(TrafficParams(), system_id=1)
    avoidance.set_home(HOME)
    hovering = report(TrafficSource.UAV, 2, np.array((60.0, 1.0, -27.0)), np.array((0.0, 0.0, 0.0)), 1_000_000)
    decision = avoidance.update(_own(), [hovering], LIMITS)
    assert decision.conflicts and decision.conflicts[0].role.value == "giving way"
    res = decision.resolution
    assert res is not None and res.safe and res.maneuver in (Maneuver.LEFT, Maneuver.RIGHT), res
    moving = report(TrafficSource.UAV, 2, np.array((60.0, 1.0, -27.0)), np.array((5.0, 0.0, 0.0)), 1_000_000)
    assert not _avoidance(TrafficAction.AVOID).update(_own(), [moving], LIMITS).conflicts  # 7 m above: separated


def test_low_under_a_manned_aircraft_a_descent_to_the_floor_keeps_the_nmac_volume() -> None:
    """Cruising at 15 m with a light aircraft at 38 m coming head-on (16 s to the loss of separation) and a 60 m
    ceiling: no climb over it, no sidestep of 150 m in time, but the altitude floor (2 m) is 36 m under it, more
    than the 30 m half-height. The planned descent (sized for the grown volume) is cut at the floor instead of
    refused, and the vehicle keeps the NMAC volume."""
    limits = AvoidLimits(down_min_m=-60.0, down_max_m=-2.0)
    own = _own(pos=(0.0, 0.0, -15.0), goal=(300.0, 0.0, -15.0))
    plane_pos, plane_vel = np.array((900.0, 0.0, -38.0)), np.array((-45.0, 0.0, 0.0))
    plane = report(TrafficSource.MANNED, 0xA1B2C3, plane_pos, plane_vel, 1_000_000)
    res = _avoidance(TrafficAction.AVOID).update(own, [plane], limits).resolution
    assert res is not None and res.path is not None and res.maneuver is Maneuver.DESCEND
    times_s = np.arange(0.0, min(res.path.duration_s, 40.0), 0.1)  # the aircraft is past by then
    assert times_s[-1] > 25.0
    pos = np.array([res.path.state_tuple(float(t))[0] for t in times_s])
    assert pos[:, 2].max() <= -2.0 + 0.1  # never below the floor
    rel = plane_pos + np.outer(times_s, plane_vel) - pos
    inside = (np.hypot(rel[:, 0], rel[:, 1]) < 150.0) & (np.abs(rel[:, 2]) < 30.0)
    assert not inside.any()


def test_the_same_detour_planned_again_is_said_again_only_after_a_while() -> None:
    """In a crowd the detour is replanned at every report; the same one (track, role, manoeuvre) is said once per
    RESAY_US (encounter case 682 said "giving way to UAV 7: stop" 30 times in 5 s)."""
    avoidance = _avoidance(TrafficAction.AVOID)
    said = []
    for k in range(30):  # 15 s of reports at 2 Hz, the detour dropped and planned anew after each
        t_us = 1_000_000 + k * 500_000
        hovering = report(TrafficSource.UAV, 1, np.array((60.0, 1.0, -20.0)), np.zeros(3), t_us)
        decision = avoidance.update(_own(t_us), [hovering], LIMITS)
        said += [(t_us, t.text) for t in decision.texts if t.text.startswith("Traffic: giving way")]
        avoidance.resolution = None
    assert [t for t, _ in said] == [1_000_000, 1_000_000 + RESAY_US]
    assert all(text.startswith("Traffic: giving way to UAV 1: turn right") for _, text in said)
