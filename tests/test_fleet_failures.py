"""Per-vehicle failures in a fleet world (``vehicles[i].failures``): the world's ``failures:`` go to every vehicle,
an entry's own to that vehicle alone, merged by time; the simulator and the autopilot read one schedule per vehicle,
bad entries are one FILE:LINE line, and ``quadsitl up`` hands each autopilot its own."""

from __future__ import annotations

from pathlib import Path

import pytest

from autopilot import cli as autopilot_cli
from autopilot.commander.script import ScriptError, failure_steps, load_world_failures
from autopilot.launch_commands import commands
from autopilot.launch_plan import plan_launch
from autopilot.launcher import build_parser
from autopilot.mission.files import load_fleet_missions
from mavlink_bridge.contract.failure_schedule import ScheduledFailure, vehicle_failures
from mavlink_bridge.contract.mav_enums import FailureType, FailureUnit
from mavlink_bridge.contract.source_lines import read_yaml
from sim.fleet_world import load_fleet
from sim.world import WorldConfigError

FLEET = """\
name: pair
home: {lat_deg: 47.3977, lon_deg: 8.5456, alt_m: 488}
world:
  failures:
    - {at_s: 40, inject: mag_off}
vehicles:
  - name: alpha
    home: {north_m: 0, east_m: 0}
    mission: [{takeoff: {alt_m: 10}}]
    failures:
      - {at_s: 40, inject: gps_off}
      - {at_s: 12, inject: motor_off, motor: 2}
  - name: bravo
    home: {north_m: 0, east_m: 8}
    mission: [{takeoff: {alt_m: 10}}]
"""
MOTOR_2_OFF = ScheduledFailure(12.0, FailureUnit.SYSTEM_MOTOR, FailureType.OFF, 2)
MAG_OFF = ScheduledFailure(40.0, FailureUnit.SENSOR_MAG, FailureType.OFF, 0)
GPS_OFF = ScheduledFailure(40.0, FailureUnit.SENSOR_GPS, FailureType.OFF, 0)


def _write(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "fleet.yaml"
    path.write_text(text)
    return path


def test_each_vehicle_gets_the_worlds_failures_and_its_own_merged_by_time(tmp_path: Path) -> None:
    path = _write(tmp_path, FLEET)
    fleet = load_fleet(path)  # the simulator's side (and the in-process fleet's)
    assert fleet.world_failures == (MAG_OFF,)
    assert fleet.vehicles[0].failures == (MOTOR_2_OFF, GPS_OFF) and fleet.vehicles[1].failures == ()
    assert fleet.failures_of(0) == (MOTOR_2_OFF, MAG_OFF, GPS_OFF)  # the world's first at a tie
    assert fleet.failures_of(1) == (MAG_OFF,)
    doc = read_yaml(path).data
    assert [vehicle_failures(doc, i) for i in (0, 1)] == [fleet.failures_of(0), fleet.failures_of(1)]
    # the autopilot's side: the same schedule, as script steps
    assert load_world_failures(path, "alpha") == failure_steps(fleet.failures_of(0))
    assert load_world_failures(path, "bravo") == failure_steps((MAG_OFF,))
    # the fleet ground station's mission reader takes the key (and leaves it to the autopilot)
    assert [p.name for p in load_fleet_missions(path)] == ["alpha", "bravo"]


@pytest.mark.parametrize(
    ("entry", "says"),
    [
        ("{at_s: 12, inject: motor_of, motor: 2}", "did you mean 'motor_off'"),
        ("{at_s: 12, inject: motor_off, motor: 9}", "motor number 1-4"),
        ("{at_s: -3, inject: gps_off}", "expected sim seconds"),
        ("{at_s: 12, inject: gps_off, when: 2}", "unknown field"),
    ],
)
def test_a_bad_vehicle_entry_is_one_line_naming_the_file_line_and_the_vehicle(
    tmp_path: Path, entry: str, says: str
) -> None:
    text = FLEET.replace("{at_s: 12, inject: motor_off, motor: 2}", entry)
    path = _write(tmp_path, text)
    line = text.splitlines().index(f"      - {entry}") + 1
    with pytest.raises(WorldConfigError) as sim_error:
        load_fleet(path)
    with pytest.raises(ScriptError) as autopilot_error:
        load_world_failures(path, "alpha")
    for message in (str(sim_error.value), str(autopilot_error.value)):
        assert message.startswith(f"{path}:{line}: vehicles[0].failures[1]"), message
        assert says in message and "\n" not in message
    assert load_world_failures(path, "bravo") == failure_steps((MAG_OFF,))  # bravo's own schedule is fine


def test_a_vehicles_failures_are_never_dropped_unsaid(tmp_path: Path) -> None:
    path = _write(tmp_path, FLEET)
    with pytest.raises(ScriptError, match=r"fleet\.yaml:\d+: vehicles\[0\]\.failures: .*fix: --fleet-vehicle NAME"):
        load_world_failures(path)  # which vehicle does this autopilot fly?
    with pytest.raises(ScriptError, match=r"no vehicle named 'alpa'; fix: did you mean 'alpha'\?"):
        load_world_failures(path, "alpa")
    no_own = _write(tmp_path, FLEET.replace("    failures:\n      - {at_s: 40, inject: gps_off}\n", "").replace(
        "      - {at_s: 12, inject: motor_off, motor: 2}\n", ""))  # fmt: skip
    assert load_world_failures(no_own) == failure_steps((MAG_OFF,))  # as before: the world's, for every vehicle
    assert autopilot_cli.main(["--fleet-vehicle", "alpha"]) == 2  # a name without a file: usage error


def test_quadsitl_up_gives_each_autopilot_its_own_failures(tmp_path: Path) -> None:
    path = _write(tmp_path, FLEET)
    args = build_parser().parse_args(["--world", str(path), "--instance", "3000", "--rerun", "off"])
    _, autopilots = commands(args, plan_launch(args))
    injected = []
    for cmd in autopilots:
        ap = autopilot_cli.build_parser().parse_args(cmd[cmd.index("autopilot") + 1 :])
        assert ap.world_failures == str(path)
        injected.append(load_world_failures(ap.world_failures, ap.fleet_vehicle))
    assert injected == [failure_steps((MOTOR_2_OFF, MAG_OFF, GPS_OFF)), failure_steps((MAG_OFF,))]
