"""Mission executor on a kinematic point vehicle: order, DO_JUMP, timers, speed, gripper, RTL/LAND, pause, replace."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import pytest

from autopilot.mission.executor import (
    ActionKind,
    ExecutorConfig,
    MissionAction,
    MissionExecutor,
    NavKind,
    NavTarget,
    VehicleSample,
)
from mavlink_bridge.contract.frames import GeoPoint, LocalNedFrame
from mavlink_bridge.contract.mav_enums import GripperAction, MavCmd, MavFrame, MissionState
from mavlink_bridge.contract.vehicle_api import MissionItem

HOME = GeoPoint(47.397742, 8.545594, 488.0)
FRAME = LocalNedFrame(HOME)
DT_US = 50_000
REL = int(MavFrame.GLOBAL_RELATIVE_ALT_INT)
DO = int(MavFrame.MISSION)


def wp(n: float, e: float, alt: float, hold_s: float = 0.0, acc_m: float = 0.0) -> MissionItem:
    g = FRAME.geodetic_from_ned(n, e, 0.0)
    return MissionItem(0, int(MavCmd.NAV_WAYPOINT), REL, hold_s, acc_m, 0.0, math.nan, g.lat_deg, g.lon_deg, alt)


def takeoff(alt: float) -> MissionItem:
    return MissionItem(0, int(MavCmd.NAV_TAKEOFF), REL, z_alt_m=alt, param4=math.nan)


def do(cmd: MavCmd, p1: float = 0.0, p2: float = 0.0) -> MissionItem:
    return MissionItem(0, int(cmd), DO, p1, p2)


def land() -> MissionItem:
    return MissionItem(0, int(MavCmd.NAV_LAND), REL, param4=math.nan)


def numbered(items: list[MissionItem]) -> list[MissionItem]:
    return [MissionItem(k, *(getattr(it, f) for f in MissionItem.__slots__[1:])) for k, it in enumerate(items)]


@dataclass
class PointVehicle:
    """Flies straight at the target's position at the target's speed (climb/descent 2 m/s); lands at down = 0."""

    pos: list[float] = field(default_factory=lambda: [0.0, 0.0, 0.0])
    landed: bool = True
    t_us: int = 0
    reached: list[tuple[int, int]] = field(default_factory=list)  # (seq, time_us)
    actions: list[MissionAction] = field(default_factory=list)
    targets: list[NavTarget] = field(default_factory=list)
    speeds: list[tuple[int, float]] = field(default_factory=list)

    def sample(self) -> VehicleSample:
        return VehicleSample(self.t_us, (self.pos[0], self.pos[1], self.pos[2]), (0.0, 0.0, 0.0), self.landed)

    def fly(self, ex: MissionExecutor, seconds: float, until_state: MissionState | None = None) -> None:
        for _ in range(int(seconds * 1e6 / DT_US)):
            out = ex.step(self.sample())
            self.reached += [(s, self.t_us) for s in out.reached]
            self.actions += list(out.actions)
            self.speeds.append((self.t_us, out.speed_m_s))
            if until_state is not None and out.state == until_state:
                return
            tgt = out.target
            if tgt is not None:
                if not self.targets or self.targets[-1] != tgt:
                    self.targets.append(tgt)
                self._move(tgt)
            self.t_us += DT_US

    def _move(self, tgt: NavTarget) -> None:
        if tgt.kind == NavKind.IDLE:
            return
        dt = DT_US / 1e6
        goal = tgt.pos_ned_m
        dn, de = goal[0] - self.pos[0], goal[1] - self.pos[1]
        dh = math.hypot(dn, de)
        step_h = min(dh, tgt.speed_m_s * dt)
        if dh > 0:
            self.pos[0] += dn / dh * step_h
            self.pos[1] += de / dh * step_h
        dd = goal[2] - self.pos[2]
        self.pos[2] += max(-2.0 * dt, min(2.0 * dt, dd))
        self.pos[2] = min(self.pos[2], 0.0)
        self.landed = self.pos[2] >= 0.0 and tgt.kind == NavKind.LAND


def run(items: list[MissionItem], seconds: float = 200.0, config: ExecutorConfig | None = None):
    ex = MissionExecutor(HOME, config or ExecutorConfig(rtl_alt_m=15.0))
    ex.set_mission(numbered(items))
    assert ex.state == MissionState.NOT_STARTED
    v = PointVehicle()
    assert ex.start(v.t_us)
    v.fly(ex, seconds, until_state=MissionState.COMPLETE)
    return ex, v


def test_each_item_reached_in_order_and_lands() -> None:
    items = [takeoff(10), wp(30, 0, 10), wp(30, 20, 12), wp(0, 20, 10), land()]
    ex, v = run(items)
    assert ex.state == MissionState.COMPLETE
    assert [s for s, _ in v.reached] == [0, 1, 2, 3, 4]
    assert v.landed and v.pos[2] == 0.0
    assert math.hypot(v.pos[0] - 0.0, v.pos[1] - 20.0) < 1.0
    assert ex.current_seq == 4


def test_pass_through_lookahead_and_acceptance_radius() -> None:
    items = [takeoff(10), wp(30, 0, 10, acc_m=3.0), do(MavCmd.DO_CHANGE_SPEED, 1, 4.0), wp(30, 20, 10), land()]
    _, v = run(items)
    first = next(t for t in v.targets if t.kind == NavKind.WAYPOINT and t.seq == 1)
    assert first.pass_through and first.accept_radius_m == 3.0
    assert first.next_pos_ned_m is not None
    assert first.next_pos_ned_m == pytest.approx((30.0, 20.0, -10.0), abs=1e-6)
    last = next(t for t in v.targets if t.kind == NavKind.WAYPOINT and t.seq == 3)
    assert not last.pass_through and last.next_pos_ned_m is None  # followed by LAND: stop there
    assert last.accept_radius_m == ExecutorConfig().accept_radius_m
    reached_1 = dict(v.reached)[1]
    assert reached_1 < dict(v.reached)[3]


def test_do_jump_repeats_the_loop() -> None:
    items = [takeoff(5), wp(10, 0, 5), wp(10, 10, 5), do(MavCmd.DO_JUMP, 1, 2), wp(0, 0, 5), land()]
    _, v = run(items, seconds=400)
    assert [s for s, _ in v.reached] == [0, 1, 2, 3, 1, 2, 3, 1, 2, 3, 4, 5]


def test_lookahead_follows_a_pending_jump() -> None:
    items = [takeoff(5), wp(10, 0, 5), wp(10, 10, 5), do(MavCmd.DO_JUMP, 1, 1), wp(0, 0, 5), land()]
    _, v = run(items, seconds=400)
    wp2 = [t for t in v.targets if t.kind == NavKind.WAYPOINT and t.seq == 2]
    assert wp2[0].next_pos_ned_m == pytest.approx((10.0, 0.0, -5.0), abs=1e-6)  # jump pending: back to item 1
    assert wp2[-1].next_pos_ned_m == pytest.approx((0.0, 0.0, -5.0), abs=1e-6)  # jump used up: on to item 4


def test_loiter_time_and_delay_hold_for_their_duration() -> None:
    loiter = MissionItem(0, int(MavCmd.NAV_LOITER_TIME), REL, 4.0, param4=math.nan)  # here, 4 s
    delay = MissionItem(0, int(MavCmd.NAV_DELAY), DO, 3.0, -1.0, -1.0, -1.0)
    items = [takeoff(5), loiter, delay, wp(0, 5, 5, hold_s=2.0), land()]
    _, v = run(items)
    t = dict(v.reached)
    assert t[1] - t[0] == pytest.approx(4e6, abs=DT_US)
    assert t[2] - t[1] == pytest.approx(3e6, abs=DT_US)
    hold_targets = [x for x in v.targets if x.kind == NavKind.LOITER and x.seq in (1, 2)]
    assert hold_targets and all(x.pos_ned_m[2] == pytest.approx(-5.0, abs=0.9) for x in hold_targets)
    flight_s = (5.0 - 1.0) / 5.0  # 5 m east at 5 m/s, accepted 1 m early
    assert t[3] - t[2] == pytest.approx((2.0 + flight_s) * 1e6, abs=2 * DT_US)


def test_speed_change_applies_from_its_item() -> None:
    items = [takeoff(5), wp(20, 0, 5), do(MavCmd.DO_CHANGE_SPEED, 1, 2.5), wp(40, 0, 5), land()]
    _, v = run(items)
    t = dict(v.reached)
    before = [s for tt, s in v.speeds if tt < t[2]]
    after = [s for tt, s in v.speeds if tt >= t[2]]
    assert set(before) == {5.0} and set(after) == {2.5}
    assert t[3] - t[2] == pytest.approx(20.0 / 2.5 * 1e6, rel=0.05)
    wp3 = next(x for x in v.targets if x.seq == 3)
    assert wp3.speed_m_s == 2.5


def test_gripper_release_at_its_item() -> None:
    items = [takeoff(5), wp(20, 0, 5), do(MavCmd.DO_GRIPPER, 1, float(GripperAction.RELEASE)), wp(0, 0, 5), land()]
    _, v = run(items)
    assert len(v.actions) == 1
    action = v.actions[0]
    assert action.kind == ActionKind.GRIPPER_RELEASE and action.seq == 2
    assert action.time_us == dict(v.reached)[1]  # released the moment the drop point is reached


def test_return_to_launch_climbs_returns_and_lands() -> None:
    items = [takeoff(5), wp(40, 30, 5), do(MavCmd.NAV_RETURN_TO_LAUNCH)]
    ex, v = run(items, seconds=300)
    assert ex.state == MissionState.COMPLETE
    kinds = [t.kind for t in v.targets if t.seq == 2]
    assert kinds == [NavKind.RETURN, NavKind.RETURN, NavKind.LAND]
    assert kinds and v.targets[[t.seq for t in v.targets].index(2)].pos_ned_m[2] == pytest.approx(-15.0)
    assert v.landed and math.hypot(v.pos[0], v.pos[1]) < 1.0


def test_pause_holds_and_freezes_timers_then_resume_continues() -> None:
    items = [takeoff(5), wp(50, 0, 5), land()]
    ex = MissionExecutor(HOME)
    ex.set_mission(numbered(items))
    v = PointVehicle()
    ex.start(0)
    v.fly(ex, 8.0)  # climbing 2.5 s, then 5.5 s toward the waypoint at 5 m/s
    assert ex.current_seq == 1
    assert ex.pause(v.t_us) and ex.state == MissionState.PAUSED
    v.fly(ex, 0.05)
    held = tuple(v.pos)
    v.fly(ex, 10.0)
    assert tuple(v.pos) == pytest.approx(held)
    assert v.targets[-1].kind == NavKind.LOITER and v.targets[-1].seq == -1
    assert ex.current_seq == 1
    assert ex.resume(v.t_us)
    v.fly(ex, 60.0, until_state=MissionState.COMPLETE)
    assert [s for s, _ in v.reached] == [0, 1, 2]


def test_pause_freezes_a_loiter_timer() -> None:
    loiter = MissionItem(0, int(MavCmd.NAV_LOITER_TIME), REL, 6.0, param4=math.nan)
    ex = MissionExecutor(HOME)
    ex.set_mission(numbered([takeoff(5), loiter, land()]))
    v = PointVehicle()
    ex.start(0)
    v.fly(ex, 6.0)  # takeoff done at ~2.5 s, ~3.5 s of loiter
    ex.pause(v.t_us)
    v.fly(ex, 20.0)
    ex.resume(v.t_us)
    v.fly(ex, 60.0, until_state=MissionState.COMPLETE)
    t = dict(v.reached)
    assert t[1] - t[0] == pytest.approx(26e6, abs=2 * DT_US)


def test_mission_replaced_in_flight_continues_the_same_item() -> None:
    a = [takeoff(5), wp(40, 0, 5), wp(40, 40, 5), land()]
    ex = MissionExecutor(HOME)
    ex.set_mission(numbered(a))
    v = PointVehicle()
    ex.start(0)
    v.fly(ex, 6.0)
    assert ex.current_seq == 1
    b = [takeoff(5), wp(40, 0, 5), wp(0, 40, 5), land()]  # same item 1, new item 2
    assert ex.set_mission(numbered(b)) == 1
    assert ex.state == MissionState.ACTIVE
    v.fly(ex, 120.0, until_state=MissionState.COMPLETE)
    assert math.hypot(v.pos[0], v.pos[1] - 40.0) < 1.0  # landed at the new item 2
    assert [s for s, _ in v.reached] == [0, 1, 2, 3]


def test_mission_replaced_in_flight_restarts_when_nothing_matches() -> None:
    ex = MissionExecutor(HOME)
    ex.set_mission(numbered([takeoff(5), wp(40, 0, 5), land()]))
    v = PointVehicle()
    ex.start(0)
    v.fly(ex, 6.0)
    new = [takeoff(5), wp(-20, 0, 8), do(MavCmd.NAV_RETURN_TO_LAUNCH)]
    assert ex.set_mission(numbered(new)) == 0
    v.fly(ex, 120.0, until_state=MissionState.COMPLETE)
    assert [s for s, _ in v.reached][:2] == [0, 0]  # old takeoff, then the new one completes at once
    assert v.landed and math.hypot(v.pos[0], v.pos[1]) < 1.0


def test_set_current_and_start_bounds() -> None:
    ex = MissionExecutor(HOME)
    assert not ex.start(0)
    assert ex.state == MissionState.NO_MISSION
    ex.set_mission(numbered([takeoff(5), wp(10, 0, 5), land()]))
    assert not ex.set_current(3)
    assert ex.set_current(1) and ex.current_seq == 1
    v = PointVehicle(pos=[0.0, 0.0, -5.0], landed=False)
    ex.start(0, seq=None)
    v.fly(ex, 60.0, until_state=MissionState.COMPLETE)
    assert [s for s, _ in v.reached] == [1, 2]


def test_complete_holds_in_air_and_idles_on_ground() -> None:
    ex, v = run([takeoff(5), wp(5, 0, 5)])
    assert ex.state == MissionState.COMPLETE
    out = ex.step(v.sample())
    assert out.target is not None and out.target.kind == NavKind.LOITER
    assert out.target.pos_ned_m == pytest.approx(tuple(v.pos))
    ex, v = run([takeoff(5), land()])
    out = ex.step(v.sample())
    assert out.state == MissionState.COMPLETE and v.landed
    assert out.target is not None and out.target.kind == NavKind.IDLE
