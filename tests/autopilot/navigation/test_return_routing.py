"""Every return routed (issue 22 item 2): the commander's RTL flies the navigator's route home around the fence.

Commander + navigator + a kinematic vehicle (``autopilot_fakes.KinematicLoop``), no sim: an RTL from every source
(GCS command, DO_SET_MODE, battery and link failsafes) with an exclusion circle between the vehicle and home
climbs, flies via points around it and lands at home (the target sequence checked leg by leg); with no route
home it says so, holds, and takes CA_NOROUTE_ACT (a return that cannot return lands where it holds); the
return altitude stays under the fence ceiling.
"""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from autopilot_fakes import FRAME, HOME, KinematicLoop, command

from autopilot.commander.state_machine import Commander
from autopilot.flight_tasks.rtl import RtlPhase, return_alt_m
from autopilot.geofence.fence import circle_fence_items, polygon_fence_items
from autopilot.navigation.home_frame import HomeFrame
from autopilot.navigation.navigator import Navigator
from autopilot.param_schema import make_param_store
from autopilot.safety.failsafe import FailsafeAction, FailsafeEvent, FailsafeKind
from mavlink_bridge.contract.mav_enums import MavCmd
from mavlink_bridge.contract.vehicle_api import (
    CommandResult,
    FlightMode,
    LandedState,
    MissionItem,
    MissionResult,
    MissionType,
)

ARM = (MavCmd.COMPONENT_ARM_DISARM, 1.0)
RTL_ALT_M = 15.0
FAR_NED = (90.0, 0.0, -10.0)


def _geo(n: float, e: float) -> tuple[float, float]:
    g = FRAME.geodetic_from_ned(n, e, 0.0)
    return g.lat_deg, g.lon_deg


def _circle_between() -> list[MissionItem]:
    """An exclusion circle of radius 10 m half-way between home and FAR_NED."""
    return circle_fence_items(0, *_geo(45.0, 0.0), 10.0, inclusion=False)


def _band_across() -> list[MissionItem]:
    """A 150 m inclusion circle about home cut in two by an exclusion band (north 40..50 m, wider than it)."""
    band = [_geo(40.0, -200.0), _geo(40.0, 200.0), _geo(50.0, 200.0), _geo(50.0, -200.0)]
    return [
        *circle_fence_items(0, *_geo(0.0, 0.0), 150.0, inclusion=True),
        *polygon_fence_items(1, band, inclusion=False),
    ]


class RoutedLoop:
    """The runner's wiring in small: the navigator routes the commander's return each step (home at the origin)."""

    def __init__(self) -> None:
        params = make_param_store()
        params.set("MIS_RTL_ALT", RTL_ALT_M)
        commander = Commander(params)
        commander.local_frame = FRAME
        commander.rtl.await_route = True
        self.loop = KinematicLoop(commander)
        self.commander, self.params = commander, params
        self.navigator = Navigator(params)
        self.navigator.set_home(HomeFrame(HOME))
        self.texts: list[str] = []
        self.track: list[tuple[float, float, float]] = []
        self.return_targets: list[tuple[float, float, float]] = []  # the RETURN phase's targets, each once

    def step(self) -> None:
        c, loop = self.commander, self.loop
        state = loop.state()
        nav = self.navigator.update(state, c.mode, c.landed_state is LandedState.ON_GROUND, (), c.rtl.return_goal_ned_m)
        if nav.failsafe is not None:
            c.apply_failsafe(nav.failsafe)
        loop.mission_target = nav.mission_target
        loop.step()
        self.texts += [t.text for t in self.navigator.drain_texts() + c.drain_texts()]
        self.track.append(loop.pos)
        if c.mode is FlightMode.AUTO_RTL and c.rtl.phase is RtlPhase.RETURN:
            goal = c.rtl.goto_ned
            if not self.return_targets or self.return_targets[-1] != goal:
                self.return_targets.append(goal)

    def run_until(self, predicate, timeout_s: float) -> bool:  # type: ignore[no-untyped-def]
        for _ in range(round(timeout_s / self.loop.dt_s)):
            self.step()
            if predicate():
                return True
        return False

    def fly_to(self, pos_ned_m: tuple[float, float, float]) -> None:
        self.commander.goto(self.loop.state(), pos_ned_m)
        assert self.run_until(lambda: math.dist(self.loop.pos, pos_ned_m) < 0.2, 60.0)

    def take_off_and_go_far(self) -> None:
        """Take off at home and reach FAR_NED by the east (clear of the test fences' circle)."""
        c = self.commander
        self.step()
        assert c.handle_command(command(MavCmd.NAV_TAKEOFF, *[0] * 6, 10.0, is_int=True, frame=6)).name == "ACCEPTED"
        assert c.handle_command(command(*ARM)) is CommandResult.ACCEPTED
        assert self.run_until(lambda: c.mode is FlightMode.AUTO_LOITER and c.in_air, 30.0)
        for point in ((0.0, 30.0, -10.0), (90.0, 30.0, -10.0), FAR_NED):
            self.fly_to(point)
        self.track.clear()


def _ask_for_a_return(r: RoutedLoop, source: str) -> None:
    """An RTL from each source the commander knows (the navigator's no-route action is a NO_ROUTE event)."""
    c = r.commander
    if source == "gcs_rtl":
        assert c.handle_command(command(MavCmd.NAV_RETURN_TO_LAUNCH)) is CommandResult.ACCEPTED
    elif source == "set_mode_auto_rtl":
        rtl = FlightMode.AUTO_RTL
        mode = command(MavCmd.DO_SET_MODE, 1, rtl.px4_main_mode, rtl.px4_sub_mode)
        assert c.handle_command(mode) is CommandResult.ACCEPTED
    else:
        kind = {"battery": FailsafeKind.BATTERY_CRITICAL, "link_loss": FailsafeKind.GCS_LOSS}[source]
        c.apply_failsafe(FailsafeEvent(kind, FailsafeAction.RTL, f"Failsafe: {kind.value}"))
    assert c.mode is FlightMode.AUTO_RTL


@pytest.mark.parametrize("source", ["gcs_rtl", "set_mode_auto_rtl", "battery", "link_loss"])
def test_rtl_climbs_then_flies_around_the_exclusion_circle_and_lands_at_home(source: str) -> None:
    r = RoutedLoop()
    assert r.navigator.replace_mission(MissionType.FENCE, _circle_between()) == (MissionResult.ACCEPTED, "")
    fence = r.navigator.geofence
    assert fence.violates((45.0, 0.0, -10.0)) and not fence.segment_clear(FAR_NED, (0.0, 0.0, -RTL_ALT_M))
    r.take_off_and_go_far()
    _ask_for_a_return(r, source)
    assert r.run_until(lambda: not r.commander.armed, 120.0), r.texts[-8:]
    track = np.array(r.track)
    assert not any(fence.violates(p) for p in track), "the return entered the exclusion zone"
    assert r.commander.landed_state is LandedState.ON_GROUND
    assert math.hypot(*r.loop.pos[:2]) < r.params.get("MIS_ACC_RAD")  # landed at home
    assert abs(-track[:, 2].min() - RTL_ALT_M) < 0.5  # climbed to the return altitude
    assert any(t.startswith("Route: ") and "around the fence" in t for t in r.texts), r.texts
    # the target sequence: the climb column, then via points around the circle (each leg clear of it
    # with the fence margin), then the point above home at the return altitude
    targets = r.return_targets
    assert math.dist(targets[0][:2], FAR_NED[:2]) < 0.5 and targets[-1] == (0.0, 0.0, -RTL_ALT_M), targets
    assert len(targets) >= 3, targets  # at least one via point
    margin_m = r.params.get("CA_FENCE_MARG_M") - 0.1
    for a, b in itertools.pairwise(targets):
        assert fence.segment_clear(a, b, margin_m), (a, b)
    assert all(abs(t[2] + RTL_ALT_M) < 1e-6 for t in targets)  # the whole return at the return altitude
    assert r.navigator.route_path_home_ned_m is None  # the routed leg is forgotten once over home


def test_no_route_home_says_so_holds_and_takes_the_no_route_action() -> None:
    r = RoutedLoop()
    r.params.set("CA_NOROUTE_T", 3.0)  # CA_NOROUTE_ACT 3 (return): a return with no way home lands where it holds
    r.navigator.apply_planner_params()  # as the runner's parameter bindings do
    r.take_off_and_go_far()
    # a band across the whole inclusion circle, uploaded while the vehicle is beyond it
    assert r.navigator.replace_mission(MissionType.FENCE, _band_across()) == (MissionResult.ACCEPTED, "")
    assert r.commander.handle_command(command(MavCmd.NAV_RETURN_TO_LAUNCH)) is CommandResult.ACCEPTED
    assert r.run_until(lambda: r.commander.mode is FlightMode.AUTO_LAND, 30.0), r.texts[-8:]
    no_route = [t for t in r.texts if t.startswith("No route to home: ")]
    assert len(no_route) == 1 and "holding, action 3 (CA_NOROUTE_ACT) in 3 s" in no_route[0], r.texts
    assert any(t.startswith("Failsafe: no route to home: ") for t in r.texts), r.texts
    assert r.run_until(lambda: not r.commander.armed, 60.0)
    fence = r.navigator.geofence
    assert not any(fence.violates(p) for p in r.track), "entered the band"
    held = np.array(r.track)[:, :2]
    assert float(np.max(np.hypot(held[:, 0] - FAR_NED[0], held[:, 1] - FAR_NED[1]))) < 1.0  # held, landed there
    assert all(math.dist(t[:2], FAR_NED[:2]) < 0.5 for t in r.return_targets)  # never flew toward home


def test_no_route_hold_action_keeps_holding() -> None:
    r = RoutedLoop()
    r.params.set("CA_NOROUTE_T", 2.0)
    r.params.set("CA_NOROUTE_ACT", 2.0)  # hold
    r.navigator.apply_planner_params()
    r.take_off_and_go_far()
    assert r.navigator.replace_mission(MissionType.FENCE, _band_across()) == (MissionResult.ACCEPTED, "")
    assert r.commander.handle_command(command(MavCmd.NAV_RETURN_TO_LAUNCH)) is CommandResult.ACCEPTED
    assert r.run_until(lambda: r.commander.mode is FlightMode.AUTO_LOITER, 30.0), r.texts[-8:]
    r.run_until(lambda: False, 5.0)
    assert r.commander.armed and r.commander.in_air
    assert math.dist(r.loop.pos[:2], FAR_NED[:2]) < 1.0


def test_the_return_altitude_stays_under_the_fence_ceiling() -> None:
    params = make_param_store()
    params.set("MIS_RTL_ALT", 30.0)
    assert return_alt_m(params.get) == 30.0
    params.set("GF_MAX_VER_DIST", 20.0)
    assert return_alt_m(params.get) == 18.0
    r = RoutedLoop()
    r.params.set("GF_MAX_VER_DIST", 14.0)  # under MIS_RTL_ALT (15 m): the return flies at 12 m
    r.take_off_and_go_far()
    assert r.commander.handle_command(command(MavCmd.NAV_RETURN_TO_LAUNCH)) is CommandResult.ACCEPTED
    assert r.run_until(lambda: not r.commander.armed, 120.0)
    assert abs(max(-p[2] for p in r.track) - 12.0) < 0.5
    assert math.hypot(*r.loop.pos[:2]) < r.params.get("MIS_ACC_RAD")
