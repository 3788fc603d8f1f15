"""Commands at fixed sim times (``quadsitl autopilot --script FILE``): deterministic flights without a GCS.

GCS commands arrive at whatever sim time the wall clock lets them, so two runs differ. A
script makes a flight a function of the seed only (the determinism and lossy-link tests,
the lockstep benchmark). The YAML file is a list of steps, each ``at_s`` (sim seconds) plus
one command; altitudes are metres above home, positions metres north/east of home::

    - {at_s: 0.5, cmd: arm}
    - {at_s: 1.0, cmd: takeoff, alt_m: 10}
    - {at_s: 12.0, cmd: goto, north_m: 20, east_m: 5, alt_m: 10}
    - {at_s: 25.0, cmd: land}

Commands: ``arm``, ``disarm``, ``takeoff`` (alt_m), ``land``, ``rtl``, ``mission_start``, ``hold``,
``goto`` (north_m, east_m, alt_m), ``inject_failure`` (unit, type, optional instance: MAV_CMD_INJECT_FAILURE,
``SYS_FAILURE_EN`` must be 1). Each runs through the same commander path as a GCS command. Failure units and
types are FAILURE_UNIT / FAILURE_TYPE names without their prefix (``gps``, ``baro``, ``mag``, ``gyro``,
``accel``, ``motor``; ``off``, ``stuck``, ``ok``) or their numbers; a motor instance is 1-based, 0 = all::

    - {at_s: 30, cmd: inject_failure, unit: gps, type: off}
    - {at_s: 32, cmd: inject_failure, unit: motor, type: off, instance: 2}

A mission's or world's ``world: failures:`` (``--world-failures FILE``; :mod:`mavlink_bridge.contract.failure_schedule`)
become the same ``inject_failure`` steps (:func:`failure_steps`), merged with the script by time; in a fleet world,
``--fleet-vehicle NAME`` adds that ``vehicles:`` entry's own ``failures:``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from mavlink_bridge.contract.failure_schedule import (
    FailureScheduleError,
    ScheduledFailure,
    mission_failures,
    vehicle_entries,
    vehicle_failures,
    vehicle_index,
)
from mavlink_bridge.contract.mav_enums import FailureType, FailureUnit, MavCmd
from mavlink_bridge.contract.source_lines import YamlSource, YamlSyntaxError, did_you_mean, read_yaml
from mavlink_bridge.contract.vehicle_api import CommandRequest

_ARGS = {
    "arm": (),
    "disarm": (),
    "takeoff": ("alt_m",),
    "land": (),
    "rtl": (),
    "mission_start": (),
    "hold": (),
    "goto": ("north_m", "east_m", "alt_m"),
    "inject_failure": ("unit", "type", "instance"),
}
#: Arguments that may be left out, with their value.
_OPTIONAL = {"instance": 0.0}
#: Arguments that may be given by name: ``gps`` for FailureUnit.SENSOR_GPS, ``off`` for FailureType.OFF.
_NAMED: dict[str, dict[str, int]] = {
    "unit": {unit.name.split("_", 1)[1].lower(): int(unit) for unit in FailureUnit},
    "type": {kind.name.lower(): int(kind) for kind in FailureType},
}
_GLOBAL_RELATIVE_ALT_INT = 6


class ScriptError(ValueError):
    """A script file that cannot run; the message names the step and the problem."""


@dataclass(frozen=True, slots=True)
class ScriptStep:
    """One command at ``at_us`` of sim time; ``args`` are the command's numbers in ``_ARGS`` order."""

    at_us: int
    cmd: str
    args: tuple[float, ...] = ()

    def request(self) -> CommandRequest | None:
        """The MAVLink command this step sends (None for ``goto``, which the commander takes directly)."""
        nan = math.nan
        params: tuple[float, ...] | None = {
            "arm": (1.0, 0.0),
            "disarm": (0.0, 0.0),
            "takeoff": (0.0, 0.0, 0.0, nan, nan, nan, *self.args),
            "land": (0.0, 0.0, 0.0, nan, nan, nan, nan),
            "rtl": (),
            "mission_start": (0.0, 0.0),
            "hold": (1.0, 4.0, 3.0),
            "inject_failure": self.args,
        }.get(self.cmd)
        number = {"arm": 400, "disarm": 400, "takeoff": 22, "land": 21, "rtl": 20, "mission_start": 300, "hold": 176}
        number["inject_failure"] = MavCmd.INJECT_FAILURE
        if params is None:
            return None
        full = (*params, *([0.0] * (7 - len(params))))
        return CommandRequest(number[self.cmd], full, 0, 0, is_int=True, frame=_GLOBAL_RELATIVE_ALT_INT)  # type: ignore[arg-type]


def parse_script(entries: object, origin: str = "<script>", source: YamlSource | None = None) -> list[ScriptStep]:
    """Validate a list of ``{at_s, cmd, ...}`` mappings into steps sorted by time.

    ``source`` (the parsed file) adds the line to each message: ``FILE:LINE: step N: ...; fix: ...``.
    """

    def place(*path: str | int) -> str:
        return source.where(*path) if source is not None else origin

    if not isinstance(entries, list):
        raise ScriptError(f"{place()}: expected a list of steps; fix: write '- {{at_s: 5, cmd: takeoff, alt_m: 10}}'")
    steps = []
    for i, entry in enumerate(entries):
        where = f"{place(i)}: step {i}"
        if not isinstance(entry, dict):
            raise ScriptError(f"{where}: expected a mapping with at_s and cmd; fix: write '- {{at_s: 5, cmd: arm}}'")
        cmd = entry.get("cmd")
        if cmd not in _ARGS:
            where = f"{place(i, 'cmd')}: step {i}"
            fix = did_you_mean(cmd, sorted(_ARGS))
            raise ScriptError(f"{where}: cmd must be one of {sorted(_ARGS)}, got {cmd!r}; fix: {fix}")
        unknown = sorted(str(k) for k in set(entry) - {"at_s", "cmd", *_ARGS[cmd]})
        if unknown:
            fix = f"{cmd} takes at_s{''.join(', ' + a for a in _ARGS[cmd])}"
            raise ScriptError(f"{place(i, unknown[0])}: step {i}: unknown keys {unknown} for {cmd}; fix: {fix}")
        try:
            at_s = float(entry["at_s"])
            args = tuple(_argument(entry, k, where) for k in _ARGS[cmd])
        except ScriptError:
            raise
        except KeyError as exc:
            raise ScriptError(f"{where}: missing {exc.args[0]}; fix: add '{exc.args[0]}: <number>'") from None
        except (TypeError, ValueError):
            raise ScriptError(f"{where}: at_s and the arguments must be numbers; fix: write plain numbers") from None
        if not (math.isfinite(at_s) and at_s >= 0.0) or not all(math.isfinite(a) for a in args):
            raise ScriptError(f"{where}: times and arguments must be finite, at_s >= 0; fix: use finite numbers")
        steps.append(ScriptStep(round(at_s * 1e6), cmd, args))
    return sorted(steps, key=lambda s: s.at_us)


def _argument(entry: dict[object, object], key: str, where: str) -> float:
    """The number of ``entry[key]`` (a name where ``_NAMED`` allows one; ``_OPTIONAL`` when absent)."""
    if key not in entry and key in _OPTIONAL:
        return _OPTIONAL[key]
    value = entry[key]
    if isinstance(value, bool):  # YAML 1.1 reads an unquoted off/no as false, on/yes as true
        if key == "type" and value is False:
            return float(FailureType.OFF)
        named = " or a name" if key in _NAMED else ""
        raise ScriptError(f"{where}: {key} must be a number{named}, got {value!r}; fix: write a number{named}")
    names = _NAMED.get(key)
    if names is not None and isinstance(value, str):
        if value.lower() not in names:
            fix = did_you_mean(value.lower(), sorted(names))
            raise ScriptError(f"{where}: {key} must be a number or one of {sorted(names)}, got {value!r}; fix: {fix}")
        return float(names[value.lower()])
    return float(value)  # type: ignore[arg-type]


def load_script(path: str | Path) -> list[ScriptStep]:
    """Read a script YAML file (ScriptError on any problem)."""
    try:
        source = read_yaml(path)
    except OSError as exc:
        raise ScriptError(f"{path}: cannot read: {exc.strerror}; fix: check the path given to --script") from None
    except YamlSyntaxError as exc:
        raise ScriptError(str(exc)) from None
    return parse_script(source.data, str(path), source)


def failure_steps(failures: Sequence[ScheduledFailure]) -> list[ScriptStep]:
    """The ``inject_failure`` steps of scheduled failures (the world file's ``failures:``)."""
    return [
        ScriptStep(round(f.at_s * 1e6), "inject_failure", (float(f.unit), float(f.kind), float(f.instance)))
        for f in failures
    ]


def load_world_failures(path: str | Path, vehicle: str | None = None) -> list[ScriptStep]:
    """The ``world: failures:`` of a mission or bare world file as script steps (ScriptError FILE:LINE); in a fleet
    world, ``vehicle`` (a ``vehicles:`` name) adds that vehicle's own ``failures:``, merged by time. A fleet world
    whose vehicles schedule their own failures needs ``vehicle`` (no vehicle's failures are dropped unsaid)."""
    try:
        source = read_yaml(path)
    except OSError as exc:
        raise ScriptError(
            f"{path}: cannot read: {exc.strerror}; fix: check the path given to --world-failures"
        ) from None
    except YamlSyntaxError as exc:
        raise ScriptError(str(exc)) from None
    try:
        if vehicle is not None:
            return failure_steps(vehicle_failures(source.data, vehicle_index(source.data, vehicle)))
        for i, entry in enumerate(vehicle_entries(source.data)):
            if isinstance(entry, dict) and entry.get("failures"):
                raise FailureScheduleError(
                    ("vehicles", i, "failures"),
                    f"vehicle {entry.get('name')!r} schedules its own failures and this autopilot flies no named "
                    "vehicle; fix: --fleet-vehicle NAME (quadsitl up passes it)",
                )
        return failure_steps(mission_failures(source.data))
    except FailureScheduleError as exc:
        raise ScriptError(f"{source.where(*exc.node)}: {exc}") from None


def merged(*step_lists: Sequence[ScriptStep]) -> list[ScriptStep]:
    """Steps of several sources in time order (stable: a script's step before a failure at the same time)."""
    return sorted((step for steps in step_lists for step in steps), key=lambda s: s.at_us)


class CommandScript:
    """Hands out the steps that are due at a sim time, each once."""

    def __init__(self, steps: Sequence[ScriptStep]) -> None:
        self._steps = list(steps)
        self._next = 0

    def due(self, time_us: int) -> list[ScriptStep]:
        out = []
        while self._next < len(self._steps) and self._steps[self._next].at_us <= time_us:
            out.append(self._steps[self._next])
            self._next += 1
        return out

    @property
    def next_at_us(self) -> int | float:
        """Sim time (µs) of the next step not handed out yet (inf when finished): nothing is due before."""
        return self._steps[self._next].at_us if self._next < len(self._steps) else math.inf

    @property
    def finished(self) -> bool:
        return self._next >= len(self._steps)
