"""Stale-data check on the IMU, magnetometer, barometer and GPS, PX4's ``DataValidator`` way (SPEC §5b).

A real sensor's reading is never bit-identical for long: noise moves its last digits. A reading that stays
exactly the same for :data:`STALE_AFTER_US` is a stuck sensor (a frozen driver, a dead bus; or
MAV_CMD_INJECT_FAILURE ... STUCK). :class:`StaleSensorCheck` sits between the frame and the estimator: a stale
magnetometer or barometer is dropped (NaN: "no sample", the estimator falls back to GPS height or gyro heading
and its status says so); a stale GPS (position and velocity of every fix the same: a frozen receiver) is dropped
too (no fix: the estimator dead-reckons and the GPS-loss failsafe takes over); a stale gyro or accelerometer is
reported only (the IMU clocks the prediction and has no fallback here). A sensor becomes stale only in the
air (its clock restarts at takeoff): on the ground a resting vehicle in a noise-free sim (``--no-sensor-noise``)
reads exactly the same, and that is not a failure (a noise-free sim can still trip it in a perfectly steady
hover: real sensors, and the sim's default, are never noise-free); a stale sensor stays stale, on the ground
too, until its readings change. Every transition is a STATUSTEXT. While nothing is stale the frame goes through
unchanged (no allocation).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

from autopilot.estimation.state import FrameLike
from autopilot.safety.failure_injection import InjectedFrame
from mavlink_bridge.contract.vehicle_api import Severity, StatusText
from mavlink_bridge.contract.wire import SensorSample

#: A reading unchanged this long (sim µs) is stale (PX4: 100 equal samples, ~0.5 s at its baro rates).
STALE_AFTER_US = 500_000
GYRO, ACCEL, MAG, BARO, GPS = 0, 1, 2, 3, 4
_NAMES = ("Gyro", "Accel", "Mag", "Baro", "GPS")
_DROPPED = ("", "", "dropped: heading from the gyro", "dropped: height from GPS", "dropped: dead reckoning")
_NAN3 = (math.nan, math.nan, math.nan)
_NO_TEXTS: tuple[StatusText, ...] = ()


class StaleSensorCheck:
    """Per sensor: the last reading, since when it is unchanged, whether it is stale (see the module docstring)."""

    def __init__(self) -> None:
        self._last: list[object] = [None, None, None, None, None]
        self._since_us = [0, 0, 0, 0, 0]
        self.stale = [False, False, False, False, False]
        self._any_stale = False
        self._in_air = False
        self._texts: list[StatusText] = []

    def drain_texts(self) -> Sequence[StatusText]:
        """Stale / recovered events since the last call (a shared empty tuple when none)."""
        if not self._texts:
            return _NO_TEXTS
        out, self._texts = self._texts, []
        return out

    def _check(self, k: int, value: object, finite: bool, time_us: int, judge: bool) -> None:
        if not finite:  # no sample (already dropped upstream): nothing to judge
            return
        if value == self._last[k]:
            if judge and not self.stale[k] and time_us - self._since_us[k] >= STALE_AFTER_US:
                self.stale[k] = self._any_stale = True
                action = _DROPPED[k] or "no fallback: the estimate will degrade"
                severity = Severity.WARNING if _DROPPED[k] else Severity.CRITICAL
                held_s = (time_us - self._since_us[k]) * 1e-6
                self._texts.append(StatusText(severity, f"{_NAMES[k]} stale (unchanged for {held_s:.1f} s): {action}"))
            return
        self._last[k] = value
        self._since_us[k] = time_us
        if self.stale[k]:
            self.stale[k] = False
            self._any_stale = any(self.stale)
            self._texts.append(StatusText(Severity.NOTICE, f"{_NAMES[k]} readings change again: back in use"))

    def apply(self, frame: FrameLike, in_air: bool) -> FrameLike:
        """``frame`` as the estimator should see it (``frame`` itself unless a mag or baro is stale). On the ground
        nothing becomes stale, but a stale sensor stays so (and dropped) until its readings change."""
        s = frame.sensor
        t = s.time_us
        if in_air and not self._in_air:  # takeoff: every clock restarts (resting readings may be exact repeats)
            self._since_us[:] = [t] * len(self._since_us)
        self._in_air = in_air
        if not (in_air or self._any_stale):
            return frame
        fix = frame.gps
        if fix is not None:  # at the receiver's rate: the fix's position and velocity
            self._check(GPS, (fix.lat_deg, fix.lon_deg, fix.alt_amsl_m, fix.vel_ned_m_s), True, t, in_air)
        g, a, m, p = s.gyro_frd_rad_s, s.accel_frd_m_s2, s.mag_frd_gauss, s.pressure_alt_m
        last = self._last
        moved = g != last[GYRO] and a != last[ACCEL] and m != last[MAG] and p != last[BARO]
        if not self._any_stale and moved:
            last[GYRO], last[ACCEL], last[MAG], last[BARO] = g, a, m, p  # the usual step: every reading moved
            since = self._since_us
            since[GYRO] = since[ACCEL] = since[MAG] = since[BARO] = t
            return frame
        self._check(GYRO, g, True, t, in_air)
        self._check(ACCEL, a, True, t, in_air)
        self._check(MAG, m, math.isfinite(m[0] + m[1] + m[2]), t, in_air)
        self._check(BARO, p, math.isfinite(p), t, in_air)
        stale = self.stale
        if not (stale[MAG] or stale[BARO] or stale[GPS]):
            return frame
        sensor = s
        if stale[MAG] or stale[BARO]:
            mag = _NAN3 if stale[MAG] else m
            pressure_hpa, pressure_alt_m = (math.nan, math.nan) if stale[BARO] else (s.abs_pressure_hpa, p)
            sensor = SensorSample(t, a, g, mag, pressure_hpa, pressure_alt_m, s.temperature_degc)
        fix = None if stale[GPS] else frame.gps
        return InjectedFrame(sensor, fix, frame.truth, getattr(frame, "detections", ()))
