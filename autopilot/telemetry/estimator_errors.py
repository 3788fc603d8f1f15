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
_N_COLS = 13  # a buffered sample: 3 + 3 + 3 errors, 4 test ratios


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
    """Logs the estimate's error against the truth at ``rate_hz`` of sim time: rows are buffered and sent
    ``batch_rows`` at a time, one ``send_columns`` per series (a per-sample ``rr.log`` of four series cost the
    autopilot more than its own step at ``--speed max``); :meth:`flush` sends the rest."""

    def __init__(self, rec: rr.RecordingStream, timeline: str, rate_hz: float = 25.0, batch_rows: int = 50) -> None:
        self.rec = rec
        self.timeline = timeline
        self.batch_rows = batch_rows
        self._period_us = round(1e6 / rate_hz)
        self._next_us = 0
        self._frame: LocalNedFrame | None = None
        self._times: list[int] = []
        self._rows: list[float] = []  # per sample: position, velocity, attitude errors, then the 4 test ratios
        self._has_ratios: list[bool] = []
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
        row = self._rows
        row += (pe[0] - pt[0], pe[1] - pt[1], pe[2] - pt[2], ve[0] - vt[0], ve[1] - vt[1], ve[2] - vt[2])
        row += (math.degrees(att[0]), math.degrees(att[1]), math.degrees(att[2]))
        if status is not None:
            ratios = (status.vel_test_ratio, status.pos_test_ratio, status.hgt_test_ratio, status.mag_test_ratio)
            row += [r if math.isfinite(r) else 0.0 for r in ratios]
        else:
            row += (0.0, 0.0, 0.0, 0.0)
        self._has_ratios.append(status is not None)
        self._times.append(int(t_us))
        if len(self._times) >= self.batch_rows:
            self.flush()

    def flush(self) -> None:
        """Send the buffered samples (one ``send_columns`` per series)."""
        if not self._times:
            return
        n = len(self._times)
        rows = np.array(self._rows, dtype=np.float64).reshape(n, _N_COLS)
        t_us = np.array(self._times, dtype=np.int64)
        series: list[tuple[str, int, int, slice | np.ndarray]] = [
            (POS_ERR, 0, 3, slice(None)),
            (VEL_ERR, 3, 3, slice(None)),
            (ATT_ERR, 6, 3, slice(None)),
        ]
        has_ratios = np.array(self._has_ratios)
        if has_ratios.any():  # the test ratios only of the samples that came with an estimator status
            series.append((TEST_RATIOS, 9, 4, has_ratios))
        for path, c0, width, keep in series:
            self.rec.send_columns(
                path,
                indexes=[rr.TimeColumn(self.timeline, duration=t_us[keep].astype("timedelta64[us]"))],
                columns=rr.Scalars.columns(scalars=rows[keep, c0 : c0 + width]),
            )
        self._times.clear()
        self._rows.clear()
        self._has_ratios.clear()
