"""What a GCS sees of the estimator: ESTIMATOR_STATUS contents and the SYS_STATUS health bits it drives.

PX4 fills ESTIMATOR_STATUS.flags from EKF2's ``control_status``/``solution_status`` and clears the SYS_STATUS
health of AHRS, GPS, baro and mag when the estimator stops using them (``HealthAndArmingChecks``); these two
pure functions do the same from an :class:`EstimatorStatus`.
"""

from __future__ import annotations

from autopilot.estimation.state import EstimatorStatus
from mavlink_bridge.contract.vehicle_api import EstimatorFlags, EstimatorReport

#: MAV_SYS_STATUS_SENSOR bits the estimator speaks for.
SENSOR_MAG = 0x4
SENSOR_ABSOLUTE_PRESSURE = 0x8
SENSOR_GPS = 0x20
SENSOR_AHRS = 0x200000
ESTIMATOR_SENSOR_BITS = SENSOR_MAG | SENSOR_ABSOLUTE_PRESSURE | SENSOR_GPS | SENSOR_AHRS


def estimator_flags(status: EstimatorStatus) -> EstimatorFlags:
    """ESTIMATOR_STATUS_FLAGS of a status: attitude once aligned, velocity and position while valid."""
    flags = EstimatorFlags(0)
    if status.aligned:
        flags |= EstimatorFlags.ATTITUDE
    if status.pos_horiz_valid:
        flags |= EstimatorFlags.VELOCITY_HORIZ | EstimatorFlags.POS_HORIZ_REL
        flags |= EstimatorFlags.PRED_POS_HORIZ_REL
        if status.gps_fused or status.dead_reckoning:
            flags |= EstimatorFlags.POS_HORIZ_ABS | EstimatorFlags.PRED_POS_HORIZ_ABS
    if status.pos_vert_valid:
        flags |= EstimatorFlags.VELOCITY_VERT | EstimatorFlags.POS_VERT_ABS
    if status.aligned and not status.pos_horiz_valid:
        flags |= EstimatorFlags.CONST_POS_MODE
    if status.pos_test_ratio > 1.0:
        flags |= EstimatorFlags.GPS_GLITCH
    return flags


def estimator_report(status: EstimatorStatus) -> EstimatorReport:
    """The ESTIMATOR_STATUS field set of ``status`` (the snapshot's ``estimator``)."""
    return EstimatorReport(
        flags=estimator_flags(status),
        vel_ratio=status.vel_test_ratio,
        pos_horiz_ratio=status.pos_test_ratio,
        pos_vert_ratio=status.hgt_test_ratio,
        mag_ratio=status.mag_test_ratio,
        pos_horiz_accuracy_m=status.pos_horiz_accuracy_m,
        pos_vert_accuracy_m=status.pos_vert_accuracy_m,
    )


def estimator_health_bits(status: EstimatorStatus) -> int:
    """Of ``ESTIMATOR_SENSOR_BITS``, those that are healthy: AHRS once aligned (and the estimate is healthy or
    dead reckoning), GPS while fused, baro while fused, mag while fused."""
    bits = 0
    if status.aligned and (status.healthy or status.dead_reckoning or status.pos_horiz_valid):
        bits |= SENSOR_AHRS
    if status.gps_fused:
        bits |= SENSOR_GPS
    if status.baro_fused:
        bits |= SENSOR_ABSOLUTE_PRESSURE
    if status.mag_fused:
        bits |= SENSOR_MAG
    return bits


def apply_estimator_health(sensors_health: int, status: EstimatorStatus) -> int:
    """``sensors_health`` with the estimator's bits replaced by :func:`estimator_health_bits`."""
    return (sensors_health & ~ESTIMATOR_SENSOR_BITS) | estimator_health_bits(status)
