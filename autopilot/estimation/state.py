"""What an estimator reads and what it produces: the per-step contract of ``autopilot.estimation``.

An estimator turns one lockstep frame (IMU/baro/mag ``SensorSample``, an optional ``GpsSample`` at 10 Hz and,
for the truth estimator only, the sim's ``GroundTruth``) into a :class:`VehicleState` (local NED about the
*estimator origin*, the first good fix) and an :class:`EstimatorStatus` (alignment, which sources are fused,
innovation test ratios, accuracies) for arming checks, failsafes and ESTIMATOR_STATUS.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Protocol

from mavlink_bridge.contract.frames import GeoPoint, LocalNedFrame, Quat, Vec3
from mavlink_bridge.contract.wire import GpsSample, GroundTruth, SensorSample, fast_frozen_init


class FrameLike(Protocol):
    """What an estimator reads from a lockstep frame (``mavlink_bridge.lockstep.LockstepFrame``)."""

    @property
    def sensor(self) -> SensorSample: ...

    @property
    def gps(self) -> GpsSample | None: ...

    @property
    def truth(self) -> GroundTruth | None: ...


@fast_frozen_init
@dataclass(frozen=True, slots=True)
class VehicleState:
    """The estimated vehicle state at one control step; NED about the local origin, SI units."""

    time_us: int
    pos_ned_m: Vec3
    vel_ned_m_s: Vec3
    q_ned_frd: Quat
    rate_frd_rad_s: Vec3
    roll_rad: float
    pitch_rad: float
    yaw_rad: float
    lat_deg: float
    lon_deg: float
    alt_amsl_m: float
    gps_fix_type: int  # 0 none, 2 2D, 3 3D (GPS_FIX_TYPE)
    gps_satellites: int
    gps_eph_m: float
    gps_epv_m: float
    valid: bool


@dataclass(frozen=True, slots=True)
class EstimatorStatus:
    """The estimator's health at one step (PX4 ``estimator_status`` in spirit; ESTIMATOR_STATUS on the wire).

    Test ratios are innovation² / gate² (PX4's convention: > 1 means the measurement was rejected); NaN when that
    source was not fused. An estimator hands out the same object while nothing changes (no per-step
    allocation). Accuracies are 1-sigma from the filter's covariance. ``reason`` says, for a user, why
    the estimate is not ``healthy`` ("" when it is).
    """

    aligned: bool = False  # tilt and heading initialised on the ground
    healthy: bool = False  # aligned, position valid, innovations passing: fit to arm and fly
    gps_fused: bool = False  # GPS position/velocity fused recently
    baro_fused: bool = False
    mag_fused: bool = False
    dead_reckoning: bool = False  # horizontal position from the IMU alone (GPS lost)
    pos_horiz_valid: bool = False
    pos_vert_valid: bool = False
    vel_test_ratio: float = math.nan
    pos_test_ratio: float = math.nan
    hgt_test_ratio: float = math.nan
    mag_test_ratio: float = math.nan
    pos_horiz_accuracy_m: float = math.nan
    pos_vert_accuracy_m: float = math.nan
    reason: str = "no data yet"


class Estimator(Protocol):
    """One lockstep frame in, the vehicle state out (``None`` before the first fix)."""

    @property
    def origin(self) -> GeoPoint | None: ...

    @property
    def local_frame(self) -> LocalNedFrame | None: ...

    @property
    def status(self) -> EstimatorStatus: ...

    def set_landed(self, landed: bool) -> None:
        """The land detector's verdict for the next :meth:`update` (an EKF fuses zero velocity while landed)."""

    def update(self, frame: FrameLike) -> VehicleState | None: ...


def _euler_zyx(q: Quat) -> tuple[float, float, float]:
    """Roll, pitch, yaw (rad) of ``q_ned_frd``; scalar math (per step, no numpy allocation)."""
    w, x, y, z = q
    roll = math.atan2(2.0 * (w * x + y * z), 1.0 - 2.0 * (x * x + y * y))
    pitch = math.asin(max(-1.0, min(1.0, 2.0 * (w * y - z * x))))
    yaw = math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))
    return roll, pitch, yaw
