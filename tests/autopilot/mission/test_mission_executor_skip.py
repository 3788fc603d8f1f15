"""Mission executor route and skipping (issue 6): ``route_ahead`` for the planner, ``skip_to`` for bypassed items."""

from __future__ import annotations

import math

import numpy as np
import pytest
from test_mission_executor import DO, HOME, PointVehicle, do, land, numbered, takeoff, wp

from autopilot.mission.executor import ActionKind, ExecutorConfig, MissionExecutor, NavKind
from mavlink_bridge.contract.mav_enums import GripperAction, MavCmd, MissionState
from mavlink_bridge.contract.vehicle_api import MissionItem


def started(items: list[MissionItem], seconds: float = 4.0) -> tuple[MissionExecutor, PointVehicle]:
    """An executor that has flown ``seconds`` (the takeoff to 5 m takes 2.5 s, then on to item 1)."""
    ex = MissionExecutor(HOME, ExecutorConfig(rtl_alt_m=15.0))
    ex.set_mission(numbered(items))
    v = PointVehicle()
    assert ex.start(v.t_us)
    v.fly(ex, seconds)
    return ex, v


def test_route_ahead_lists_positional_items_through_do_items_and_stops_at_land() -> None:
    grip = do(MavCmd.DO_GRIPPER, 1, float(GripperAction.RELEASE))
    items = [takeoff(5), wp(20, 0, 5), grip, wp(20, 10, 6), do(MavCmd.DO_CHANGE_SPEED, 1, 3.0), wp(0, 10, 5), land()]
    ex, _ = started(items)
    assert ex.current_seq == 1
    route = ex.route_ahead(1000.0, 64)
    assert route.seqs == (1, 3, 5)
    assert route.pos_ned_m == pytest.approx(np.array([[20, 0, -5], [20, 10, -6], [0, 10, -5]], float), abs=1e-6)
    assert route.next_seq == 6  # the LAND it stops at
    assert ex.route_ahead(1000.0, 64) is route  # cached while the current item is the same
    short = ex.route_ahead(5.0, 64)
    assert short.seqs == (1, 3) and short.next_seq == -1  # cut by length: 10.05 m >= 5 m after two points
    assert ex.route_ahead(1000.0, 2).seqs == (1, 3)


def test_route_ahead_follows_a_pending_jump_and_is_empty_off_a_positional_item() -> None:
    items = [takeoff(5), wp(10, 0, 5), wp(10, 10, 5), do(MavCmd.DO_JUMP, 1, 1), wp(0, 0, 5), land()]
    ex = MissionExecutor(HOME)
    ex.set_mission(numbered(items))
    assert ex.route_ahead(100.0, 64).seqs == ()  # not started
    v = PointVehicle()
    ex.start(0)
    v.fly(ex, 0.1)
    assert ex.current_seq == 0 and ex.route_ahead(100.0, 64).seqs == ()  # takeoff: no route
    v.fly(ex, 3.0)
    assert ex.route_ahead(1000.0, 64).seqs == (1, 2, 1, 2, 4)  # jump pending once, then on


def test_skip_reports_skipped_items_in_order_and_fires_the_gripper_between() -> None:
    grip = do(MavCmd.DO_GRIPPER, 1, float(GripperAction.RELEASE))
    items = [takeoff(5), wp(20, 0, 5), wp(30, 0, 5), grip, wp(40, 0, 5), wp(50, 0, 5), land()]
    ex, v = started(items)
    assert ex.current_seq == 1 and not v.actions
    assert ex.skip_to(5, v.t_us + 1)  # the detour rejoins toward item 5: items 1, 2, 3 (DO), 4 are bypassed
    assert ex.current_seq == 5
    out = ex.step(v.sample())
    assert out.bypassed == (1, 2, 4) and out.reached == (3,)  # flown around, never "reached"; the DO item ran
    v.actions += list(out.actions)
    v.fly(ex, 200.0, until_state=MissionState.COMPLETE)
    assert [s for s, _ in v.reached] == [0, 5, 6]
    assert len(v.actions) == 1
    action = v.actions[0]
    assert action.kind is ActionKind.GRIPPER_RELEASE and action.seq == 3
    assert action.time_us == 4_000_001  # stamped with the skip's time
    assert ex.state == MissionState.COMPLETE and v.landed
    assert math.hypot(v.pos[0] - 50.0, v.pos[1]) <= 1.0 + 1e-6  # flew on to item 5 (accepted 1 m early), landed


def test_skip_applies_speed_changes_and_counts_jumps() -> None:
    items = [takeoff(5), wp(30, 0, 5), do(MavCmd.DO_CHANGE_SPEED, 1, 2.0), wp(30, 10, 5)]
    items += [do(MavCmd.DO_JUMP, 1, 1), wp(0, 10, 5), land()]
    ex, v = started(items)
    assert ex.current_seq == 1
    route = ex.route_ahead(1000.0, 64)
    assert route.seqs == (1, 3, 1, 3, 5)
    assert ex.skip_to(5, v.t_us)  # through the jump once
    assert ex.speed_m_s == 2.0
    out = ex.step(v.sample())
    assert out.bypassed == (1, 3, 1, 3) and out.reached == (2, 4, 2, 4)
    assert ex.current_seq == 5 and ex.route_ahead(1000.0, 64).seqs == (5,)
    assert out.target is not None and out.target.kind is NavKind.WAYPOINT and out.target.seq == 5


@pytest.mark.parametrize(
    ("seq", "why"),
    [
        (6, "a LAND would be skipped over"),
        (1, "the current item"),
        (0, "behind the current item"),
        (7, "out of range"),
    ],
)
def test_skip_refuses_what_it_must_not_skip(seq: int, why: str) -> None:
    items = [takeoff(5), wp(20, 0, 5), wp(30, 0, 5), wp(40, 0, 5), land(), wp(0, 0, 5), land()]
    ex, v = started(items)
    assert ex.current_seq == 1
    assert not ex.skip_to(seq, v.t_us), why
    out = ex.step(v.sample())
    assert out.reached == () and out.bypassed == () and ex.current_seq == 1


def test_skip_refuses_a_takeoff_and_when_paused() -> None:
    items = [takeoff(5), wp(20, 0, 5), wp(30, 0, 5), land()]
    ex = MissionExecutor(HOME)
    ex.set_mission(numbered(items))
    assert not ex.skip_to(2, 0)  # not started
    v = PointVehicle()
    ex.start(0)
    v.fly(ex, 0.1)
    assert ex.current_seq == 0 and not ex.skip_to(2, v.t_us)  # a takeoff is never skipped
    v.fly(ex, 4.0)
    assert ex.pause(v.t_us) and not ex.skip_to(2, v.t_us)


def test_skip_past_a_position_less_loiter_is_refused() -> None:
    loiter_here = MissionItem(0, int(MavCmd.NAV_LOITER_TIME), DO, 5.0, param4=math.nan)
    items = [takeoff(5), wp(20, 0, 5), loiter_here, wp(30, 0, 5), land()]
    ex, v = started(items)
    assert ex.route_ahead(1000.0, 64).seqs == (1,) and ex.route_ahead(1000.0, 64).next_seq == 2
    assert not ex.skip_to(3, v.t_us)
    assert ex.skip_to(2, v.t_us)  # the waypoint before it may be skipped
    assert ex.step(v.sample()).bypassed == (1,)
