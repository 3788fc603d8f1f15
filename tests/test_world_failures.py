"""Failures scheduled from the world file (``world: failures:``, issue 22 item 5): parsed with the world (FILE:LINE
on a bad entry), run by the autopilot as the ``--script``'s ``inject_failure`` steps, at their sim times."""

from __future__ import annotations

import math
from pathlib import Path

import pytest
from autopilot_loop import SimLoop

from autopilot.commander.script import CommandScript, ScriptError, load_script, load_world_failures, merged
from autopilot.safety.failure_injection import SUPPORTED_FAILURES
from mavlink_bridge.contract.failure_schedule import INJECTIONS, ScheduledFailure
from mavlink_bridge.contract.mav_enums import FailureType, FailureUnit
from sim.world import WorldConfigError, load_world

MISSION = """\
name: failures
home: {lat_deg: 30.2635, lon_deg: 120.1233, alt_m: 12.0}
vehicle: x500
mission:
  - takeoff: {alt_m: 10}
world:
  wind: {north_m_s: 1.0}
  failures:
    - {at_s: 40, inject: gps_off}
    - {at_s: 30, inject: motor_off, motor: 2}
    - {at_s: 43.5, inject: gps_ok}
"""


def _write(tmp_path: Path, text: str, name: str = "world.yaml") -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


def test_the_world_carries_its_failures_sorted_by_time(tmp_path: Path) -> None:
    world = load_world(_write(tmp_path, MISSION))
    assert world.failures == (
        ScheduledFailure(30.0, FailureUnit.SYSTEM_MOTOR, FailureType.OFF, 2),
        ScheduledFailure(40.0, FailureUnit.SENSOR_GPS, FailureType.OFF, 0),
        ScheduledFailure(43.5, FailureUnit.SENSOR_GPS, FailureType.OK, 0),
    )
    assert [f.inject for f in world.failures] == ["motor_off", "gps_off", "gps_ok"]
    bare = load_world(_write(tmp_path, "failures: [{at_s: 5, inject: baro_stuck}]\n", "bare.yaml"))
    assert bare.failures == (ScheduledFailure(5.0, FailureUnit.SENSOR_BARO, FailureType.STUCK, 0),)
    assert load_world(_write(tmp_path, "wind: {north_m_s: 1.0}\n", "none.yaml")).failures == ()


@pytest.mark.parametrize(
    ("entry", "line_key", "says"),
    [
        ("{at_s: 40, inject: gps_of}", "inject", "did you mean 'gps_off'"),
        ("{at_s: -1, inject: gps_off}", "at_s", "expected sim seconds"),
        ("{at_s: 40, inject: gps_off, motor: 2}", "motor", "only motor_off and motor_ok take a motor"),
        ("{at_s: 40, inject: motor_off, motor: 7}", "motor", "motor number 1-4"),
        ("{at_s: 40, inject: gps_off, when: 3}", "when", "unknown field"),
        ("{inject: gps_off}", None, "missing at_s"),
    ],
)
def test_a_bad_entry_is_one_line_naming_the_file_line_and_the_fix(
    tmp_path: Path, entry: str, line_key: str | None, says: str
) -> None:
    text = MISSION.replace("{at_s: 43.5, inject: gps_ok}", entry)
    path = _write(tmp_path, text)
    line = text.splitlines().index(f"    - {entry}") + 1
    with pytest.raises(WorldConfigError) as sim_error:
        load_world(path)
    with pytest.raises(ScriptError) as autopilot_error:
        load_world_failures(path)
    for message in (str(sim_error.value), str(autopilot_error.value)):
        assert message.startswith(f"{path}:{line}: world.failures[2]") and says in message and "\n" not in message
    assert line_key is None or f"failures[2].{line_key}" in str(sim_error.value)


def test_every_world_injection_is_one_the_autopilot_supports() -> None:
    for name, (unit, kind) in INJECTIONS.items():
        assert kind is FailureType.OK or kind in SUPPORTED_FAILURES[unit], name
        assert name == f"{unit.name.split('_', 1)[1].lower()}_{kind.name.lower()}"  # --script's unit and type names
    assert {unit for unit, _ in INJECTIONS.values()} == set(SUPPORTED_FAILURES)


def test_world_failures_merge_with_the_script_and_run_at_their_sim_times(tmp_path: Path) -> None:
    world_path = _write(tmp_path, MISSION.replace("at_s: 40, inject: gps_off", "at_s: 1.0, inject: baro_off"))
    script = _write(tmp_path, "- {at_s: 0.5, cmd: hold}\n", "script.yaml")
    steps = merged(load_script(script), load_world_failures(world_path))
    assert [(s.at_us, s.cmd) for s in steps][:2] == [(500_000, "hold"), (1_000_000, "inject_failure")]
    loop = SimLoop("x500", script=CommandScript(steps))
    loop.ap.params.set("SYS_FAILURE_EN", 1.0)
    loop.run_s(0.95)
    assert not any("baro off" in t for t in loop.texts)
    loop.run_s(0.1)
    assert "Script inject_failure: ACCEPTED" in loop.texts and "Failure injected: baro off" in loop.texts
    seen = loop.ap.failures.apply_to_frame(loop.frame())
    assert math.isnan(seen.sensor.pressure_alt_m)
