"""Autopilot runner in a closed loop with the simulator's vehicle model in-process (no sockets).

Proves the wiring estimator → commander/mission → setpoints → cascade → actuators flies: GCS-style
commands through the VehicleInterface adapter, a mission with a payload release, parameter
changes, mission refusals, and the summary's numbers.
"""

from __future__ import annotations

import math

import pytest
from autopilot_fakes import command

from autopilot.runner import Autopilot, AutopilotConfig
from autopilot.vehicle_adapter import VehicleAdapter
from mavlink_bridge.contract.frames import LocalNedFrame
from mavlink_bridge.contract.vehicle_api import (
    CommandResult,
    FlightMode,
    LandedState,
    MissionItem,
    MissionResult,
    MissionType,
)
from mavlink_bridge.lockstep import LockstepFrame
from sim.sensors import SensorModel
from sim.vehicle import VehicleSim
from sim.vehicle_config import load_vehicle
from sim.world import empty_world


class Loop:
    """Sim vehicle + sensors + autopilot, stepped together at 250 Hz."""

    def __init__(self, seed: int = 3) -> None:
        vehicle = load_vehicle("x500")
        self.world = empty_world()
        self.sim = VehicleSim(vehicle, world=self.world, seed=seed)
        self.sensors = SensorModel(vehicle, self.world.home, seed)
        self.ap = Autopilot(AutopilotConfig(vehicle="x500"))
        self.vehicle = VehicleAdapter(self.ap)
        self.texts: list[str] = []
        self.released_at_s: float | None = None

    def step(self) -> None:
        sim = self.sim
        frame = LockstepFrame(self.sensors.imu_baro_mag(sim), self.sensors.gps(sim), sim.ground_truth())
        cmd = self.ap.step(frame)
        assert cmd.time_us == frame.time_us
        assert all(0.0 <= u <= 1.0 for u in cmd.motor_cmd)
        if cmd.gripper_release and self.released_at_s is None:
            sim.release_payload()
            self.released_at_s = sim.t_s
        sim.step(cmd.motor_cmd)
        self.texts += [t.text for t in self.ap.drain_texts()]

    def run_until(self, predicate, timeout_s: float) -> bool:  # type: ignore[no-untyped-def]
        for _ in range(round(timeout_s * 250)):
            self.step()
            if predicate():
                return True
        return False

    @property
    def frame(self) -> LocalNedFrame:
        frame = self.ap.estimator.local_frame
        assert frame is not None
        return frame


def test_arm_takeoff_hold_reposition_land_disarm() -> None:
    loop = Loop()
    ap, vehicle = loop.ap, loop.vehicle
    loop.run_until(lambda: False, 0.5)
    assert vehicle.handle_command(command(400, 1.0)) is CommandResult.ACCEPTED
    takeoff = command(22, *[0] * 6, 10.0, is_int=True, frame=6)
    assert vehicle.handle_command(takeoff) is CommandResult.ACCEPTED
    assert loop.run_until(lambda: ap.commander.mode is FlightMode.AUTO_LOITER, 20.0)
    loop.run_until(lambda: False, 4.0)  # hold
    assert loop.sim.pos_ned == pytest.approx([0.0, 0.0, -10.0], abs=0.1)
    goal = loop.frame.geodetic_from_ned(15.0, -10.0, 0.0)
    reposition = command(192, -1, 1, 0, math.nan, goal.lat_deg, goal.lon_deg, 12.0, is_int=True, frame=6)
    assert vehicle.handle_command(reposition) is CommandResult.ACCEPTED
    assert loop.run_until(lambda: math.dist(loop.sim.pos_ned, (15.0, -10.0, -12.0)) < 0.2, 20.0)
    assert vehicle.handle_command(command(21)) is CommandResult.ACCEPTED
    assert loop.run_until(lambda: not ap.commander.armed, 40.0)
    assert ap.commander.landed_state is LandedState.ON_GROUND
    assert loop.sim.pos_ned[:2] == pytest.approx([15.0, -10.0], abs=0.3)
    assert loop.sim.end_reason.name not in ("COLLISION", "GROUND_IMPACT", "NON_FINITE")
    summary = ap.summary(wall_time_s=1.0)
    assert summary["landed"] and summary["disarmed"]
    assert [m["mode"] for m in summary["mode_history"]] == ["AUTO_TAKEOFF", "AUTO_LOITER", "AUTO_LAND", "AUTO_LOITER"]
    assert summary["tracking_pos_err_rms_m"] < 0.3
    assert summary["max_tilt_deg"] < 25.0
    assert "Landing detected" in loop.texts


def _item(seq: int, cmd: int, frame: LocalNedFrame, n: float = 0.0, e: float = 0.0, alt: float = 0.0, **kw: float):  # type: ignore[no-untyped-def]
    geo = frame.geodetic_from_ned(n, e, 0.0)
    lat, lon = (geo.lat_deg, geo.lon_deg) if (n, e) != (0.0, 0.0) else (0.0, 0.0)
    return MissionItem(seq, cmd, 6, kw.get("p1", 0.0), kw.get("p2", 0.0), 0.0, math.nan, lat, lon, alt)


def test_mission_with_payload_release_reaches_every_item_in_order() -> None:
    loop = Loop()
    ap, vehicle = loop.ap, loop.vehicle
    items_early = [MissionItem(0, 22, 6, z_alt_m=5.0)]
    # before the first fix: stored, checked against home once it is known (issue 13/15), not flyable yet
    assert vehicle.replace_mission(MissionType.MISSION, items_early) == (MissionResult.ACCEPTED, "")
    assert not ap.navigator.mission_ready
    loop.run_until(lambda: False, 0.5)
    assert ap.navigator.mission_ready
    f = loop.frame
    mission = [
        _item(0, 22, f, alt=6.0),
        _item(1, 16, f, 12.0, 0.0, 6.0, p2=1.0),
        _item(2, 211, f, p1=1.0, p2=0.0),  # DO_GRIPPER release
        _item(3, 16, f, 12.0, 8.0, 8.0),
        _item(4, 21, f, 12.0, 8.0, 0.0),
    ]
    mission[2] = MissionItem(2, 211, 2, 1.0, 0.0)
    assert vehicle.replace_mission(MissionType.MISSION, mission) == (MissionResult.ACCEPTED, "")
    assert vehicle.mission_items(MissionType.MISSION) == mission
    bad = [*mission[:1], MissionItem(1, 16, 6, x_lat_deg=123.0, y_lon_deg=8.0, z_alt_m=5.0)]
    result, reason = vehicle.replace_mission(MissionType.MISSION, bad)
    assert result is not MissionResult.ACCEPTED and "item 1" in reason
    assert vehicle.mission_items(MissionType.MISSION) == mission  # previous mission kept
    assert vehicle.handle_command(command(400, 1.0)) is CommandResult.ACCEPTED
    assert vehicle.handle_command(command(300, 0, 0)) is CommandResult.ACCEPTED
    assert ap.commander.mode is FlightMode.AUTO_MISSION
    assert loop.run_until(lambda: not ap.commander.armed, 90.0)
    assert ap.progress.reached_seqs == [0, 1, 2, 3, 4]
    assert loop.released_at_s is not None
    summary = ap.summary(1.0)
    assert summary["items_reached"] == summary["items_total"] == 5
    assert summary["mission_state"] == "COMPLETE" and summary["payload_released"]
    assert loop.sim.pos_ned[:2] == pytest.approx([12.0, 8.0], abs=0.5)


def test_params_refused_out_of_range_and_live_in_flight() -> None:
    loop = Loop()
    vehicle = loop.vehicle
    ok, value, reason = vehicle.param_set("MPC_TKO_SPEED", 99.0)
    assert not ok and value == vehicle.param_get("MPC_TKO_SPEED") and "outside" in reason
    assert vehicle.param_get("NO_SUCH_PARAM") is None
    assert vehicle.param_set("NO_SUCH_PARAM", 1.0)[0] is False
    assert "MIS_TAKEOFF_ALT" in vehicle.param_names() and "MIS_RTL_ALT" in vehicle.param_names()
    assert vehicle.param_set("MPC_TKO_SPEED", 3.0) == (True, 3.0, "")
    loop.run_until(lambda: False, 0.5)
    vehicle.handle_command(command(400, 1.0))
    vehicle.handle_command(command(22, *[0] * 6, math.nan))
    loop.run_until(lambda: False, 3.0)
    climb = -loop.sim.vel_ned[2]
    assert climb == pytest.approx(3.0, abs=0.3)  # MPC_TKO_SPEED in force
    assert vehicle.param_set("MPC_ACC_HOR", 1.0)[0]
    assert loop.ap.control.setpoints.limits.acc_xy_m_s2 == 1.0
