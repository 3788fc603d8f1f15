"""The "truth" estimator (``--estimator truth``): the sim's HIL_STATE_QUATERNION about the first fix.

For controller studies only: it reads the frame's ground truth, which no real estimator can.
"""

from __future__ import annotations

import math

from autopilot.estimation.state import EstimatorStatus, FrameLike, VehicleState
from mavlink_bridge.contract.frames import GeoPoint, LocalNedFrame
from mavlink_bridge.contract.wire import GpsSample

#: The truth is always aligned; it is "healthy" once the receiver has a 3D fix (so the arming checks still wait for
#: GPS, as with a real estimator).
_TRUTH_OK = EstimatorStatus(
    aligned=True, healthy=True, gps_fused=True, baro_fused=True, mag_fused=True, pos_horiz_valid=True,
    pos_vert_valid=True, pos_horiz_accuracy_m=0.0, pos_vert_accuracy_m=0.0, reason="",
)  # fmt: skip
_NO_FIX = EstimatorStatus(aligned=True, pos_vert_valid=True, reason="no 3D GPS fix yet")
_INVALID = EstimatorStatus(reason="ground truth not finite")


class _StateBuilder:
    """Same slots as :class:`VehicleState`, but plain: filled by attribute assignment, then re-classed.

    Building a frozen slotted dataclass calls a descriptor per field (16 here, every step); assigning to a
    plain twin's slots and switching ``__class__`` (allowed: identical slot layout) gives the same frozen
    ``VehicleState`` at a quarter of the cost (``test_autopilot_estimator.py`` checks equality).
    """

    __slots__ = VehicleState.__slots__


class TruthEstimator:
    """The "truth" estimator: the sim's HIL_STATE_QUATERNION, expressed about the first fix.

    GPS quality (fix type, satellites, eph/epv) is taken from the latest ``GpsSample`` so
    that the arming checks still see "no fix" until the simulated receiver has one. The
    state is ``valid`` when the truth is finite and the quaternion has unit norm.
    """

    def __init__(self) -> None:
        self._frame: LocalNedFrame | None = None
        self._gps: GpsSample | None = None
        self._status = _NO_FIX
        # the geodetic kernels' first call JIT-loads them: now, not inside the lockstep
        LocalNedFrame(GeoPoint(0.0, 0.0, 0.0)).ned_from_geodetic(0.0, 0.0, 0.0)

    @property
    def origin(self) -> GeoPoint | None:
        return None if self._frame is None else self._frame.home

    @property
    def status(self) -> EstimatorStatus:
        return self._status

    @property
    def local_frame(self) -> LocalNedFrame | None:
        return self._frame

    def set_landed(self, landed: bool) -> None:
        """The truth needs no help on the ground."""

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
        fix = gps is not None and gps.fix_type >= 3
        status = _TRUTH_OK if valid and fix else (_NO_FIX if valid else _INVALID)
        if status is not self._status:
            self._status = status
        s.__class__ = VehicleState  # type: ignore[assignment]
        return s  # type: ignore[return-value]
