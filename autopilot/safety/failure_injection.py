"""Injected sensor and motor failures, PX4's way (MAV_CMD_INJECT_FAILURE 420, SPEC §5b).

:class:`FailureInjector` is a pure class between the lockstep frame and the estimator, and between the
cascade's motor commands and the answer: the simulator's truth is never touched, only what the autopilot
sees and sends. A command (``handle_command``; also scheduled from a ``--script`` file) is refused with a
reason while ``SYS_FAILURE_EN`` is 0, as in PX4.

Supported (``SUPPORTED_FAILURES``), ``FailureType.OK`` clears a unit (a motor instance, 0 = all):

- GPS OFF: no ``GpsSample`` reaches the estimator. GPS STUCK: every new fix repeats the one at injection
  (position, velocity, quality), with the new time stamp.
- Baro OFF: pressure and pressure altitude are NaN (the sample carries no reading: HIL_SENSOR's
  ``fields_updated`` bit is not on the wire contract, so a non-finite value is "no sample"). Baro STUCK:
  frozen at the first reading after injection.
- Mag OFF: the field vector is NaN. Mag STUCK: frozen (body frame) at the first reading after injection.
- Gyro / accel STUCK: frozen at the first reading after injection (the IMU clocks the estimator's
  prediction, so it is never removed).
- Motor OFF (instance 1-4, PX4 quad-x order, 0 = all): that output is 0 (PX4 SITL's motor failure).

While nothing is injected, ``apply_to_frame`` and ``apply_to_motors`` return their argument (no allocation).
Every injection and clearance is a :class:`StatusText` (``drain_texts``).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, replace

from autopilot.estimation.state import FrameLike
from autopilot.parameters.store import ParamStore
from mavlink_bridge.contract.mav_enums import FailureType, FailureUnit
from mavlink_bridge.contract.vehicle_api import CommandRequest, CommandResult, Severity, StatusText
from mavlink_bridge.contract.wire import (
    MOTOR_CHANNELS,
    GpsSample,
    GroundTruth,
    ObstacleDetection,
    SensorSample,
    Vec3,
)

#: Failure types each unit supports (besides OK, which clears it).
SUPPORTED_FAILURES: dict[FailureUnit, frozenset[FailureType]] = {
    FailureUnit.SENSOR_GYRO: frozenset({FailureType.STUCK}),
    FailureUnit.SENSOR_ACCEL: frozenset({FailureType.STUCK}),
    FailureUnit.SENSOR_MAG: frozenset({FailureType.OFF, FailureType.STUCK}),
    FailureUnit.SENSOR_BARO: frozenset({FailureType.OFF, FailureType.STUCK}),
    FailureUnit.SENSOR_GPS: frozenset({FailureType.OFF, FailureType.STUCK}),
    FailureUnit.SYSTEM_MOTOR: frozenset({FailureType.OFF}),
}
#: MAV_SYS_STATUS_SENSOR_MOTOR_OUTPUTS: cleared from SYS_STATUS health while a motor has failed.
SENSOR_MOTOR_OUTPUTS = 0x8000
MOTOR_COUNT = len(MOTOR_CHANNELS)
_NAN3: Vec3 = (math.nan, math.nan, math.nan)
_NO_TEXTS: tuple[StatusText, ...] = ()
_UNIT_TEXT = {
    FailureUnit.SENSOR_GYRO: "gyro",
    FailureUnit.SENSOR_ACCEL: "accel",
    FailureUnit.SENSOR_MAG: "mag",
    FailureUnit.SENSOR_BARO: "baro",
    FailureUnit.SENSOR_GPS: "GPS",
}


@dataclass(frozen=True, slots=True)
class InjectedFrame:
    """A lockstep frame as the estimator sees it under an injected failure (truth and detections unchanged)."""

    sensor: SensorSample
    gps: GpsSample | None
    truth: GroundTruth | None
    detections: tuple[ObstacleDetection, ...] = ()


def _whole(value: float) -> bool:
    return math.isfinite(value) and value == math.floor(value)


class FailureInjector:
    """Active sensor failures (one per unit) and failed motors; see the module docstring."""

    def __init__(self, params: ParamStore) -> None:
        self._params = params
        self._sensors: dict[FailureUnit, FailureType] = {}
        self._held: dict[FailureUnit, object] = {}  # STUCK values, taken at the first frame after injection
        self._motor_off = [False] * MOTOR_COUNT
        self._any_motor_off = False
        self._texts: list[StatusText] = []

    # ------------------------------------------------------------------ state
    @property
    def active(self) -> bool:
        """Any failure injected (sensor or motor)."""
        return bool(self._sensors) or self._any_motor_off

    @property
    def sensor_failures(self) -> dict[FailureUnit, FailureType]:
        """The injected sensor failures (a copy)."""
        return dict(self._sensors)

    @property
    def failed_motors(self) -> tuple[int, ...]:
        """Motor numbers (1-based, PX4 quad-x order) that are off."""
        return tuple(i + 1 for i, off in enumerate(self._motor_off) if off)

    @property
    def unhealthy_bits(self) -> int:
        """MAV_SYS_STATUS_SENSOR bits to clear from SYS_STATUS health (motor outputs while a motor is off)."""
        return SENSOR_MOTOR_OUTPUTS if self._any_motor_off else 0

    def drain_texts(self) -> Sequence[StatusText]:
        """Injection and clearance events since the last call (a shared empty tuple when none: no allocation)."""
        if not self._texts:
            return _NO_TEXTS
        out, self._texts = self._texts, []
        return out

    def _say(self, text: str, severity: Severity) -> None:
        self._texts.append(StatusText(severity, text))

    # ------------------------------------------------------------------ the command
    def handle_command(self, request: CommandRequest) -> tuple[CommandResult, str]:
        """MAV_CMD_INJECT_FAILURE: (result, reason); the reason is "" when accepted."""
        if self._params.get("SYS_FAILURE_EN") < 0.5:
            return CommandResult.DENIED, "INJECT_FAILURE: failure injection is disabled (set SYS_FAILURE_EN to 1)"
        p = request.params
        for name, value in (("unit", p[0]), ("type", p[1]), ("instance", p[2])):
            if not _whole(value):
                return CommandResult.DENIED, f"INJECT_FAILURE: failure {name} must be a whole number, got {value:g}"
        try:
            unit = FailureUnit(int(p[0]))
        except ValueError:
            return CommandResult.DENIED, f"INJECT_FAILURE: unknown failure unit {int(p[0])}"
        try:
            kind = FailureType(int(p[1]))
        except ValueError:
            return CommandResult.DENIED, f"INJECT_FAILURE: unknown failure type {int(p[1])}"
        supported = SUPPORTED_FAILURES.get(unit)
        if supported is None:
            units = ", ".join(u.name for u in SUPPORTED_FAILURES)
            return CommandResult.UNSUPPORTED, f"INJECT_FAILURE: {unit.name} cannot fail here (supported: {units})"
        if kind is not FailureType.OK and kind not in supported:
            kinds = ", ".join(sorted(k.name for k in supported))
            return CommandResult.UNSUPPORTED, f"INJECT_FAILURE: {unit.name} {kind.name} is not supported ({kinds}, OK)"
        instance = int(p[2])
        if unit is FailureUnit.SYSTEM_MOTOR:
            if not 0 <= instance <= MOTOR_COUNT:
                return CommandResult.DENIED, f"INJECT_FAILURE: motor must be 1-{MOTOR_COUNT} or 0 (all), got {instance}"
            self._set_motors(instance, kind is FailureType.OFF)
        else:
            if instance not in (0, 1):
                return CommandResult.DENIED, f"INJECT_FAILURE: one {unit.name} here (instance 0 or 1), got {instance}"
            self._set_sensor(unit, kind)
        return CommandResult.ACCEPTED, ""

    def _set_sensor(self, unit: FailureUnit, kind: FailureType) -> None:
        self._held.pop(unit, None)
        name = _UNIT_TEXT[unit]
        if kind is FailureType.OK:
            if self._sensors.pop(unit, None) is not None:
                self._say(f"Failure cleared: {name} back to normal", Severity.NOTICE)
            return
        self._sensors[unit] = kind
        self._say(f"Failure injected: {name} {kind.name.lower()}", Severity.WARNING)

    def _set_motors(self, instance: int, off: bool) -> None:
        numbers = range(1, MOTOR_COUNT + 1) if instance == 0 else (instance,)
        changed = [n for n in numbers if self._motor_off[n - 1] is not off]
        for n in numbers:
            self._motor_off[n - 1] = off
        self._any_motor_off = any(self._motor_off)
        if not changed:
            return
        which = "all motors" if len(changed) == MOTOR_COUNT else ", ".join(f"motor {n}" for n in changed)
        if off:
            self._say(f"Failure injected: {which} off (motor output failed)", Severity.CRITICAL)
        else:
            self._say(f"Failure cleared: {which} back to normal", Severity.NOTICE)

    # ------------------------------------------------------------------ per step
    def _hold(self, unit: FailureUnit, value: object) -> object:
        """The value frozen for ``unit`` (``value`` the first time)."""
        held = self._held.get(unit)
        if held is None:
            held = self._held[unit] = value
        return held

    def apply_to_frame(self, frame: FrameLike) -> FrameLike:
        """What the estimator sees of ``frame``: ``frame`` itself while no sensor has failed."""
        failures = self._sensors
        if not failures:
            return frame
        s = frame.sensor
        gyro, accel, mag = s.gyro_frd_rad_s, s.accel_frd_m_s2, s.mag_frd_gauss
        pressure_hpa, pressure_alt_m = s.abs_pressure_hpa, s.pressure_alt_m
        if failures.get(FailureUnit.SENSOR_GYRO) is FailureType.STUCK:
            gyro = self._hold(FailureUnit.SENSOR_GYRO, gyro)  # type: ignore[assignment]
        if failures.get(FailureUnit.SENSOR_ACCEL) is FailureType.STUCK:
            accel = self._hold(FailureUnit.SENSOR_ACCEL, accel)  # type: ignore[assignment]
        mag_failure = failures.get(FailureUnit.SENSOR_MAG)
        if mag_failure is FailureType.OFF:
            mag = _NAN3
        elif mag_failure is FailureType.STUCK:
            mag = self._hold(FailureUnit.SENSOR_MAG, mag)  # type: ignore[assignment]
        baro_failure = failures.get(FailureUnit.SENSOR_BARO)
        if baro_failure is FailureType.OFF:
            pressure_hpa = pressure_alt_m = math.nan
        elif baro_failure is FailureType.STUCK:
            pressure_hpa, pressure_alt_m = self._hold(FailureUnit.SENSOR_BARO, (pressure_hpa, pressure_alt_m))  # type: ignore[misc]
        gps = frame.gps
        gps_failure = failures.get(FailureUnit.SENSOR_GPS)
        if gps_failure is FailureType.OFF:
            gps = None
        elif gps_failure is FailureType.STUCK and gps is not None:
            held: GpsSample = self._hold(FailureUnit.SENSOR_GPS, gps)  # type: ignore[assignment]
            gps = held if held is gps else replace(held, time_us=gps.time_us)
        sensor = SensorSample(s.time_us, accel, gyro, mag, pressure_hpa, pressure_alt_m, s.temperature_degc)
        return InjectedFrame(sensor, gps, frame.truth, getattr(frame, "detections", ()))

    def apply_to_motors(self, motor_cmd: tuple[float, float, float, float]) -> tuple[float, float, float, float]:
        """The motor commands sent to the sim: a failed motor's output is 0; ``motor_cmd`` itself otherwise."""
        if not self._any_motor_off:
            return motor_cmd
        off = self._motor_off
        m0, m1, m2, m3 = motor_cmd
        return (0.0 if off[0] else m0, 0.0 if off[1] else m1, 0.0 if off[2] else m2, 0.0 if off[3] else m3)
