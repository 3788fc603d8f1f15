"""Fence-aware routing in the autopilot (issue 13), in-process closed loop (sim vehicle + sensors + Autopilot).

An item outside the inclusion fence is refused at upload naming it, with the same reason before and after the first
fix; what needs home (GF_MAX_HOR_DIST) is checked once home is known, and a mission failing then is not flown; a
leg crossing a no-fly corridor with buildings past it is flown around the zones with the real avoidance
planner: no breach, no collision, every item reached or honestly bypassed.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
from autopilot_fakes import command
from autopilot_loop import SimLoop
from conftest import REPO_ROOT

from autopilot.geofence.fence import circle_fence_items, geofence_from_items
from autopilot.mission.files import load_mission_file
from autopilot.telemetry import RerunTelemetry
from autopilot.telemetry import entities as ent
from autopilot.telemetry.recording_reader import read_recording
from autopilot.telemetry.sinks import RerunSink, SinkKind, open_recording
from mavlink_bridge.contract.frames import LocalNedFrame
from mavlink_bridge.contract.mav_enums import MavCmd, MavFrame
from mavlink_bridge.contract.vehicle_api import CommandResult, MissionItem, MissionResult, MissionType
from sim.world import load_world

CORRIDOR = REPO_ROOT / "missions" / "no_fly_corridor.yaml"
REL = int(MavFrame.GLOBAL_RELATIVE_ALT_INT)


def _far_mission(loop: SimLoop) -> list[MissionItem]:
    """Takeoff, a waypoint 100 m north, one 900 m north, land (about the world's home)."""
    frame = LocalNedFrame(loop.sim.world.home)
    items = [MissionItem(0, int(MavCmd.NAV_TAKEOFF), REL, param4=math.nan, z_alt_m=10.0)]
    for n in (100.0, 900.0):
        g = frame.geodetic_from_ned(n, 0.0, 0.0)
        items.append(MissionItem(len(items), int(MavCmd.NAV_WAYPOINT), REL, 0.0, 1.0, 0.0, math.nan, g.lat_deg,
                                 g.lon_deg, 20.0))  # fmt: skip
    items.append(MissionItem(len(items), int(MavCmd.NAV_LAND), REL, param4=math.nan))
    return items


def _inclusion_500m(loop: SimLoop) -> list[MissionItem]:
    home = loop.sim.world.home
    return circle_fence_items(0, home.lat_deg, home.lon_deg, 500.0, inclusion=True)


def test_waypoint_outside_a_500m_inclusion_fence_is_refused_naming_it() -> None:
    loop = SimLoop("x500")
    loop.run_s(0.5)  # home known
    assert loop.vehicle.replace_mission(MissionType.FENCE, _inclusion_500m(loop)) == (MissionResult.ACCEPTED, "")
    result, reason = loop.vehicle.replace_mission(MissionType.MISSION, _far_mission(loop))
    assert result is MissionResult.INVALID_PARAM5_X
    assert reason.startswith("item 2: 400 m outside the inclusion fence (inclusion circle 1 (r 500 m at 30.2635")
    loop.run_s(0.01)
    assert f"Mission refused: {reason}" in loop.texts  # the STATUSTEXT a GCS shows (MISSION_ACK has no text)
    assert not loop.ap.navigator.mission_ready


def test_waypoint_outside_the_fence_is_refused_before_and_after_the_first_fix_with_the_same_reason() -> None:
    """Fence and waypoint are both geodetic: the check needs no home, so the fix's timing cannot change the answer."""
    loop = SimLoop("x500")
    assert loop.ap.home_geo is None  # no frame yet: no fix, no home
    assert loop.vehicle.replace_mission(MissionType.FENCE, _inclusion_500m(loop)) == (MissionResult.ACCEPTED, "")
    before = loop.vehicle.replace_mission(MissionType.MISSION, _far_mission(loop))
    loop.run_s(0.5)
    assert loop.ap.home_geo is not None
    after = loop.vehicle.replace_mission(MissionType.MISSION, _far_mission(loop))
    assert before == after
    assert before[0] is MissionResult.INVALID_PARAM5_X and before[1].startswith("item 2: 400 m outside the inclusion")
    loop.run_s(0.01)
    assert loop.texts.count(f"Mission refused: {before[1]}") == 2
    assert not loop.ap.navigator.mission and not loop.ap.navigator.mission_ready


def test_what_needs_home_is_checked_once_home_is_known_and_a_failing_mission_never_starts() -> None:
    loop = SimLoop("x500")
    assert loop.ap.home_geo is None
    assert loop.vehicle.param_set("GF_MAX_HOR_DIST", 500.0)[0]
    assert loop.vehicle.replace_mission(MissionType.MISSION, _far_mission(loop)) == (MissionResult.ACCEPTED, "")
    loop.run_s(0.5)
    issue = "item 2: 900 m from home, beyond the 500 m limit (GF_MAX_HOR_DIST)"
    assert any(t.startswith(f"Mission not flyable from home: {issue}") for t in loop.texts), loop.texts
    assert not loop.ap.navigator.mission_ready  # reported and not flown
    assert loop.vehicle.handle_command(command(400, 1.0)) is CommandResult.ACCEPTED
    assert loop.vehicle.handle_command(command(300, 0.0)) is not CommandResult.ACCEPTED
    good = [*_far_mission(loop)[:2], MissionItem(2, int(MavCmd.NAV_LAND), REL, param4=math.nan)]
    assert loop.vehicle.replace_mission(MissionType.MISSION, good) == (MissionResult.ACCEPTED, "")
    assert loop.ap.navigator.mission_ready


def test_leg_across_a_no_fly_corridor_with_buildings_past_it_flies_clean() -> None:
    plan = load_mission_file(CORRIDOR)
    world = load_world(CORRIDOR)
    loop = SimLoop(plan.vehicle, world=world, payload_kg=1.0)
    assert loop.vehicle.replace_mission(MissionType.FENCE, plan.fence) == (MissionResult.ACCEPTED, "")
    assert loop.vehicle.replace_mission(MissionType.MISSION, plan.items) == (MissionResult.ACCEPTED, "")
    loop.run_s(0.5)
    assert loop.ap.navigator.mission_ready, loop.texts
    fence = geofence_from_items(plan.fence, world.home)
    assert loop.vehicle.handle_command(command(400, 1.0)) is CommandResult.ACCEPTED
    assert loop.vehicle.handle_command(command(300, 0.0)) is CommandResult.ACCEPTED
    track: list[list[float]] = []
    done = loop.run_until(lambda: track.append(list(loop.sim.pos_ned)) is None and not loop.ap.commander.armed, 240)
    assert done, loop.texts[-10:]
    pts = np.array(track)
    assert not any(fence.violates(p) for p in pts[::25]), "entered a no-fly zone"
    assert float(np.min(world.clearance_m(pts))) > 0.0
    assert not [t for t in loop.texts if t.startswith("Failsafe")], loop.texts
    assert any(t.startswith("Route: ") for t in loop.texts), loop.texts  # planned around the zones
    nav = loop.ap.navigator
    assert sorted(set(loop.ap.progress.reached_seqs) | set(nav.bypassed_seqs)) == list(range(len(plan.items)))
    assert loop.sim.payload_kg == 0.0  # the parcel was delivered


def test_the_recording_shows_the_leg_routed_around_the_zones(tmp_path: Path) -> None:
    plan = load_mission_file(CORRIDOR)
    world = load_world(CORRIDOR)
    path = tmp_path / "route.rrd"
    telemetry = RerunTelemetry(open_recording(RerunSink(SinkKind.SAVE, str(path))))
    loop = SimLoop(plan.vehicle, world=world, payload_kg=1.0, listener=telemetry)
    loop.run_s(0.5)
    assert loop.vehicle.replace_mission(MissionType.FENCE, plan.fence) == (MissionResult.ACCEPTED, "")
    assert loop.vehicle.replace_mission(MissionType.MISSION, plan.items) == (MissionResult.ACCEPTED, "")
    assert loop.vehicle.handle_command(command(400, 1.0)) is CommandResult.ACCEPTED
    assert loop.vehicle.handle_command(command(300, 0.0)) is CommandResult.ACCEPTED
    assert loop.run_until(lambda: loop.ap.navigator.route_path_home_ned_m is not None, 30.0), loop.texts
    loop.run_s(1.0)
    telemetry.close()
    strip = np.asarray(read_recording(path).latest_component(ent.PLANNED_ROUTE, "LineStrips3D:strips")[0])
    fence = geofence_from_items(plan.fence, world.home)
    assert len(strip) > 2  # via points: the leg goes around the corridor
    assert all(fence.segment_clear(strip[i], strip[i + 1], 2.9) for i in range(len(strip) - 1))
