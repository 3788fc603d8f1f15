"""The EKF in the in-process closed loop: arming waits for it, SYS_STATUS health and ESTIMATOR_STATUS follow it.

The runner hands ``estimator.status`` to the commander in ``CommandContext.estimator_status``; these tests do
that step by step, as the runner does, and read what a GCS would get (``Autopilot.snapshot``).
"""

from __future__ import annotations

from autopilot_fakes import command
from autopilot_loop import SimLoop

from autopilot.estimation import EkfEstimator
from autopilot.estimation.report import SENSOR_AHRS, SENSOR_GPS, SENSOR_MAG
from autopilot.reporting.report import SENSOR_PREARM_CHECK
from mavlink_bridge.contract.vehicle_api import CommandResult, EstimatorFlags

GYRO, ACCEL = 0x1, 0x2


def _loop() -> tuple[SimLoop, EkfEstimator]:
    est = EkfEstimator()
    loop = SimLoop("x500", seed=4, estimator=est)
    return loop, est


def _run(loop: SimLoop, est: EkfEstimator, seconds: float) -> None:
    def wire() -> None:
        loop.ap.update_context(estimator_status=est.status)

    loop.run_s(seconds, wire)


def test_arming_is_refused_with_the_reason_until_the_ekf_is_healthy_then_health_is_all_ok() -> None:
    loop, est = _loop()
    _run(loop, est, 0.3)
    assert not est.status.aligned
    assert loop.vehicle.handle_command(command(400, 1.0)) is not CommandResult.ACCEPTED
    reason = loop.ap.commander.last_reason
    assert "estimator" in reason and "aligning" in reason
    assert any("aligning" in t.text for t in loop.ap.drain_texts())  # the STATUSTEXT a GCS shows
    snap = loop.ap.snapshot()
    assert snap is not None and snap.estimator is not None
    assert not snap.sensors_health & (SENSOR_AHRS | SENSOR_GPS | SENSOR_PREARM_CHECK)
    assert not snap.estimator.flags & EstimatorFlags.ATTITUDE
    _run(loop, est, 2.5)
    assert est.status.healthy, est.status.reason
    snap = loop.ap.snapshot()
    assert snap is not None and snap.estimator is not None
    # what MAVSDK's health_all_ok reads: gyro, accel, mag (present and healthy), GPS (global/local position), and
    # the pre-arm bit (is_armable)
    wanted = GYRO | ACCEL | SENSOR_MAG | SENSOR_GPS | SENSOR_AHRS | SENSOR_PREARM_CHECK
    assert snap.sensors_present & wanted == wanted and snap.sensors_health & wanted == wanted
    assert snap.estimator.flags & (EstimatorFlags.ATTITUDE | EstimatorFlags.POS_HORIZ_ABS | EstimatorFlags.POS_VERT_ABS)
    assert 0.0 < snap.estimator.pos_horiz_accuracy_m < 2.0
    assert loop.vehicle.handle_command(command(400, 1.0)) is CommandResult.ACCEPTED
