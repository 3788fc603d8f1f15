"""EKF estimator: alignment, static convergence, gating, GPS dropout, never the truth, NaN input, arming, report."""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np
import pytest
from autopilot_fakes import make_commander

from autopilot.estimation import EkfEstimator, EstimatorStatus, make_estimator
from autopilot.estimation.report import (
    SENSOR_AHRS,
    SENSOR_GPS,
    SENSOR_MAG,
    apply_estimator_health,
    estimator_flags,
    estimator_report,
)
from mavlink_bridge.contract.frames import GeoPoint, LocalNedFrame, dcm_from_quat, quat_from_euler
from mavlink_bridge.contract.vehicle_api import EstimatorFlags
from mavlink_bridge.contract.wire import GpsSample, SensorSample

ORIGIN = GeoPoint(30.2635, 120.1233, 12.0)
FRAME = LocalNedFrame(ORIGIN)
MAG_NED = np.array([0.21, 0.0, 0.42])
G = 9.80665
STEP_US = 4000


class _TruthForbidden:
    """A frame whose truth raises: the EKF must never read it."""

    @property
    def truth(self):  # type: ignore[no-untyped-def]
        raise AssertionError("the EKF read the ground truth")


@dataclass(frozen=True)
class Frame(_TruthForbidden):
    sensor: SensorSample
    gps: GpsSample | None


class StillVehicle:
    """A vehicle standing still at ``pos_ned`` with attitude ``euler``: noisy IMU/mag/baro, GPS at 10 Hz."""

    def __init__(self, euler=(0.05, -0.03, 0.8), pos_ned=(0.0, 0.0, 0.0), seed: int = 1, noise: bool = True):  # type: ignore[no-untyped-def]
        self.rng = np.random.default_rng(seed)
        self.s = 1.0 if noise else 0.0
        self.q = np.array(quat_from_euler(*euler))
        self.r = dcm_from_quat(self.q)
        self.pos = np.array(pos_ned, dtype=float)
        self.t_us = 0
        self.gyro_bias = np.array([0.002, -0.001, 0.0015]) * self.s

    def frame(self, gps: bool = True, gps_offset_ned=(0.0, 0.0, 0.0), **override) -> Frame:  # type: ignore[no-untyped-def]
        n = self.rng.standard_normal(16) * self.s
        accel = self.r.T @ np.array([0.0, 0.0, -G]) + 0.05 * n[0:3]
        gyro = self.gyro_bias + 0.004 * n[3:6]
        mag = self.r.T @ MAG_NED + 0.004 * n[6:9]
        alt = ORIGIN.alt_amsl_m - self.pos[2] + 0.08 * n[9]
        values = {"accel": tuple(accel), "gyro": tuple(gyro), "mag": tuple(mag), "baro": float(alt)}
        values.update(override)
        sensor = SensorSample(self.t_us, values["accel"], values["gyro"], values["mag"], 1000.0, values["baro"], 15.0)
        sample = None
        if gps and self.t_us % 100_000 == 0:
            p = self.pos + 0.2 * n[10:13] + np.array(gps_offset_ned)
            geo = FRAME.geodetic_from_ned(*p)
            sample = GpsSample(
                self.t_us, geo.lat_deg, geo.lon_deg, geo.alt_amsl_m, tuple(0.05 * n[13:16]), 0.8, 1.4, 3, 12
            )
        self.t_us += STEP_US
        return Frame(sensor, sample)

    def run(self, est: EkfEstimator, seconds: float, **kw):  # type: ignore[no-untyped-def]
        state = None
        for _ in range(round(seconds * 250)):
            state = est.update(self.frame(**kw))
        return state


def _att_err_deg(q_est, q_true) -> float:  # type: ignore[no-untyped-def]
    dot = abs(float(np.dot(q_est, q_true)))
    return math.degrees(2.0 * math.acos(min(1.0, dot)))


def test_make_estimator_knows_ekf() -> None:
    assert isinstance(make_estimator("ekf"), EkfEstimator)


def test_alignment_levels_from_the_accelerometer_and_heads_from_the_magnetometer() -> None:
    vehicle, est = StillVehicle(euler=(0.1, -0.05, 2.0)), EkfEstimator()
    state = est.update(vehicle.frame())
    assert state is not None and not state.valid  # origin from the first fix, not aligned yet
    assert not est.status.aligned and est.status.reason.startswith("aligning")
    state = vehicle.run(est, 0.45)
    assert not est.status.aligned
    state = vehicle.run(est, 0.2)
    assert est.status.aligned and state is not None and state.valid
    assert (state.roll_rad, state.pitch_rad, state.yaw_rad) == pytest.approx((0.1, -0.05, 2.0), abs=0.01)


def test_a_moving_vehicle_does_not_align() -> None:
    vehicle, est = StillVehicle(), EkfEstimator()
    for _ in range(500):
        est.update(vehicle.frame(gyro=(0.5, 0.0, 0.0)))
    assert not est.status.aligned and "moving" in est.status.reason


def test_static_convergence_to_a_healthy_estimate() -> None:
    vehicle, est = StillVehicle(pos_ned=(0.0, 0.0, 0.0)), EkfEstimator()
    state = vehicle.run(est, 20.0)
    assert state is not None and state.valid
    status = est.status
    assert status.healthy and status.reason == "" and status.gps_fused and status.baro_fused and status.mag_fused
    assert not status.dead_reckoning and status.pos_horiz_valid and status.pos_vert_valid
    assert np.linalg.norm(state.pos_ned_m[:2]) < 0.5 and abs(state.pos_ned_m[2]) < 1.0  # height: one fix sets it
    assert np.linalg.norm(state.vel_ned_m_s) < 0.1
    assert _att_err_deg(state.q_ned_frd, vehicle.q) < 1.0
    assert np.linalg.norm(state.rate_frd_rad_s) < 0.02  # gyro bias removed
    assert 0.0 < status.pos_horiz_accuracy_m < 1.0 and status.pos_test_ratio < 1.0


def test_the_innovation_gate_rejects_a_gps_outlier() -> None:
    vehicle, est = StillVehicle(), EkfEstimator()
    vehicle.run(est, 10.0)
    assert est.status.healthy
    while vehicle.t_us % 100_000:  # up to the next fix
        est.update(vehicle.frame())
    state = est.update(vehicle.frame(gps_offset_ned=(40.0, 0.0, 0.0)))
    assert state is not None and abs(state.pos_ned_m[0]) < 1.0  # not pulled towards the outlier
    assert est.status.pos_test_ratio > 1.0 and not est.status.healthy
    assert estimator_flags(est.status) & EstimatorFlags.GPS_GLITCH
    vehicle.run(est, 1.0)
    assert est.status.pos_test_ratio < 1.0


def test_gps_dropout_dead_reckons_then_recovers() -> None:
    vehicle, est = StillVehicle(), EkfEstimator()
    vehicle.run(est, 10.0)
    assert est.status.gps_fused and not est.status.dead_reckoning
    state = vehicle.run(est, 3.0, gps=False)
    status = est.status
    assert status.dead_reckoning and not status.gps_fused and not status.healthy
    assert "dead reckoning" in status.reason and status.pos_horiz_valid  # still valid within EKF2_NOAID_TOUT
    assert state is not None and np.linalg.norm(state.pos_ned_m[:2]) < 2.0
    acc_dr = status.pos_horiz_accuracy_m
    vehicle.run(est, 3.0, gps=False)
    assert est.status.pos_horiz_accuracy_m > acc_dr and not est.status.pos_horiz_valid  # growing covariance
    vehicle.run(est, 2.0)
    assert est.status.gps_fused and not est.status.dead_reckoning and est.status.healthy


def test_baro_and_mag_loss_fall_back_to_gps_height_and_gyro_heading() -> None:
    vehicle, est = StillVehicle(), EkfEstimator()
    vehicle.run(est, 10.0)
    state = vehicle.run(est, 3.0, baro=math.nan, mag=(0.0, 0.0, 0.0))
    status = est.status
    assert not status.baro_fused and not status.mag_fused and status.pos_vert_valid and status.healthy
    assert state is not None and abs(state.pos_ned_m[2]) < 1.0
    assert abs(state.yaw_rad - 0.8) < 0.02
    vehicle.run(est, 1.0)
    assert est.status.baro_fused and est.status.mag_fused


def test_non_finite_samples_never_crash_or_poison_the_state() -> None:
    vehicle, est = StillVehicle(), EkfEstimator()
    vehicle.run(est, 5.0)
    nan3 = (math.nan, math.nan, math.nan)
    for override in ({"accel": nan3}, {"gyro": (0.0, math.inf, 0.0)}, {"mag": nan3}, {"baro": math.nan}):
        state = est.update(vehicle.frame(**override))
        assert state is not None and state.valid
        assert all(math.isfinite(v) for v in (*state.pos_ned_m, *state.vel_ned_m_s, *state.q_ned_frd))
    assert "IMU" in est.status.reason
    gps = GpsSample(vehicle.t_us, math.nan, ORIGIN.lon_deg, 12.0, (math.nan, 0.0, 0.0), 0.8, 1.4, 3, 12)
    state = est.update(Frame(vehicle.frame(gps=False).sensor, gps))
    assert state is not None and math.isfinite(state.pos_ned_m[0])
    vehicle.run(est, 2.0)
    assert est.status.healthy


def test_no_state_before_a_fix_and_the_origin_is_the_first_good_fix() -> None:
    vehicle, est = StillVehicle(pos_ned=(3.0, -2.0, 0.0), noise=False), EkfEstimator()
    assert est.update(vehicle.frame(gps=False)) is None and est.origin is None
    vehicle.t_us = 100_000
    vehicle.run(est, 2.0)
    assert est.origin is not None
    assert FRAME.ned_from_geodetic(est.origin.lat_deg, est.origin.lon_deg, est.origin.alt_amsl_m) == pytest.approx(
        (3.0, -2.0, 0.0), abs=1e-3
    )


def test_arming_is_refused_until_the_filter_is_aligned_and_healthy() -> None:
    vehicle, est = StillVehicle(), EkfEstimator()
    commander = make_commander()

    def refusal(state):  # type: ignore[no-untyped-def]
        commander.context = replace(commander.context, estimator_status=est.status)  # as the runner hands it over
        return commander.arming_refusal(state)

    state = est.update(vehicle.frame())
    reason = refusal(state)
    assert reason is not None and "aligning" in reason
    state = vehicle.run(est, 0.7)
    reason = refusal(state)
    assert reason is not None and reason.startswith("estimator:")
    state = vehicle.run(est, 2.0)
    assert refusal(state) is None


def test_report_and_health_bits_follow_the_status() -> None:
    ok = EstimatorStatus(
        aligned=True, healthy=True, gps_fused=True, baro_fused=True, mag_fused=True, pos_horiz_valid=True,
        pos_vert_valid=True, vel_test_ratio=0.1, pos_test_ratio=0.2, hgt_test_ratio=0.3, mag_test_ratio=0.4,
        pos_horiz_accuracy_m=0.5, pos_vert_accuracy_m=0.6, reason="",
    )  # fmt: skip
    report = estimator_report(ok)
    assert report.flags & EstimatorFlags.ATTITUDE and report.flags & EstimatorFlags.POS_HORIZ_ABS
    assert not report.flags & EstimatorFlags.CONST_POS_MODE
    assert (report.vel_ratio, report.pos_horiz_ratio, report.pos_horiz_accuracy_m) == (0.1, 0.2, 0.5)
    all_bits = 0xFFFFFFF
    assert apply_estimator_health(all_bits, ok) == all_bits
    aligning = EstimatorStatus()
    cleared = apply_estimator_health(all_bits, aligning)
    assert not cleared & (SENSOR_AHRS | SENSOR_GPS | SENSOR_MAG)
    assert estimator_flags(aligning) == EstimatorFlags(0)


class _FakeRec:
    """Records ``log`` and ``send_columns`` calls (path, archetype or columns) like a Rerun recording stream."""

    def __init__(self) -> None:
        self.logged: list[tuple[str, object]] = []

    def log(self, path: str, value: object, static: bool = False) -> None:
        self.logged.append((path, value))

    def send_columns(self, path: str, indexes: object, columns: object) -> None:
        self.logged.append((path, columns))

    def set_time(self, timeline: str, duration: object) -> None:
        pass


def test_recording_gets_estimate_vs_truth_error_series() -> None:
    from autopilot.telemetry.estimator_errors import ATT_ERR, POS_ERR, EstimatorErrorLog, attitude_error_ned_rad
    from mavlink_bridge.contract.wire import GroundTruth

    yaw_err = attitude_error_ned_rad(tuple(quat_from_euler(0.0, 0.0, 0.51)), tuple(quat_from_euler(0.0, 0.0, 0.5)))
    assert yaw_err == pytest.approx((0.0, 0.0, 0.01), abs=1e-6)
    vehicle, est = StillVehicle(), EkfEstimator()
    state = vehicle.run(est, 2.0)
    assert state is not None
    rec = _FakeRec()
    log = EstimatorErrorLog(rec, "sim_time")  # type: ignore[arg-type]
    geo = FRAME.geodetic_from_ned(0.0, 0.0, 0.0)
    q = tuple(float(v) for v in vehicle.q)
    truth = GroundTruth(state.time_us, q, (0, 0, 0), geo.lat_deg, geo.lon_deg, geo.alt_amsl_m, (0, 0, 0), (0, 0, -G))
    log.log(state, truth, est.status)
    log.log(state, truth, est.status)  # not due yet: nothing more
    assert len(rec.logged) == 4  # the four series' names; the sample waits in the batch
    log.flush()
    paths = [p for p, _ in rec.logged[4:]]
    assert paths == [POS_ERR, "estimator/vel_err_ned_m_s", ATT_ERR, "estimator/test_ratios"]


def test_the_sparse_covariance_prediction_is_phi_p_phi_transposed() -> None:
    from autopilot.estimation import ekf_layout as lay
    from autopilot.estimation.ekf_kernel import _predict

    rng = np.random.default_rng(5)
    x, _, _, prm, work, _ = lay.new_arrays()
    x[lay.X_Q : lay.X_Q + 4] = quat_from_euler(0.3, -0.2, 1.1)
    x[lay.X_GYRO_BIAS : lay.X_GYRO_BIAS + 3] = (0.01, -0.02, 0.005)
    root = rng.standard_normal((lay.N_E, lay.N_E))
    p = root @ root.T
    dt, f_frd, w_frd = 0.004, np.array([0.5, -0.3, -9.5]), np.array([0.2, -0.1, 0.3])
    r = dcm_from_quat(x[lay.X_Q : lay.X_Q + 4].copy())
    a_ned = r @ (f_frd - x[lay.X_ACCEL_BIAS : lay.X_ACCEL_BIAS + 3])
    phi = np.eye(lay.N_E)
    phi[lay.E_ATT : lay.E_ATT + 3, lay.E_GYRO_BIAS : lay.E_GYRO_BIAS + 3] = -r * dt
    phi[lay.E_VEL : lay.E_VEL + 3, lay.E_ACCEL_BIAS : lay.E_ACCEL_BIAS + 3] = -r * dt
    skew = np.array([[0.0, -a_ned[2], a_ned[1]], [a_ned[2], 0.0, -a_ned[0]], [-a_ned[1], a_ned[0], 0.0]])
    phi[lay.E_VEL : lay.E_VEL + 3, lay.E_ATT : lay.E_ATT + 3] = -skew * dt
    phi[lay.E_POS : lay.E_POS + 3, lay.E_VEL : lay.E_VEL + 3] = np.eye(3) * dt
    expected = phi @ p @ phi.T
    _predict(x, p, prm, work, dt, *f_frd, *w_frd)  # prm zeros: no process noise
    assert p == pytest.approx(expected, rel=1e-12, abs=1e-12)
