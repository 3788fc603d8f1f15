"""Runner glue between the mission executor and the avoidance planner (issue 6), in-process closed loop.

A scripted planner stands in for ``AvoidancePlanner`` (same ``update`` signature and output fields) so the
runner's part is tested alone: the route it hands over, the bypassed waypoints it skips on
``rejoin_route_index``, the waypoints inside an obstacle's safety volume it never targets, and the nose
facing along the path (MPC_YAW_MODE 0).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from autopilot_fakes import command
from autopilot_loop import SimLoop

from autopilot.planner.obstacle_map import ObstacleKind, TrackedObstacle
from mavlink_bridge.contract.frames import LocalNedFrame
from mavlink_bridge.contract.mav_enums import GripperAction, MavCmd, MavFrame
from mavlink_bridge.contract.vehicle_api import CommandResult, MissionItem, MissionResult, MissionType

REL = int(MavFrame.GLOBAL_RELATIVE_ALT_INT)
ALT_M = 5.0


@dataclass(frozen=True)
class _Output:
    """The ``PlannerOutput`` fields the runner reads."""

    setpoint: None = None
    decisions: tuple[object, ...] = ()
    obstacles: tuple[TrackedObstacle, ...] = ()
    look_ahead_ned: None = None
    rejoin_route_index: int = 0


@dataclass
class ScriptedPlanner:
    """Never overrides the reference; reports ``rejoin`` once when the target is ``rejoin_at``, and ``obstacles``."""

    rejoin_at: tuple[float, float] | None = None
    rejoin: int = 0
    obstacles: tuple[TrackedObstacle, ...] = ()
    routes: list[tuple[tuple[float, ...], np.ndarray | None]] = field(default_factory=list)

    def update(  # type: ignore[no-untyped-def]
        self, time_us, pos_ned, vel_ned, q_ned_frd, detections, route_target_ned, route_next_ned=None, route_items=None
    ) -> _Output:
        nxt = None if route_next_ned is None else np.array(route_next_ned, float).reshape(-1, 3)
        self.routes.append((tuple(route_target_ned), nxt))
        k = 0
        if self.rejoin_at is not None and math.dist(route_target_ned[:2], self.rejoin_at) < 1e-3:
            k, self.rejoin_at = self.rejoin, None
        return _Output(obstacles=self.obstacles, rejoin_route_index=k)


def _mission(loop: SimLoop, items: Sequence[MissionItem]) -> None:
    numbered = [MissionItem(k, *(getattr(it, f) for f in MissionItem.__slots__[1:])) for k, it in enumerate(items)]
    assert loop.vehicle.replace_mission(MissionType.MISSION, numbered) == (MissionResult.ACCEPTED, "")


def _wp(frame: LocalNedFrame, n: float, e: float) -> MissionItem:
    g = frame.geodetic_from_ned(n, e, 0.0)
    return MissionItem(0, int(MavCmd.NAV_WAYPOINT), REL, 0.0, 1.0, 0.0, math.nan, g.lat_deg, g.lon_deg, ALT_M)


def _fly(planner: ScriptedPlanner, points: Sequence[tuple[float, float]], gripper_after: int = -1):  # type: ignore[no-untyped-def]
    """Take off to 5 m, fly ``points`` (DO_GRIPPER release after point ``gripper_after``), land; the loop."""
    loop = SimLoop("x500", planner=planner)
    loop.run_s(0.5)
    frame = LocalNedFrame(loop.ap.home_geo)
    items = [MissionItem(0, int(MavCmd.NAV_TAKEOFF), REL, z_alt_m=ALT_M, param4=math.nan)]
    for i, (n, e) in enumerate(points):
        items.append(_wp(frame, n, e))
        if i == gripper_after:
            items.append(
                MissionItem(0, int(MavCmd.DO_GRIPPER), int(MavFrame.MISSION), 1.0, float(GripperAction.RELEASE))
            )
    items.append(MissionItem(0, int(MavCmd.NAV_LAND), REL, param4=math.nan))
    _mission(loop, items)
    assert loop.vehicle.handle_command(command(400, 1.0)) is CommandResult.ACCEPTED
    assert loop.vehicle.handle_command(command(300, 0.0)) is CommandResult.ACCEPTED
    track: list[tuple[float, float, float]] = []
    done = loop.run_until(lambda: track.append(_pose(loop)) is None and not loop.ap.commander.armed, 90.0)
    assert done, loop.texts
    return loop, items, np.array(track)


def _pose(loop: SimLoop) -> tuple[float, float, float]:
    q = loop.sim.q_ned_frd
    yaw = math.atan2(2.0 * (q[0] * q[3] + q[1] * q[2]), 1.0 - 2.0 * (q[2] * q[2] + q[3] * q[3]))
    return float(loop.sim.pos_ned[0]), float(loop.sim.pos_ned[1]), yaw


def test_rejoin_index_skips_bypassed_waypoints_reports_them_and_still_fires_the_gripper() -> None:
    points = [(0.0, 8.0), (0.0, 12.0), (0.0, 16.0), (0.0, 24.0)]
    planner = ScriptedPlanner(rejoin_at=(0.0, 8.0), rejoin=3)  # from item 1: items 1..4 (DO_GRIPPER 3) bypassed
    loop, _, track = _fly(planner, points, gripper_after=1)
    # flown around, never reached: bypassed items are reported as such (the DO_GRIPPER between them ran)
    assert loop.ap.progress.reached_seqs == [0, 3, 5, 6] and loop.ap.navigator.bypassed_seqs == [1, 2, 4]
    assert any(t.startswith("Bypassed item 1: a detour rejoined the route past it") for t in loop.texts), loop.texts
    assert loop.ap.summary(0.0)["items_bypassed"] == 3
    assert loop.ap.commander.gripper_release  # the DO_GRIPPER between skipped waypoints fired
    first_next = next(r[1] for r in planner.routes if math.dist(r[0][:2], (0.0, 8.0)) < 1e-3)
    assert first_next is not None  # the route after the target: every later waypoint, at the mission altitude
    np.testing.assert_allclose(first_next, [(n, e, -ALT_M) for n, e in points[1:]], atol=1e-6)
    # the skip happened at once: the vehicle never flew the bypassed legs (it landed at the last waypoint)
    assert math.hypot(track[-1, 0], track[-1, 1] - 24.0) < 1.5
    leg = track[np.abs(track[:, 1] - 12.0) < 4.0]
    assert len(leg) and np.all(np.abs(np.degrees(leg[:, 2]) - 90.0) < 15.0)  # nose east, along the route


def test_waypoint_inside_an_obstacle_safety_volume_is_never_targeted() -> None:
    points = [(0.0, 8.0), (8.0, 14.0), (0.0, 20.0)]
    column = TrackedObstacle(7, ObstacleKind.COLUMN, (8.0, 14.5, 0.0), 1.0, 0, 0, 5)  # covers item 2
    planner = ScriptedPlanner(obstacles=(column,))
    loop, _, track = _fly(planner, points)
    assert loop.ap.progress.reached_seqs == [0, 1, 3, 4] and loop.ap.navigator.bypassed_seqs == [2]
    assert any("Skipped to item 3" in t for t in loop.texts), loop.texts
    reason = "Bypassed item 2: it lies inside obstacle 7's safety volume (0.5 m inside it, CA_RSAFE_M"
    assert any(t.startswith(reason) for t in loop.texts), loop.texts
    assert loop.ap.summary(0.0)["bypass_reasons"]["2"].startswith(reason.removeprefix("Bypassed item 2: "))
    assert all(math.dist(r[0][:2], (8.0, 14.0)) > 1e-3 for r in planner.routes)  # never handed as target
    assert float(np.min(np.hypot(track[:, 0] - 8.0, track[:, 1] - 14.0))) > 4.0
