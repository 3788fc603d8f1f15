"""A routed return still detours around what it senses (issue 22 item 2): the in-process autopilot and sim.

A tower the autopilot does not know stands on the straight way home; the RTL's leg (routed, here direct: no
fence) is handed to the reactive Bézier planner like a mission leg, which flies around the tower; the vehicle
lands at home without touching it.
"""

from __future__ import annotations

import math

import numpy as np
from autopilot_fakes import command
from autopilot_loop import SimLoop

from mavlink_bridge.contract.mav_enums import MavCmd
from mavlink_bridge.contract.vehicle_api import CommandResult, FlightMode
from sim.world import load_world

TOWER = """
home: {lat_deg: 30.2635, lon_deg: 120.1233, alt_m: 12.0}
obstacles:
  - cylinder: {north_m: 45, east_m: 0, radius_m: 3, height_m: 40}
"""


def test_the_reactive_detour_flies_around_a_sensed_tower_on_the_way_home() -> None:
    world = load_world(TOWER)
    loop = SimLoop("x500", world=world)
    loop.ap.params.set("MIS_RTL_ALT", 10.0)
    loop.take_off(10.0, settle_s=1.0)
    commander = loop.ap.commander
    for n, e in ((0.0, 20.0), (70.0, 20.0), (70.0, 0.0)):  # out beside the tower, then behind it
        home = loop.ap.home_ned
        commander.goto(loop.ap.state, (home[0] + n, home[1] + e, home[2] - 10.0))  # type: ignore[arg-type]
        assert loop.run_until(lambda n=n, e=e: math.hypot(loop.sim.pos_ned[0] - n, loop.sim.pos_ned[1] - e) < 1.0, 40)
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
