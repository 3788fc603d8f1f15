"""Stale-data check (PX4 DataValidator's stale test): a stuck mag/baro is dropped before the estimator and comes
back when its readings change; a stuck gyro/accel is reported; nothing becomes stale on the ground."""

from __future__ import annotations

import math

from autopilot.safety.failure_injection import InjectedFrame
from autopilot.safety.sensor_validation import GPS, STALE_AFTER_US, StaleSensorCheck
from mavlink_bridge.contract.vehicle_api import Severity
from mavlink_bridge.contract.wire import GpsSample, SensorSample

STEP_US = 4000


class _Frame:
    def __init__(self, t_us: int, k: int, frozen: frozenset[str] = frozenset()) -> None:
        def v(name: str, x: float) -> float:
            return 0.5 if name in frozen else x + 1e-3 * k

        mag = (v("mag", 0.2), 0.0, 0.4)
        self.sensor = SensorSample(
            t_us, (v("accel", 0.0), 0.0, -9.8), (v("gyro", 0.0), 0.0, 0.0), mag, 1000.0, v("baro", 10.0), 20.0
        )
        self.gps = None
        self.truth = None
        self.detections = ()


def _run(check: StaleSensorCheck, frozen: frozenset[str], seconds: float, in_air: bool = True, t0: int = 0):  # type: ignore[no-untyped-def]
    seen = None
    n = round(seconds * 1e6 / STEP_US)
    for k in range(n):
        seen = check.apply(_Frame(t0 + k * STEP_US, k, frozen), in_air)
    return seen, t0 + n * STEP_US


def test_changing_readings_pass_through_unchanged() -> None:
    check = StaleSensorCheck()
    frame = _Frame(0, 1)
    assert check.apply(frame, True) is frame
    seen, _ = _run(check, frozenset(), 2.0)
    assert not isinstance(seen, InjectedFrame) and not any(check.stale) and not check.drain_texts()


def test_a_stuck_baro_is_dropped_after_the_stale_time_and_comes_back() -> None:
    check = StaleSensorCheck()
    seen, t = _run(check, frozenset({"baro"}), STALE_AFTER_US * 1e-6 - 0.02)
    assert not isinstance(seen, InjectedFrame)  # not yet
    seen, t = _run(check, frozenset({"baro"}), 0.1, t0=t)
    assert isinstance(seen, InjectedFrame) and math.isnan(seen.sensor.pressure_alt_m)
    assert math.isnan(seen.sensor.abs_pressure_hpa) and seen.sensor.mag_frd_gauss[0] == seen.sensor.mag_frd_gauss[0]
    (text,) = check.drain_texts()
    assert text.text.startswith("Baro stale") and "height from GPS" in text.text and text.severity is Severity.WARNING
    seen, _ = _run(check, frozenset(), 0.1, t0=t)
    assert not isinstance(seen, InjectedFrame) and not check.stale[3]
    assert [x.text for x in check.drain_texts()] == ["Baro readings change again: back in use"]


def test_a_stuck_mag_is_dropped_and_a_stuck_gyro_only_reported() -> None:
    check = StaleSensorCheck()
    seen, _ = _run(check, frozenset({"mag", "gyro"}), 1.0)
    assert isinstance(seen, InjectedFrame) and all(math.isnan(x) for x in seen.sensor.mag_frd_gauss)
    assert seen.sensor.gyro_frd_rad_s == (0.5, 0.0, 0.0) and not math.isnan(seen.sensor.pressure_alt_m)
    texts = {t.text.split(" ")[0]: t for t in check.drain_texts()}
    assert set(texts) == {"Gyro", "Mag"}
    assert texts["Gyro"].severity is Severity.CRITICAL and "heading from the gyro" in texts["Mag"].text


def test_nothing_is_judged_on_the_ground_and_the_clock_restarts_in_the_air() -> None:
    check = StaleSensorCheck()
    seen, t = _run(check, frozenset({"baro", "mag", "gyro", "accel"}), 3.0, in_air=False)
    assert not isinstance(seen, InjectedFrame) and not check.drain_texts()
    seen, t = _run(check, frozenset({"baro"}), 0.3, t0=t)
    assert not isinstance(seen, InjectedFrame)  # 0.3 s in the air: not stale yet
    seen, t = _run(check, frozenset({"baro"}), 0.3, t0=t)
    assert isinstance(seen, InjectedFrame)
    seen, t = _run(check, frozenset({"baro"}), 2.0, in_air=False, t0=t)  # landed, still stuck: still dropped
    assert isinstance(seen, InjectedFrame) and check.stale[3]
    seen, t = _run(check, frozenset(), 0.1, in_air=False, t0=t)  # its readings change: back, on the ground too
    assert not isinstance(seen, InjectedFrame) and not any(check.stale)
    seen, t = _run(check, frozenset({"gyro"}), 3.0, in_air=False, t0=t)  # resting: exact repeats on the ground
    seen, _ = _run(check, frozenset({"gyro"}), 0.45, t0=t)  # the clock restarted at takeoff
    assert not any(check.stale)


def test_a_dropped_nan_reading_is_not_judged() -> None:
    check = StaleSensorCheck()
    for k in range(500):
        s = _Frame(k * STEP_US, k).sensor
        frame = _Frame(k * STEP_US, k)
        frame.sensor = SensorSample(
            s.time_us, s.accel_frd_m_s2, s.gyro_frd_rad_s, s.mag_frd_gauss, math.nan, math.nan, 20.0
        )
        assert check.apply(frame, True) is frame
    assert not any(check.stale)


def _gps_frames(check: StaleSensorCheck, seconds: float, frozen: bool, t0: int = 0, in_air: bool = True):  # type: ignore[no-untyped-def]
    """Frames with a fix every 0.1 s (frozen: the same position and velocity each time); the fix frames seen."""
    fixes = []
    n = round(seconds * 1e6 / STEP_US)
    for k in range(n):
        frame = _Frame(t0 + k * STEP_US, k)
        if k % 25 == 0:
            j = 0 if frozen else k
            frame.gps = GpsSample(frame.sensor.time_us, 30.0 + 1e-7 * j, 120.0, 12.0, (0.0, 0.0, 0.0), 0.8, 1.4, 3, 12)
            fixes.append(check.apply(frame, in_air))
        else:
            check.apply(frame, in_air)
    return fixes, t0 + n * STEP_US


def test_a_frozen_gps_is_dropped_in_the_air_and_comes_back_when_its_fixes_move() -> None:
    check = StaleSensorCheck()
    fixes, _ = _gps_frames(check, 3.0, frozen=True, in_air=False)
    assert all(f.gps is not None for f in fixes) and not check.stale[GPS]  # on the ground: never judged
    check = StaleSensorCheck()
    fixes, t = _gps_frames(check, 1.0, frozen=True)
    assert fixes[4].gps is not None and all(f.gps is None for f in fixes[6:])  # 0.5 s of the same fix
    (text,) = check.drain_texts()
    assert text.text.startswith("GPS stale") and "dead reckoning" in text.text and text.severity is Severity.WARNING
    fixes, _ = _gps_frames(check, 0.5, frozen=False, t0=t)
    assert fixes[-1].gps is not None and not check.stale[GPS]
    assert [x.text for x in check.drain_texts()] == ["GPS readings change again: back in use"]
