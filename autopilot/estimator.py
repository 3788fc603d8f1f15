"""State estimation: the ``Estimator`` seam and the ground-truth estimator (SPEC §4, issue 4).

An estimator turns one lockstep frame (IMU/baro/mag ``SensorSample``, an optional
``GpsSample`` at 10 Hz, and the sim's ``GroundTruth``) into a :class:`VehicleState`:
local NED position about the *origin* (the first position fix), NED velocity,
``q_ned_frd``, body rates, Euler angles and the GPS quality the arming checks need.

Seam for a sensor-fusion estimator (``--estimator ekf`` later): implement
:class:`Estimator` — ``update(frame)`` is called once per lockstep step with the whole
frame and must not read ``frame.truth``; it returns ``None`` until it has a first fix and
``VehicleState(valid=False)`` while it is not trusted. ``origin`` is the geodetic point of
local NED (0, 0, 0). Nothing else in the autopilot knows which estimator runs.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Protocol

from mavlink_bridge.frames import GeoPoint, LocalNedFrame
from mavlink_bridge.wire import GpsSample, GroundTruth, Quat, SensorSample, Vec3, fast_frozen_init


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


class _StateBuilder:
    """Same slots as :class:`VehicleState`, but plain: filled by attribute assignment, then re-classed.

    Building a frozen slotted dataclass calls a descriptor per field (16 here, every step); assigning to a
    plain twin's slots and switching ``__class__`` (allowed: identical slot layout) gives the same frozen
    ``VehicleState`` at a quarter of the cost (``tests/test_autopilot_estimator.py`` checks equality).
    """

    __slots__ = VehicleState.__slots__


class Estimator(Protocol):
    """One lockstep frame in, the vehicle state out (``None`` before the first fix)."""

    @property
    def origin(self) -> GeoPoint | None: ...

    @property
    def local_frame(self) -> LocalNedFrame | None: ...

    def update(self, frame: FrameLike) -> VehicleState | None: ...


def _euler_zyx(q: Quat) -> tuple[float, float, float]:
    """Roll, pitch, yaw (rad) of ``q_ned_frd``; scalar math (per step, no numpy allocation)."""
    w, x, y, z = q
    roll = math.atan2(2.0 * (w * x + y * z), 1.0 - 2.0 * (x * x + y * y))
    pitch = math.asin(max(-1.0, min(1.0, 2.0 * (w * y - z * x))))
    yaw = math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))
    return roll, pitch, yaw


class TruthEstimator:
    """The "truth" estimator: the sim's HIL_STATE_QUATERNION, expressed about the first fix.

    GPS quality (fix type, satellites, eph/epv) is taken from the latest ``GpsSample`` so
    that the arming checks still see "no fix" until the simulated receiver has one. The
    state is ``valid`` when the truth is finite and the quaternion has unit norm.
    """

    def __init__(self) -> None:
        self._frame: LocalNedFrame | None = None
        self._gps: GpsSample | None = None

    @property
    def origin(self) -> GeoPoint | None:
        return None if self._frame is None else self._frame.home

    @property
    def local_frame(self) -> LocalNedFrame | None:
        return self._frame

    def update(self, frame: FrameLike) -> VehicleState | None:
        if frame.gps is not None:
            self._gps = frame.gps
        truth = frame.truth
        if truth is None:
            return None
        if self._frame is None:
            if not (math.isfinite(truth.lat_deg) and math.isfinite(truth.lon_deg) and math.isfinite(truth.alt_amsl_m)):
                return None
            self._frame = LocalNedFrame(GeoPoint(truth.lat_deg, truth.lon_deg, truth.alt_amsl_m))
        pos = self._frame.ned_from_geodetic(truth.lat_deg, truth.lon_deg, truth.alt_amsl_m)
        q = truth.q_ned_frd
        norm = math.sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3])
        vel, rate = truth.vel_ned_m_s, truth.rate_frd_rad_s
        # a sum is finite only when every term is (inf - inf is NaN): one check instead of eleven
        finite = math.isfinite(pos[0] + pos[1] + pos[2] + vel[0] + vel[1] + vel[2] + rate[0] + rate[1] + rate[2] + norm)
        valid = finite and abs(norm - 1.0) < 1e-3
        if valid and norm != 1.0:
            q = (q[0] / norm, q[1] / norm, q[2] / norm, q[3] / norm)
        if valid:  # _euler_zyx inline (every step)
            w, x, y, z = q
            roll = math.atan2(2.0 * (w * x + y * z), 1.0 - 2.0 * (x * x + y * y))
            pitch = math.asin(max(-1.0, min(1.0, 2.0 * (w * y - z * x))))
            yaw = math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))
        else:
            roll = pitch = yaw = math.nan
        gps = self._gps
        s = _StateBuilder()  # VehicleState(...) at a quarter of the cost (see _StateBuilder)
        s.time_us, s.pos_ned_m, s.vel_ned_m_s, s.q_ned_frd, s.rate_frd_rad_s = truth.time_us, pos, vel, q, rate
        s.roll_rad, s.pitch_rad, s.yaw_rad = roll, pitch, yaw
        s.lat_deg, s.lon_deg, s.alt_amsl_m = truth.lat_deg, truth.lon_deg, truth.alt_amsl_m
        if gps is None:
            s.gps_fix_type, s.gps_satellites, s.gps_eph_m, s.gps_epv_m = 0, 0, math.inf, math.inf
        else:
            s.gps_fix_type, s.gps_satellites, s.gps_eph_m, s.gps_epv_m = (
                gps.fix_type,
                gps.satellites_visible,
                gps.eph_m,
                gps.epv_m,
            )
        s.valid = valid
        s.__class__ = VehicleState  # type: ignore[assignment]
        return s  # type: ignore[return-value]


ESTIMATORS = {"truth": TruthEstimator}


def make_estimator(name: str) -> Estimator:
    """The estimator called ``name`` (``--estimator``); ValueError names the choices."""
    try:
        return ESTIMATORS[name]()
    except KeyError:
        raise ValueError(f"unknown estimator {name!r}; choose one of {sorted(ESTIMATORS)}") from None
