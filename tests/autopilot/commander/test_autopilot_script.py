"""Scripted commands: parsing with clear errors, due steps in sim-time order, each once."""

from __future__ import annotations

import math

import pytest

from autopilot.commander.script import CommandScript, ScriptError, parse_script


def test_steps_sorted_and_handed_out_once_when_due() -> None:
    steps = parse_script(
        [
            {"at_s": 2.0, "cmd": "land"},
            {"at_s": 0.5, "cmd": "arm"},
            {"at_s": 1.0, "cmd": "takeoff", "alt_m": 12},
            {"at_s": 1.5, "cmd": "goto", "north_m": 3, "east_m": -4, "alt_m": 8},
        ]
    )
    script = CommandScript(steps)
    assert script.due(400_000) == []
    assert [s.cmd for s in script.due(1_000_000)] == ["arm", "takeoff"]
    assert script.due(1_000_000) == []
    assert [s.cmd for s in script.due(5_000_000)] == ["goto", "land"]
    assert script.finished
    takeoff = steps[1].request()
    assert takeoff is not None and takeoff.command == 22 and takeoff.params[6] == 12.0
    assert takeoff.is_int and takeoff.frame == 6  # altitude relative to home
    assert steps[2].request() is None and steps[2].args == (3.0, -4.0, 8.0)
    land = steps[3].request()
    assert land is not None and land.command == 21 and math.isnan(land.params[4])


@pytest.mark.parametrize(
    ("entries", "message"),
    [
        ({"at_s": 1}, "expected a list"),
        ([{"at_s": 1, "cmd": "fly"}], "cmd must be one of"),
        ([{"at_s": 1, "cmd": "takeoff"}], "missing alt_m"),
        ([{"at_s": 1, "cmd": "arm", "alt_m": 3}], "unknown keys"),
        ([{"at_s": -1, "cmd": "arm"}], "at_s >= 0"),
        ([{"at_s": "soon", "cmd": "arm"}], "must be numbers"),
    ],
)
def test_bad_scripts_are_refused_with_the_step_named(entries: object, message: str) -> None:
    with pytest.raises(ScriptError, match=message):
        parse_script(entries, "f.yaml")
