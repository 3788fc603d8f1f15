"""Estimate-vs-truth error series for the Rerun recording, under ``estimator/`` (issue 12).

Ground truth is its own message (HIL_STATE_QUATERNION); this compares the estimate with it for the recording
only (nothing here feeds the flight software). Position is compared through the estimate's own lat/lon/alt
about a frame fixed at the first truth sample, so the estimator's origin choice does not count. Attitude error is
the small-angle rotation vector ``δθ`` of ``R_est R_trueᵀ = I − [δθ]×`` in NED (degrees).
"""

from __future__ import annotations

import math

import numpy as np
import rerun as rr

from autopilot.estimation.state import EstimatorStatus, VehicleState
from mavlink_bridge.contract.frames import GeoPoint, LocalNedFrame
from mavlink_bridge.contract.wire import GroundTruth

POS_ERR = "estimator/pos_err_ned_m"
VEL_ERR = "estimator/vel_err_ned_m_s"
ATT_ERR = "estimator/att_err_ned_deg"
TEST_RATIOS = "estimator/test_ratios"
_NAMES3 = ["north", "east", "down"]
_RATIO_NAMES = ["vel", "pos", "hgt", "mag"]


def attitude_error_ned_rad(q_est: tuple[float, ...], q_true: tuple[float, ...]) -> tuple[float, float, float]:
    """Small-angle rotation vector (rad, NED) taking the true attitude to the estimate."""
    w, x, y, z = q_est
    # q_err = q_est ⊗ q_true⁻¹ (global error); vector part × 2 ≈ −δθ with R_est = (I − [δθ]×) R_true
    tw, tx, ty, tz = q_true[0], -q_true[1], -q_true[2], -q_true[3]
    ew = w * tw - x * tx - y * ty - z * tz
    ex = w * tx + x * tw + y * tz - z * ty
    ey = w * ty - x * tz + y * tw + z * tx
    ez = w * tz + x * ty - y * tx + z * tw
    s = 2.0 if ew >= 0.0 else -2.0
    return (s * ex, s * ey, s * ez)


class EstimatorErrorLog:
    """Logs the estimate's error against the truth at ``rate_hz`` of sim time (a handful of ``rr.log`` calls)."""

    def __init__(self, rec: rr.RecordingStream, timeline: str, rate_hz: float = 25.0) -> None:
        self.rec = rec
        self.timeline = timeline
        self._period_us = round(1e6 / rate_hz)
        self._next_us = 0
        self._frame: LocalNedFrame | None = None
        for path in (POS_ERR, VEL_ERR, ATT_ERR):
            rec.log(path, rr.SeriesLines(names=_NAMES3), static=True)
        rec.log(TEST_RATIOS, rr.SeriesLines(names=_RATIO_NAMES), static=True)

    def log(self, state: VehicleState, truth: GroundTruth, status: EstimatorStatus | None = None) -> None:
        """One sample when due (and both are finite)."""
        t_us = truth.time_us
        if t_us < self._next_us or not state.valid:
            return
        self._next_us = t_us + self._period_us
        if self._frame is None:
            if not math.isfinite(truth.lat_deg + truth.lon_deg + truth.alt_amsl_m):
                return
            self._frame = LocalNedFrame(GeoPoint(truth.lat_deg, truth.lon_deg, truth.alt_amsl_m))
        f = self._frame
        pe = f.ned_from_geodetic(state.lat_deg, state.lon_deg, state.alt_amsl_m)
        pt = f.ned_from_geodetic(truth.lat_deg, truth.lon_deg, truth.alt_amsl_m)
        ve, vt = state.vel_ned_m_s, truth.vel_ned_m_s
        att = attitude_error_ned_rad(state.q_ned_frd, truth.q_ned_frd)
        rec = self.rec
        rec.set_time(self.timeline, duration=np.timedelta64(int(t_us), "us"))
        rec.log(POS_ERR, rr.Scalars([pe[0] - pt[0], pe[1] - pt[1], pe[2] - pt[2]]))
        rec.log(VEL_ERR, rr.Scalars([ve[0] - vt[0], ve[1] - vt[1], ve[2] - vt[2]]))
        rec.log(ATT_ERR, rr.Scalars([math.degrees(a) for a in att]))
        if status is not None:
            ratios = (status.vel_test_ratio, status.pos_test_ratio, status.hgt_test_ratio, status.mag_test_ratio)
            rec.log(TEST_RATIOS, rr.Scalars([r if math.isfinite(r) else 0.0 for r in ratios]))
