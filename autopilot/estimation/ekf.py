"""The sensor-fusion estimator (``--estimator ekf``, the default): IMU, GPS, baro and magnetometer, never the truth.

A thin owner of :mod:`autopilot.estimation.ekf_kernel` (the filter itself, one numba call per step; the array
layout in :mod:`~autopilot.estimation.ekf_layout`): it picks the local origin at the first good fix (PX4 EKF2's
``_pos_ref``), hands the kernel the step's samples as scalars and turns its output array into a
:class:`VehicleState`, and its flags into an :class:`EstimatorStatus` (rebuilt only when the kernel's status
version changes: on a flag change, a GPS fusion, and at most every 0.1 s of sim time otherwise).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from autopilot.estimation import ekf_layout as k
from autopilot.estimation.ekf_kernel import ekf_step
from autopilot.estimation.state import EstimatorStatus, FrameLike, VehicleState
from mavlink_bridge.contract.frames import GeoPoint, LocalNedFrame
from mavlink_bridge.contract.wire import GpsSample


@dataclass(frozen=True)
class EkfParams:
    """Filter tuning, PX4 EKF2 names in the comments; noises are 1-sigma per sample, gates in sigmas."""

    gyro_noise_rad_s: float = 0.015  # EKF2_GYR_NOISE
    accel_noise_m_s2: float = 0.35  # EKF2_ACC_NOISE
    gyro_bias_noise_rad_s2: float = 1.0e-3  # EKF2_GYR_B_NOISE
    accel_bias_noise_m_s3: float = 3.0e-3  # EKF2_ACC_B_NOISE
    gps_pos_noise_m: float = 0.5  # EKF2_GPS_P_NOISE (the receiver's eph is used when larger)
    gps_vel_noise_m_s: float = 0.1  # EKF2_GPS_V_NOISE (the receiver here reports 0.05 m/s; PX4 default 0.3)
    gps_hgt_noise_m: float = 1.0  # GPS height when it is the height source
    baro_noise_m: float = 1.0  # EKF2_BARO_NOISE
    mag_noise_gauss: float = 0.05  # EKF2_MAG_NOISE
    mag_bias_noise_gauss_s: float = 1.0e-4  # EKF2_MAG_B_NOISE
    gps_pos_gate: float = 5.0  # EKF2_GPS_P_GATE
    gps_vel_gate: float = 5.0  # EKF2_GPS_V_GATE
    baro_gate: float = 5.0  # EKF2_BARO_GATE
    mag_gate: float = 3.0  # EKF2_MAG_GATE
    mag_declination_rad: float = 0.0  # EKF2_MAG_DECL (the sim's field has none)
    align_samples: int = 125  # still IMU samples averaged for the alignment (0.5 s at 250 Hz)
    gps_reset_s: float = 5.0  # GPS rejected this long: reset the position to it (EKF2_RESET_TIMEOUT_MAX-like)
    fuse_timeout_s: float = 0.5  # a source counts as fused if fused within this
    no_aid_dead_reckoning_s: float = 1.0  # no GPS fused this long: dead reckoning
    no_aid_valid_s: float = 5.0  # EKF2_NOAID_TOUT: horizontal position stays valid this long without GPS
    gps_max_eph_m: float = 5.0  # EKF2_REQ_EPH: a fix with a larger eph is not used
    health_gps_s: float = 1.0  # GPS fused this long before the filter reports healthy
    zero_vel_noise_m_s: float = 0.1  # the zero-velocity update while landed and still (PX4's ZUPT)
    zero_vel_period_s: float = 0.2  # how often it is fused


class _StateBuilder:
    """Plain twin of :class:`VehicleState` (same slots), re-classed after filling (see ``truth._StateBuilder``)."""

    __slots__ = VehicleState.__slots__


_NO_DATA = EstimatorStatus(reason="no sensor data yet")


class EkfEstimator:
    """Extended (error-state) Kalman filter on the step's IMU, GPS, baro and magnetometer samples.

    Reads ``frame.sensor`` and ``frame.gps`` only: ``frame.truth`` is never touched. Returns None until the
    first good fix has set the local origin; then a state every step, ``valid`` once aligned and positioned.
    :meth:`set_landed` (the land detector, each step) enables the zero-velocity update.
    """

    def __init__(self, params: EkfParams | None = None) -> None:
        self.params = params or EkfParams()
        self._x, self._p, self._aux, self._prm, self._work, self._out = k.new_arrays()
        p, prm = self.params, self._prm
        for index, value in (
            (k.P_GYR_NOISE, p.gyro_noise_rad_s), (k.P_ACC_NOISE, p.accel_noise_m_s2),
            (k.P_GYR_B_NOISE, p.gyro_bias_noise_rad_s2), (k.P_ACC_B_NOISE, p.accel_bias_noise_m_s3),
            (k.P_GPS_P_NOISE, p.gps_pos_noise_m), (k.P_GPS_V_NOISE, p.gps_vel_noise_m_s),
            (k.P_BARO_NOISE, p.baro_noise_m), (k.P_MAG_NOISE, p.mag_noise_gauss),
            (k.P_MAG_B_NOISE, p.mag_bias_noise_gauss_s), (k.P_MAG_GATE, p.mag_gate),
            (k.P_GPS_P_GATE, p.gps_pos_gate), (k.P_GPS_V_GATE, p.gps_vel_gate), (k.P_BARO_GATE, p.baro_gate),
            (k.P_MAG_DECL, p.mag_declination_rad),
            (k.P_ALIGN_SAMPLES, p.align_samples), (k.P_GPS_HGT_NOISE, p.gps_hgt_noise_m),
            (k.P_GPS_RESET_S, p.gps_reset_s), (k.P_FUSE_TIMEOUT_S, p.fuse_timeout_s),
            (k.P_NOAID_S, p.no_aid_dead_reckoning_s), (k.P_NOAID_VALID_S, p.no_aid_valid_s),
            (k.P_GPS_MAX_EPH, p.gps_max_eph_m), (k.P_ZUPT_NOISE, p.zero_vel_noise_m_s),
            (k.P_ZUPT_PERIOD_S, p.zero_vel_period_s),
        ):  # fmt: skip
            prm[index] = value
        self._warm_up()
        self._frame: LocalNedFrame | None = None
        self._gps: GpsSample | None = None
        self._version = -1
        self._status_version = -1
        self._status = _NO_DATA
        self._landed = 0

    def _warm_up(self) -> None:
        """One step on scratch arrays now: the kernel's first call JIT-loads it (seconds, when not cached), which
        must not happen inside the lockstep, where the sim would declare the autopilot lost."""
        x, p, aux, _, work, out = k.new_arrays()
        nan = math.nan
        ekf_step(x, p, aux, self._prm.copy(), work, out, 0, 0.0, 0.0, -9.8, 0.0, 0.0, 0.0, 0.2, 0.0, 0.4, 0.0,
                 0, nan, nan, nan, nan, nan, nan, nan, nan, 0)  # fmt: skip

    @property
    def origin(self) -> GeoPoint | None:
        return None if self._frame is None else self._frame.home

    @property
    def local_frame(self) -> LocalNedFrame | None:
        return self._frame

    @property
    def status(self) -> EstimatorStatus:
        """The filter's health now (rebuilt only after the kernel's status version changed)."""
        if self._status_version != self._version:
            self._status_version = self._version
            self._status = self._build_status()
        return self._status

    @property
    def flags(self) -> int:
        """The kernel's status bits (``ekf_kernel.F_*``)."""
        return int(self._aux[k.A_FLAGS])

    def set_landed(self, landed: bool) -> None:
        """The land detector's verdict for the next updates: while landed and still, zero velocity is fused."""
        self._landed = 1 if landed else 0

    def _origin_at(self, gps: GpsSample, baro_alt_m: float) -> GeoPoint:
        """The local origin at this fix, its altitude on the height datum (PX4: the baro on the ground at start
        is height 0): the fix's altitude minus the height the baro says the vehicle has climbed since, so the
        ground it started on reads 0 whatever the fix's vertical error."""
        datum = self._aux[k.A_BARO_DATUM]
        climbed_m = baro_alt_m - datum if math.isfinite(baro_alt_m - datum) else 0.0
        return GeoPoint(gps.lat_deg, gps.lon_deg, gps.alt_amsl_m - climbed_m)

    def _usable_fix(self, gps: GpsSample) -> bool:
        return (
            gps.fix_type >= 3
            and gps.eph_m <= self.params.gps_max_eph_m
            and math.isfinite(gps.lat_deg + gps.lon_deg + gps.alt_amsl_m)
        )

    def update(self, frame: FrameLike) -> VehicleState | None:
        sensor = frame.sensor
        gps = frame.gps
        has_gps = 0
        glat = glon = galt = gvn = gve = gvd = eph = epv = math.nan
        if gps is not None:
            self._gps = gps
            if self._usable_fix(gps):
                if self._frame is None:  # the local origin: the first good fix
                    self._frame = LocalNedFrame(self._origin_at(gps, sensor.pressure_alt_m))
                    self._prm[k.P_ECEF : k.P_ECEF + 12] = self._frame.ecef_constants
                    self._aux[k.A_HAS_ORIGIN] = 1.0
                has_gps = 1
                glat, glon, galt = gps.lat_deg, gps.lon_deg, gps.alt_amsl_m
                gvn, gve, gvd = gps.vel_ned_m_s
                eph, epv = gps.eph_m, gps.epv_m
        a, g, m = sensor.accel_frd_m_s2, sensor.gyro_frd_rad_s, sensor.mag_frd_gauss
        self._version = ekf_step(
            self._x, self._p, self._aux, self._prm, self._work, self._out, sensor.time_us,
            a[0], a[1], a[2], g[0], g[1], g[2], m[0], m[1], m[2], sensor.pressure_alt_m,
            has_gps, glat, glon, galt, gvn, gve, gvd, eph, epv, self._landed,
        )  # fmt: skip
        if self._frame is None:
            return None
        o = self._out.tolist()
        s = _StateBuilder()
        s.time_us = sensor.time_us
        s.q_ned_frd = (o[0], o[1], o[2], o[3])
        s.vel_ned_m_s = (o[4], o[5], o[6])
        s.pos_ned_m = (o[7], o[8], o[9])
        s.rate_frd_rad_s = (o[10], o[11], o[12])
        s.roll_rad, s.pitch_rad, s.yaw_rad = o[13], o[14], o[15]
        s.lat_deg, s.lon_deg, s.alt_amsl_m = o[16], o[17], o[18]
        last = self._gps
        if last is None:
            s.gps_fix_type, s.gps_satellites, s.gps_eph_m, s.gps_epv_m = 0, 0, math.inf, math.inf
        else:
            s.gps_fix_type, s.gps_satellites = last.fix_type, last.satellites_visible
            s.gps_eph_m, s.gps_epv_m = last.eph_m, last.epv_m
        s.valid = o[19] == 1.0
        s.__class__ = VehicleState  # type: ignore[assignment]
        return s  # type: ignore[return-value]

    def _build_status(self) -> EstimatorStatus:
        aux, flags = self._aux, self.flags
        t_s = aux[k.A_T]
        gps_fused = bool(flags & k.F_GPS_FUSED)
        aligned = bool(flags & k.F_ALIGNED)
        reason = self._reason(flags, t_s)
        return EstimatorStatus(
            aligned=aligned,
            healthy=reason == "",
            gps_fused=gps_fused,
            baro_fused=bool(flags & k.F_BARO_FUSED),
            mag_fused=bool(flags & k.F_MAG_FUSED),
            dead_reckoning=bool(flags & k.F_DEAD_RECKONING),
            pos_horiz_valid=bool(flags & k.F_POS_HORIZ_VALID),
            pos_vert_valid=bool(flags & k.F_POS_VERT_VALID),
            vel_test_ratio=float(aux[k.A_VEL_TR]) if gps_fused or flags & k.F_VEL_REJECTED else math.nan,
            pos_test_ratio=float(aux[k.A_POS_TR]) if gps_fused or flags & k.F_POS_REJECTED else math.nan,
            hgt_test_ratio=float(aux[k.A_HGT_TR]),
            mag_test_ratio=float(aux[k.A_MAG_TR]) if not flags & k.F_MAG_ABSENT else math.nan,
            pos_horiz_accuracy_m=float(self._out[k.O_ACC_H]) if flags & k.F_POS_INIT else math.nan,
            pos_vert_accuracy_m=float(self._out[k.O_ACC_V]) if flags & k.F_POS_INIT else math.nan,
            reason=reason,
        )

    def _reason(self, flags: int, t_s: float) -> str:
        """Why the filter is not healthy, for a user ("" when it is)."""
        if flags & k.F_IMU_BAD:
            return "IMU data invalid (non-finite samples)"
        if not flags & k.F_ALIGNED:
            if flags & k.F_MOVING:
                return "aligning: vehicle moving, keep it still on the ground"
            if flags & k.F_MAG_ABSENT:
                return "aligning: no magnetometer data for the heading"
            return "aligning: levelling from the accelerometer, heading from the magnetometer"
        if self._frame is None or not flags & k.F_POS_INIT:
            return "waiting for a 3D GPS fix"
        if flags & k.F_DEAD_RECKONING:
            return "dead reckoning: GPS not fused, position from the IMU only"
        if flags & k.F_POS_REJECTED:
            return "GPS position rejected by the innovation check"
        if not flags & k.F_POS_VERT_VALID:
            return "no height source (baro and GPS height not fused)"
        if not flags & k.F_GPS_FUSED:
            return "GPS not fused"
        if t_s - self._aux[k.A_T_GPS_START] < self.params.health_gps_s:
            return "GPS fusion settling"
        return ""
