"""A frozen GPS receiver (MAV_CMD_INJECT_FAILURE GPS STUCK) in flight on the EKF, closed loop in process (issue 22
item 5): the stale-data check drops the repeated fix, the estimator dead-reckons, the GPS-loss failsafe lands."""

from __future__ import annotations

import math

from autopilot_fakes import command
from autopilot_loop import SimLoop

from autopilot.estimation import EkfEstimator
from mavlink_bridge.contract.mav_enums import FailureType, FailureUnit, MavCmd
from mavlink_bridge.contract.vehicle_api import CommandResult, FlightMode
from sim.end_reason import EndReason
from sim.world import WindConfig, World, empty_world


def _airborne_on_the_ekf() -> tuple[SimLoop, EkfEstimator]:
    est = EkfEstimator()
    world = World(empty_world().home, (), WindConfig(mean_ned_m_s=(1.0, -0.5, 0.0), gust_m_s=0.3, seed=2), 0.0)
    loop = SimLoop("x500", estimator=est, world=world)
    loop.ap.params.set("SYS_FAILURE_EN", 1.0)
    loop.ap.params.set("COM_POS_FS_DELAY", 2.0)
    assert loop.run_until(
        lambda: est.status.healthy,
        30.0,
    ), est.status.reason
    loop.ap.update_context(estimator_status=est.status)
    loop.take_off(10.0, settle_s=2.0)
    return loop, est


def test_a_stuck_gps_is_caught_and_the_vehicle_lands_where_it_is() -> None:
    loop, est = _airborne_on_the_ekf()
    stuck = command(MavCmd.INJECT_FAILURE, FailureUnit.SENSOR_GPS, FailureType.STUCK, 0)
    assert loop.vehicle.handle_command(stuck) is CommandResult.ACCEPTED
    at_ned = loop.sim.pos_ned.copy()
    t0 = loop.sim.t_s
    assert loop.run_until(lambda: any(t.startswith("GPS stale") for t in loop.texts), 1.0), loop.texts
    assert loop.run_until(lambda: loop.ap.commander.mode is FlightMode.AUTO_LAND, 6.0), loop.texts
    assert any(t.startswith("GPS lost: dead reckoning") for t in loop.texts)
    assert any(t.startswith("Failsafe: position lost") for t in loop.texts)
    assert not est.status.gps_fused  # the frozen fixes never reach the filter
    assert loop.run_until(lambda: not loop.ap.commander.armed, 40.0), loop.texts
    assert loop.sim.end_reason is EndReason.RUNNING and loop.sim.on_ground  # landed, no ground impact
    drift_m = math.dist(loop.sim.pos_ned[:2], at_ned[:2])
    assert drift_m < 6.0, f"landed {drift_m:.1f} m from where the GPS froze ({loop.sim.t_s - t0:.0f} s later)"
