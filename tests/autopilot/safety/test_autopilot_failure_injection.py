"""Failure injection (MAV_CMD_INJECT_FAILURE): the SYS_FAILURE_EN gate, honest refusals, each supported unit and
type on what the estimator sees (truth untouched), motor outputs, clearing, scripted injection."""

from __future__ import annotations

import math
from pathlib import Path

import pytest
from autopilot_fakes import command, make_commander

from autopilot.commander.script import ScriptError, load_script, parse_script
from autopilot.parameters.nav_decls import nav_param_specs
from autopilot.parameters.store import ParamStore
from autopilot.safety.failure_injection import SENSOR_MOTOR_OUTPUTS, SUPPORTED_FAILURES, FailureInjector, InjectedFrame
from mavlink_bridge.contract.mav_enums import FailureType, FailureUnit, MavCmd
from mavlink_bridge.contract.vehicle_api import CommandResult, Severity
from mavlink_bridge.contract.wire import GpsSample, GroundTruth, SensorSample

MOTORS = (0.5, 0.6, 0.7, 0.8)


def _injector(enabled: bool = True) -> FailureInjector:
    params = ParamStore(nav_param_specs())
    params.set("SYS_FAILURE_EN", 1.0 if enabled else 0.0)
    return FailureInjector(params)


def _inject(inj: FailureInjector, unit: float, kind: float, instance: float = 0.0) -> tuple[CommandResult, str]:
    return inj.handle_command(command(MavCmd.INJECT_FAILURE, unit, kind, instance))


class _Frame:
    """A lockstep frame (``FrameLike``) whose readings change with ``k``."""

    def __init__(self, k: int, with_gps: bool = True) -> None:
        t = 1_000_000 + 4000 * k
        self.sensor = SensorSample(
            t, (0.1 * k, 0.0, -9.8), (0.01 * k, 0.02, 0.03), (0.2, 0.01 * k, 0.4), 1013.0 - 0.01 * k, 0.1 * k, 20.0
        )
        self.gps = (
            GpsSample(t, 47.0 + 1e-6 * k, 8.0, 500.0 + k, (1.0 * k, 0.0, 0.0), 0.5, 0.8, 3, 12) if with_gps else None
        )
        self.truth = GroundTruth(
            t, (1.0, 0.0, 0.0, 0.0), (0.0, 0.0, 0.0), 47.0, 8.0, 500.0, (0.0, 0.0, 0.0), (0, 0, -9.8)
        )
        self.detections = ()


def test_refused_while_sys_failure_en_is_0_and_nothing_changes() -> None:
    inj = _injector(enabled=False)
    result, reason = _inject(inj, FailureUnit.SENSOR_GPS, FailureType.OFF)
    assert result is CommandResult.DENIED and "SYS_FAILURE_EN" in reason
    frame = _Frame(1)
    assert inj.apply_to_frame(frame) is frame and not inj.active and not inj.drain_texts()


@pytest.mark.parametrize(
    ("params", "result", "words"),
    [
        ((math.nan, 1, 0), CommandResult.DENIED, "unit must be a whole number"),
        ((4, math.nan, 0), CommandResult.DENIED, "type must be a whole number"),
        ((4, 1, math.nan), CommandResult.DENIED, "instance must be a whole number"),
        ((4.5, 1, 0), CommandResult.DENIED, "unit must be a whole number"),
        ((42, 1, 0), CommandResult.DENIED, "unknown failure unit 42"),
        ((4, 9, 0), CommandResult.DENIED, "unknown failure type 9"),
        ((FailureUnit.SENSOR_VIO, 1, 0), CommandResult.UNSUPPORTED, "SENSOR_VIO cannot fail here"),
        ((FailureUnit.SYSTEM_BATTERY, 1, 0), CommandResult.UNSUPPORTED, "SYSTEM_BATTERY cannot fail here"),
        ((FailureUnit.SENSOR_GPS, FailureType.GARBAGE, 0), CommandResult.UNSUPPORTED, "SENSOR_GPS GARBAGE"),
        ((FailureUnit.SENSOR_GYRO, FailureType.OFF, 0), CommandResult.UNSUPPORTED, "SENSOR_GYRO OFF"),
        ((FailureUnit.SYSTEM_MOTOR, FailureType.STUCK, 1), CommandResult.UNSUPPORTED, "SYSTEM_MOTOR STUCK"),
        ((FailureUnit.SYSTEM_MOTOR, FailureType.OFF, 5), CommandResult.DENIED, "motor must be 1-4 or 0"),
        ((FailureUnit.SYSTEM_MOTOR, FailureType.OFF, -1), CommandResult.DENIED, "motor must be 1-4 or 0"),
        ((FailureUnit.SENSOR_BARO, FailureType.OFF, 2), CommandResult.DENIED, "instance 0 or 1"),
    ],
)
def test_bad_or_unsupported_requests_get_an_honest_result_and_reason(
    params: tuple[float, float, float], result: CommandResult, words: str
) -> None:
    inj = _injector()
    got, reason = _inject(inj, *params)
    assert got is result and words in reason
    assert not inj.active and not inj.drain_texts()


def test_nothing_injected_passes_frames_and_motor_commands_through_unchanged() -> None:
    inj = _injector()
    frame = _Frame(3)
    assert inj.apply_to_frame(frame) is frame
    assert inj.apply_to_motors(MOTORS) is MOTORS
    assert inj.unhealthy_bits == 0 and inj.failed_motors == ()


def _seen(inj: FailureInjector, k: int, with_gps: bool = True) -> tuple[_Frame, InjectedFrame]:
    frame = _Frame(k, with_gps)
    seen = inj.apply_to_frame(frame)
    assert isinstance(seen, InjectedFrame)
    assert seen.truth is frame.truth and seen.detections is frame.detections  # the sim's truth is never touched
    assert seen.sensor.time_us == frame.sensor.time_us
    return frame, seen


def test_gps_off_drops_every_fix_and_ok_brings_it_back() -> None:
    inj = _injector()
    assert _inject(inj, FailureUnit.SENSOR_GPS, FailureType.OFF) == (CommandResult.ACCEPTED, "")
    (text,) = inj.drain_texts()
    assert text.text == "Failure injected: GPS off" and text.severity is Severity.WARNING
    frame, seen = _seen(inj, 5)
    assert seen.gps is None and seen.sensor == frame.sensor  # only the GPS is gone
    assert _inject(inj, FailureUnit.SENSOR_GPS, FailureType.OK)[0] is CommandResult.ACCEPTED
    assert [t.text for t in inj.drain_texts()] == ["Failure cleared: GPS back to normal"]
    frame = _Frame(6)
    assert inj.apply_to_frame(frame) is frame


def test_gps_stuck_repeats_the_first_fix_with_new_time_stamps() -> None:
    inj = _injector()
    _inject(inj, FailureUnit.SENSOR_GPS, FailureType.STUCK)
    first, seen1 = _seen(inj, 1)
    _, between = _seen(inj, 2, with_gps=False)
    later, seen2 = _seen(inj, 30)
    assert seen1.gps == first.gps and between.gps is None  # no fix in that frame: none invented
    assert seen2.gps is not None and first.gps is not None and later.gps is not None
    assert seen2.gps.time_us == later.gps.time_us
    assert (seen2.gps.lat_deg, seen2.gps.alt_amsl_m, seen2.gps.vel_ned_m_s) == (
        first.gps.lat_deg,
        first.gps.alt_amsl_m,
        first.gps.vel_ned_m_s,
    )


def test_baro_off_is_nan_and_baro_stuck_is_frozen() -> None:
    inj = _injector()
    _inject(inj, FailureUnit.SENSOR_BARO, FailureType.OFF)
    frame, seen = _seen(inj, 4)
    assert math.isnan(seen.sensor.abs_pressure_hpa) and math.isnan(seen.sensor.pressure_alt_m)
    assert seen.sensor.mag_frd_gauss == frame.sensor.mag_frd_gauss and seen.gps == frame.gps
    _inject(inj, FailureUnit.SENSOR_BARO, FailureType.STUCK)
    first, _ = _seen(inj, 7)
    later, s2 = _seen(inj, 70)
    assert (s2.sensor.abs_pressure_hpa, s2.sensor.pressure_alt_m) == (
        first.sensor.abs_pressure_hpa,
        first.sensor.pressure_alt_m,
    )
    assert later.sensor.pressure_alt_m != first.sensor.pressure_alt_m  # the real one moved on
    assert s2.sensor.gyro_frd_rad_s == later.sensor.gyro_frd_rad_s


def test_mag_off_is_nan_and_mag_stuck_is_frozen() -> None:
    inj = _injector()
    _inject(inj, FailureUnit.SENSOR_MAG, FailureType.OFF, 1)
    _, seen = _seen(inj, 4)
    assert all(math.isnan(v) for v in seen.sensor.mag_frd_gauss)
    _inject(inj, FailureUnit.SENSOR_MAG, FailureType.STUCK)
    first, _ = _seen(inj, 8)
    _, s2 = _seen(inj, 80)
    assert s2.sensor.mag_frd_gauss == first.sensor.mag_frd_gauss


@pytest.mark.parametrize(
    ("unit", "field"),
    [(FailureUnit.SENSOR_GYRO, "gyro_frd_rad_s"), (FailureUnit.SENSOR_ACCEL, "accel_frd_m_s2")],
)
def test_gyro_and_accel_stuck_freeze_only_that_sensor(unit: FailureUnit, field: str) -> None:
    inj = _injector()
    _inject(inj, unit, FailureType.STUCK)
    first, _ = _seen(inj, 2)
    later, s2 = _seen(inj, 50)
    assert getattr(s2.sensor, field) == getattr(first.sensor, field) != getattr(later.sensor, field)
    other = "accel_frd_m_s2" if field == "gyro_frd_rad_s" else "gyro_frd_rad_s"
    assert getattr(s2.sensor, other) == getattr(later.sensor, other)
    assert _inject(inj, unit, FailureType.OK)[0] is CommandResult.ACCEPTED
    _inject(inj, unit, FailureType.STUCK)  # stuck again: frozen at the new value, not the old one
    again, _ = _seen(inj, 60)
    _, s3 = _seen(inj, 61)
    assert getattr(s3.sensor, field) == getattr(again.sensor, field)


def test_every_supported_unit_and_type_is_accepted_and_cleared_by_ok() -> None:
    for unit, kinds in SUPPORTED_FAILURES.items():
        for kind in kinds:
            inj = _injector()
            instance = 1 if unit is FailureUnit.SYSTEM_MOTOR else 0
            assert _inject(inj, unit, kind, instance) == (CommandResult.ACCEPTED, "")
            assert inj.active
            assert _inject(inj, unit, FailureType.OK, instance) == (CommandResult.ACCEPTED, "")
            assert not inj.active, (unit, kind)
            assert len(inj.drain_texts()) == 2


def test_one_motor_off_zeroes_that_output_and_clears_the_motor_health_bit() -> None:
    inj = _injector()
    assert _inject(inj, FailureUnit.SYSTEM_MOTOR, FailureType.OFF, 2) == (CommandResult.ACCEPTED, "")
    (text,) = inj.drain_texts()
    assert "motor 2 off" in text.text and text.severity is Severity.CRITICAL
    assert inj.apply_to_motors(MOTORS) == (0.5, 0.0, 0.7, 0.8)
    assert inj.failed_motors == (2,) and inj.unhealthy_bits == SENSOR_MOTOR_OUTPUTS
    frame = _Frame(1)
    assert inj.apply_to_frame(frame) is frame  # a motor failure changes no sensor
    _inject(inj, FailureUnit.SYSTEM_MOTOR, FailureType.OK, 2)
    assert inj.apply_to_motors(MOTORS) is MOTORS and inj.unhealthy_bits == 0
    _inject(inj, FailureUnit.SYSTEM_MOTOR, FailureType.OFF, 0)
    assert inj.apply_to_motors(MOTORS) == (0.0, 0.0, 0.0, 0.0) and inj.failed_motors == (1, 2, 3, 4)
    assert "all motors off" in inj.drain_texts()[-1].text


def test_the_commander_routes_the_command_and_reports_refusals() -> None:
    commander = make_commander()
    inj = FailureInjector(commander.params)
    commander.command_handlers[MavCmd.INJECT_FAILURE] = inj.handle_command
    req = command(MavCmd.INJECT_FAILURE, FailureUnit.SENSOR_GPS, FailureType.OFF, 0)
    assert commander.handle_command(req) is CommandResult.DENIED
    assert "SYS_FAILURE_EN" in commander.last_reason
    assert any("SYS_FAILURE_EN" in t.text for t in commander.drain_texts())
    commander.params.set("SYS_FAILURE_EN", 1.0)
    assert commander.handle_command(req) is CommandResult.ACCEPTED and inj.sensor_failures == {
        FailureUnit.SENSOR_GPS: FailureType.OFF
    }
    inf = command(MavCmd.INJECT_FAILURE, math.inf, FailureType.OFF, 0)
    assert commander.handle_command(inf) is CommandResult.DENIED and "infinite" in commander.last_reason
    del commander.command_handlers[MavCmd.INJECT_FAILURE]  # nothing wired: the commander's own path refuses it
    assert commander.handle_command(req) is not CommandResult.ACCEPTED


def test_script_schedules_failures_by_name_or_number(tmp_path: Path) -> None:
    steps = parse_script(
        [
            {"at_s": 30, "cmd": "inject_failure", "unit": "gps", "type": "off"},
            {"at_s": 31, "cmd": "inject_failure", "unit": "MOTOR", "type": "off", "instance": 2},
            {"at_s": 32, "cmd": "inject_failure", "unit": 3, "type": 2},
        ]
    )
    requests = [s.request() for s in steps]
    assert all(r is not None and r.command == MavCmd.INJECT_FAILURE for r in requests)
    assert [r.params[:3] for r in requests if r is not None] == [(4.0, 1.0, 0.0), (101.0, 1.0, 2.0), (3.0, 2.0, 0.0)]
    yaml_text = tmp_path / "script.yaml"  # YAML reads an unquoted `off` as false: still OFF
    yaml_text.write_text("- {at_s: 12, cmd: inject_failure, unit: motor, type: off, instance: 1}\n")
    (step,) = load_script(yaml_text)
    assert step.args == (101.0, 1.0, 1.0)
    yaml_text.write_text("- {at_s: 12, cmd: inject_failure, unit: gps, type: on}\n")
    with pytest.raises(ScriptError, match="type must be a number or a name, got True"):
        load_script(yaml_text)
    with pytest.raises(ScriptError, match="unit must be a number or one of"):
        parse_script([{"at_s": 1, "cmd": "inject_failure", "unit": "lidar", "type": "off"}])
    with pytest.raises(ScriptError, match="missing type"):
        parse_script([{"at_s": 1, "cmd": "inject_failure", "unit": "gps"}])
    with pytest.raises(ScriptError, match="finite"):
        parse_script([{"at_s": 1, "cmd": "inject_failure", "unit": "gps", "type": "off", "instance": math.nan}])
