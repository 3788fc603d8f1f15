"""Routed returns in the in-process autopilot and sim (issue 22 item 2).

A tower the autopilot does not know stands on the straight way home: the RTL's leg (routed, here direct: no
fence) is handed to the reactive Bézier planner like a mission leg, which flies around the tower; the vehicle
lands at home without touching it. With an exclusion circle on the way home, the recording shows the routed
return like a mission's routed leg (the planned-route strip around the zone).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
from autopilot_fakes import command
from autopilot_loop import SimLoop

from autopilot.geofence.fence import circle_fence_items, geofence_from_items
from autopilot.telemetry import RerunTelemetry
from autopilot.telemetry import entities as ent
from autopilot.telemetry.recording_reader import read_recording
from autopilot.telemetry.sinks import RerunSink, SinkKind, open_recording
from mavlink_bridge.contract.frames import LocalNedFrame
from mavlink_bridge.contract.mav_enums import MavCmd
from mavlink_bridge.contract.vehicle_api import CommandResult, FlightMode, MissionResult, MissionType
from sim.world import empty_world, load_world

TOWER = """
home: {lat_deg: 30.2635, lon_deg: 120.1233, alt_m: 12.0}
obstacles:
  - cylinder: {north_m: 45, east_m: 0, radius_m: 3, height_m: 40}
"""


def _fly_behind(loop: SimLoop, rtl_alt_m: float = 10.0) -> None:
    """Take off, fly out 20 m east of the straight line, then to 70 m north of home (behind what is on the way)."""
    loop.ap.params.set("MIS_RTL_ALT", rtl_alt_m)
    loop.take_off(10.0, settle_s=1.0)
    for n, e in ((0.0, 20.0), (70.0, 20.0), (70.0, 0.0)):
        home = loop.ap.home_ned
        loop.ap.commander.goto(loop.ap.state, (home[0] + n, home[1] + e, home[2] - 10.0))  # type: ignore[arg-type]
        assert loop.run_until(lambda n=n, e=e: math.hypot(loop.sim.pos_ned[0] - n, loop.sim.pos_ned[1] - e) < 1.0, 40)


def test_the_reactive_detour_flies_around_a_sensed_tower_on_the_way_home() -> None:
    world = load_world(TOWER)
    loop = SimLoop("x500", world=world)
    _fly_behind(loop)
    commander = loop.ap.commander
    loop.texts.clear()
    assert loop.vehicle.handle_command(command(MavCmd.NAV_RETURN_TO_LAUNCH)) is CommandResult.ACCEPTED
    track: list[list[float]] = []
    detoured = []

    def landed() -> bool:
        track.append(list(loop.sim.pos_ned))
        out = loop.ap.navigator.planner_output
        if commander.mode is FlightMode.AUTO_RTL and getattr(out, "setpoint", None) is not None:
            detoured.append(loop.sim.pos_ned[0])
        return not commander.armed

    assert loop.run_until(landed, 90.0), loop.texts[-10:]
    pts = np.array(track)
    assert float(np.min(world.clearance_m(pts))) > 1.0, "too close to the tower"
    assert detoured, loop.texts  # the planner's setpoint flew part of the return
    assert math.hypot(pts[-1][0], pts[-1][1]) < 1.5  # landed at home
    assert float(np.max(np.abs(pts[:, 1]))) > 3.0  # went round the tower, not through it


def test_the_recording_shows_the_return_routed_around_the_zone(tmp_path: Path) -> None:
    world = empty_world()
    path = tmp_path / "rtl.rrd"
    telemetry = RerunTelemetry(open_recording(RerunSink(SinkKind.SAVE, str(path))))
    loop = SimLoop("x500", world=world, listener=telemetry)
    g = LocalNedFrame(world.home).geodetic_from_ned(35.0, 0.0, 0.0)
    items = circle_fence_items(0, g.lat_deg, g.lon_deg, 8.0, inclusion=False)
    assert loop.vehicle.replace_mission(MissionType.FENCE, items) == (MissionResult.ACCEPTED, "")
    _fly_behind(loop)
    assert loop.vehicle.handle_command(command(MavCmd.NAV_RETURN_TO_LAUNCH)) is CommandResult.ACCEPTED
    assert loop.run_until(lambda: loop.ap.navigator.route_path_home_ned_m is not None, 20.0), loop.texts
    loop.run_s(1.0)
    telemetry.close()
    strip = np.asarray(read_recording(path).latest_component(ent.PLANNED_ROUTE, "LineStrips3D:strips")[0])
    fence = geofence_from_items(items, world.home)
    assert len(strip) > 2 and math.hypot(strip[-1][0], strip[-1][1]) < 0.1  # via points, ending over home
    assert all(fence.segment_clear(strip[i], strip[i + 1], 2.9) for i in range(len(strip) - 1))
