"""Truth estimator: local NED about the first fix, attitude, GPS quality and validity from known frames."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pytest

from autopilot.estimation import TruthEstimator, make_estimator
from mavlink_bridge.contract.frames import GeoPoint, LocalNedFrame, quat_from_euler
from mavlink_bridge.contract.wire import GpsSample, GroundTruth, SensorSample

ORIGIN = GeoPoint(30.2635, 120.1233, 12.0)
FRAME = LocalNedFrame(ORIGIN)


@dataclass(frozen=True)
class Frame:
    sensor: SensorSample
    gps: GpsSample | None
    truth: GroundTruth | None


def _sensor(t_us: int) -> SensorSample:
    return SensorSample(t_us, (0.0, 0.0, -9.8), (0.0, 0.0, 0.0), (0.2, 0.0, 0.4), 1013.0, 12.0, 20.0)


def _truth(t_us: int, pos_ned: tuple[float, float, float], q: tuple[float, float, float, float]) -> GroundTruth:
    geo = FRAME.geodetic_from_ned(*pos_ned)
    vel, accel = (1.0, 2.0, -0.5), (0.0, 0.0, -9.8)
    return GroundTruth(t_us, q, (0.1, -0.2, 0.3), geo.lat_deg, geo.lon_deg, geo.alt_amsl_m, vel, accel)


def test_first_fix_is_the_origin_and_positions_follow_in_ned() -> None:
    est = TruthEstimator()
    q = (1.0, 0.0, 0.0, 0.0)
    assert est.update(Frame(_sensor(0), None, None)) is None
    s0 = est.update(Frame(_sensor(4000), None, _truth(4000, (0.0, 0.0, 0.0), q)))
    assert s0 is not None and s0.pos_ned_m == pytest.approx((0.0, 0.0, 0.0), abs=1e-6)
    assert est.origin is not None and est.origin.lat_deg == pytest.approx(ORIGIN.lat_deg)
    s1 = est.update(Frame(_sensor(8000), None, _truth(8000, (120.0, -45.0, -30.0), q)))
    assert s1 is not None
    assert s1.pos_ned_m == pytest.approx((120.0, -45.0, -30.0), abs=1e-3)
    assert s1.vel_ned_m_s == (1.0, 2.0, -0.5) and s1.rate_frd_rad_s == (0.1, -0.2, 0.3)
    assert s1.time_us == 8000


def test_attitude_euler_matches_the_quaternion() -> None:
    est = TruthEstimator()
    roll, pitch, yaw = 0.2, -0.3, 2.5
    q = tuple(float(v) for v in quat_from_euler(roll, pitch, yaw))
    s = est.update(Frame(_sensor(0), None, _truth(0, (0.0, 0.0, 0.0), q)))  # type: ignore[arg-type]
    assert s is not None and s.valid
    assert (s.roll_rad, s.pitch_rad, s.yaw_rad) == pytest.approx((roll, pitch, yaw), abs=1e-9)
    assert np.linalg.norm(s.q_ned_frd) == pytest.approx(1.0)


def test_gps_quality_comes_from_the_latest_gps_sample() -> None:
    est = TruthEstimator()
    q = (1.0, 0.0, 0.0, 0.0)
    s = est.update(Frame(_sensor(0), None, _truth(0, (0.0, 0.0, 0.0), q)))
    assert s is not None and s.gps_fix_type == 0 and math.isinf(s.gps_eph_m)
    gps = GpsSample(100_000, ORIGIN.lat_deg, ORIGIN.lon_deg, ORIGIN.alt_amsl_m, (0, 0, 0), 0.7, 1.1, 3, 12)
    est.update(Frame(_sensor(100_000), gps, _truth(100_000, (0.0, 0.0, 0.0), q)))
    s = est.update(Frame(_sensor(104_000), None, _truth(104_000, (0.0, 0.0, 0.0), q)))
    assert s is not None and (s.gps_fix_type, s.gps_satellites, s.gps_eph_m) == (3, 12, 0.7)


def test_non_finite_or_non_unit_truth_is_not_valid() -> None:
    est = TruthEstimator()
    s = est.update(Frame(_sensor(0), None, _truth(0, (0.0, 0.0, 0.0), (1.0, 0.0, 0.0, 0.0))))
    assert s is not None and s.valid
    s = est.update(Frame(_sensor(4000), None, _truth(4000, (0.0, 0.0, 0.0), (math.nan, 0.0, 0.0, 0.0))))
    assert s is not None and not s.valid
    s = est.update(Frame(_sensor(8000), None, _truth(8000, (0.0, 0.0, 0.0), (2.0, 0.0, 0.0, 0.0))))
    assert s is not None and not s.valid
    fresh = TruthEstimator()
    nan_fix = GroundTruth(0, (1.0, 0.0, 0.0, 0.0), (0, 0, 0), math.nan, 0.0, 0.0, (0, 0, 0), (0, 0, 0))
    assert fresh.update(Frame(_sensor(0), None, nan_fix)) is None and fresh.origin is None


def test_make_estimator_names_the_choices() -> None:
    assert isinstance(make_estimator("truth"), TruthEstimator)
    with pytest.raises(ValueError, match="truth"):
        make_estimator("ekf9000")


def test_fast_built_state_is_the_frozen_dataclass_with_the_reference_values() -> None:
    """``TruthEstimator`` builds ``VehicleState`` through a plain twin (speed): same type, values, frozen."""
    import dataclasses

    from autopilot.estimation.state import VehicleState, _euler_zyx

    est = TruthEstimator()
    gps = GpsSample(4000, 30.2635, 120.1233, 12.0, (0.0, 0.0, 0.0), 0.8, 1.2, 3, 11)
    q = quat_from_euler(0.1, -0.2, 2.5)
    state = est.update(Frame(_sensor(4000), gps, _truth(4000, (1.0, 2.0, -3.0), tuple(q))))  # type: ignore[arg-type]
    assert type(state) is VehicleState
    reference = VehicleState(*(getattr(state, f.name) for f in dataclasses.fields(VehicleState)))
    assert state == reference and hash(state) == hash(reference) and repr(state) == repr(reference)
    assert (state.roll_rad, state.pitch_rad, state.yaw_rad) == _euler_zyx(state.q_ned_frd)
    assert (state.gps_fix_type, state.gps_satellites, state.gps_eph_m, state.gps_epv_m) == (3, 11, 0.8, 1.2)
    with pytest.raises(dataclasses.FrozenInstanceError):
        state.valid = False  # type: ignore[misc]
    assert dataclasses.replace(state, valid=False).valid is False
