"""The EKF on the ground (issue 22 item 5): zero velocity while landed, the height datum from the baro, and disarm
as soon after touchdown as on the truth."""

from __future__ import annotations

import numpy as np
import pytest
from test_autopilot_ekf import ORIGIN, G, StillVehicle

from autopilot.estimation import EkfEstimator
from autopilot.estimation import ekf_layout as k
from tools.benchmarks.estimator import fly_delivery


def _drift_without_gps(landed: bool) -> tuple[float, float]:
    """Speed and horizontal distance (m/s, m) the estimate shows after 30 s without GPS, an accelerometer bias of
    0.15 m/s² appearing with the outage (the filter has not learnt it)."""
    vehicle, est = StillVehicle(seed=3), EkfEstimator()
    vehicle.run(est, 15.0)
    assert est.status.healthy
    est.set_landed(landed)
    state = None
    accel = tuple(vehicle.r.T @ np.array([0.0, 0.0, -G]) + np.array([0.15, 0.0, 0.0]))
    for _ in range(30 * 250):
        state = est.update(vehicle.frame(gps=False, accel=accel))
    assert state is not None
    return float(np.linalg.norm(state.vel_ned_m_s)), float(np.linalg.norm(state.pos_ned_m[:2]))


def test_landed_and_still_the_estimate_holds_still_without_gps() -> None:
    speed, moved = _drift_without_gps(landed=True)
    assert speed < 0.05 and moved < 0.5
    assert EkfEstimator().flags & k.F_AT_REST == 0
    speed_air, moved_air = _drift_without_gps(landed=False)  # the same outage in the air: no zero velocity
    assert speed_air > 1.0 and moved_air > 10.0


def test_a_moving_imu_gets_no_zero_velocity_even_when_told_landed() -> None:
    vehicle, est = StillVehicle(), EkfEstimator()
    vehicle.run(est, 10.0)
    est.set_landed(True)
    vehicle.run(est, 1.0)
    assert est.flags & k.F_AT_REST
    est.update(vehicle.frame(gyro=(0.6, 0.0, 0.0)))  # turning: not at rest
    assert not est.flags & k.F_AT_REST


def test_the_ground_reads_0_whatever_the_first_fix_says_about_height() -> None:
    vehicle, est = StillVehicle(seed=5), EkfEstimator()
    state = vehicle.run(est, 10.0, gps_offset_ned=(0.0, 0.0, -0.8))  # every fix 0.8 m too high
    assert state is not None and est.status.healthy
    assert state.pos_ned_m[2] == pytest.approx(0.0, abs=0.05)  # height from the baro datum
    assert est.origin is not None and est.origin.alt_amsl_m == pytest.approx(ORIGIN.alt_amsl_m + 0.8, abs=0.3)


def test_a_fix_that_comes_in_the_air_is_placed_on_the_height_climbed() -> None:
    vehicle, est = StillVehicle(seed=6), EkfEstimator()
    vehicle.run(est, 2.0, gps=False)  # aligned on the ground, no fix yet: the baro there is the datum
    vehicle.pos[2] = -5.0  # 5 m up when the first fix arrives
    state = vehicle.run(est, 10.0)
    assert state is not None and est.status.healthy
    assert state.pos_ned_m[2] == pytest.approx(-5.0, abs=0.3)
    assert est.origin is not None and est.origin.alt_amsl_m == pytest.approx(ORIGIN.alt_amsl_m, abs=0.5)


def test_disarm_follows_touchdown_as_fast_as_on_the_truth_and_the_ground_reads_0() -> None:
    ekf = fly_delivery("ekf", 1, time_estimator=False, sample_every=25)
    truth = fly_delivery("truth", 1, time_estimator=False, sample_every=25)
    assert ekf.completed and truth.completed
    assert ekf.disarm_delay_s == pytest.approx(truth.disarm_delay_s, abs=0.3)
    assert abs(ekf.landed_alt_rel_m) < 0.1
