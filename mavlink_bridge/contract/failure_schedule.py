"""Failures scheduled by the world file (``world: failures:``), shared by the simulator and the autopilot.

A mission's or bare world's ``failures`` key lists failures at sim times::

    world:
      failures:
        - {at_s: 40, inject: gps_off}
        - {at_s: 43.5, inject: gps_ok}
        - {at_s: 30, inject: motor_off, motor: 2}

``inject`` is ``<unit>_<type>`` with the unit and type names ``--script``'s ``inject_failure`` takes (FAILURE_UNIT /
FAILURE_TYPE without their prefix, lower case; :data:`INJECTIONS` lists them); ``motor`` is the motor instance
(1-4 in PX4 quad-x order, 0 = all; motor injections only, default 0). The simulator validates the key with the
rest of the world; the autopilot, which owns failure injection, runs each entry as the ``inject_failure`` step of
a ``--script`` at that sim time (:func:`autopilot.commander.script.failure_steps`).

In a fleet world each ``vehicles:`` entry may carry its own ``failures:`` (the same entries), for that vehicle only;
the world's ``failures:`` go to every vehicle, and a vehicle gets both, merged by time
(:func:`vehicle_failures`: world entries first at a tie).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from mavlink_bridge.contract.mav_enums import FailureType, FailureUnit
from mavlink_bridge.contract.source_lines import did_you_mean


def _name(unit: FailureUnit, kind: FailureType) -> str:
    return f"{unit.name.split('_', 1)[1].lower()}_{kind.name.lower()}"


_U, _T = FailureUnit, FailureType
#: Every ``inject`` name and its (unit, type): what the autopilot's failure injection supports (``ok`` clears).
INJECTIONS: dict[str, tuple[FailureUnit, FailureType]] = {
    _name(unit, kind): (unit, kind)
    for unit, kinds in (
        (_U.SENSOR_GPS, (_T.OFF, _T.STUCK, _T.OK)),
        (_U.SENSOR_BARO, (_T.OFF, _T.STUCK, _T.OK)),
        (_U.SENSOR_MAG, (_T.OFF, _T.STUCK, _T.OK)),
        (_U.SENSOR_GYRO, (_T.STUCK, _T.OK)),
        (_U.SENSOR_ACCEL, (_T.STUCK, _T.OK)),
        (_U.SYSTEM_MOTOR, (_T.OFF, _T.OK)),
    )
    for kind in kinds
}
MAX_AT_S = 1e6


class FailureScheduleError(ValueError):
    """A ``failures`` entry that cannot run; the message starts with its path (``world.failures[2].inject: ...``),
    ``node`` is that path as a tuple (for the file's line)."""

    def __init__(self, node: tuple[str | int, ...], problem: str) -> None:
        head = "".join(f"[{p}]" if isinstance(p, int) else f".{p}" for p in node).lstrip(".")
        super().__init__(f"{head}: {problem}")
        self.node = node


@dataclass(frozen=True, slots=True)
class ScheduledFailure:
    """One failure at ``at_s`` of sim time: the unit, the type and the instance (a motor; 0 = all or n/a)."""

    at_s: float
    unit: FailureUnit
    kind: FailureType
    instance: int = 0

    @property
    def inject(self) -> str:
        """The world file's name of this failure (``gps_off``)."""
        return _name(self.unit, self.kind)


def parse_failures(spec: Any, node: tuple[str | int, ...] = ("world", "failures")) -> tuple[ScheduledFailure, ...]:
    """Validate a ``failures`` list (at ``node`` of its file) into entries sorted by time (stable);
    FailureScheduleError names the field and says what to write."""
    if spec is None:
        return ()
    if not isinstance(spec, list):
        raise FailureScheduleError(node, f"expected a list of {{at_s, inject}} entries, got {spec!r}")
    out = []
    for i, entry in enumerate(spec):
        at = (*node, i)
        if not isinstance(entry, dict):
            raise FailureScheduleError(at, f"expected a mapping like {{at_s: 40, inject: gps_off}}, got {entry!r}")
        unknown = sorted(str(k) for k in set(entry) - {"at_s", "inject", "motor"})
        if unknown:
            fix = did_you_mean(unknown[0], ["at_s", "inject", "motor"])
            raise FailureScheduleError((*at, unknown[0]), f"unknown field(s) {unknown}; allowed at_s, inject, motor; "
                                       f"fix: {fix}")  # fmt: skip
        for key in ("at_s", "inject"):
            if key not in entry:
                raise FailureScheduleError(at, f"missing {key}; fix: write e.g. {{at_s: 40, inject: gps_off}}")
        at_s = entry["at_s"]
        if isinstance(at_s, bool) or not isinstance(at_s, int | float) or not (0.0 <= at_s <= MAX_AT_S):
            raise FailureScheduleError(
                (*at, "at_s"), f"expected sim seconds in [0, {MAX_AT_S:g}], got {at_s!r}; fix: write a plain number"
            )
        name = entry["inject"]
        if name not in INJECTIONS:
            names = sorted(INJECTIONS)
            fix = did_you_mean(str(name), names)
            raise FailureScheduleError((*at, "inject"), f"unknown failure {name!r}; allowed {', '.join(names)}; "
                                       f"fix: {fix}")  # fmt: skip
        unit, kind = INJECTIONS[name]
        motor = entry.get("motor", 0)
        if "motor" in entry and unit is not FailureUnit.SYSTEM_MOTOR:
            raise FailureScheduleError((*at, "motor"), "only motor_off and motor_ok take a motor; fix: remove it")
        if isinstance(motor, bool) or not isinstance(motor, int) or not 0 <= motor <= 4:
            raise FailureScheduleError(
                (*at, "motor"), f"expected a motor number 1-4 (0 = all), got {motor!r}; fix: write an integer 0-4"
            )
        out.append(ScheduledFailure(float(at_s), unit, kind, motor))
    return tuple(sorted(out, key=lambda f: f.at_s))


def merge_failures(*schedules: tuple[ScheduledFailure, ...]) -> tuple[ScheduledFailure, ...]:
    """Several schedules as one, by time (stable: an earlier schedule's entry first at a tie)."""
    return tuple(sorted((f for s in schedules for f in s), key=lambda f: f.at_s))


def mission_failures(doc: Any) -> tuple[ScheduledFailure, ...]:
    """The ``failures`` of a parsed mission (``world: failures:``) or bare world mapping (``failures:``): in a fleet
    world, the ones every vehicle gets."""
    if not isinstance(doc, dict):
        return ()
    if "world" in doc:
        world = doc["world"] or {}
        return parse_failures(world.get("failures") if isinstance(world, dict) else None)
    return parse_failures(doc.get("failures"), ("failures",))


def vehicle_entries(doc: Any) -> list[Any]:
    """The ``vehicles:`` entries of a parsed world document (``[]``: not a fleet world)."""
    entries = doc.get("vehicles") if isinstance(doc, dict) else None
    return entries if isinstance(entries, list) else []


def vehicle_failures(doc: Any, index: int) -> tuple[ScheduledFailure, ...]:
    """What fleet vehicle ``index`` (``vehicles[index]``, MAV_SYS_ID ``index + 1``) injects: the world's
    ``failures:`` merged by time with its entry's own ``failures:`` (FailureScheduleError naming the field)."""
    entries = vehicle_entries(doc)
    if not 0 <= index < len(entries):
        raise FailureScheduleError(("vehicles",), f"no vehicle {index} (the file lists {len(entries)})")
    entry = entries[index]
    own = entry.get("failures") if isinstance(entry, dict) else None
    return merge_failures(mission_failures(doc), parse_failures(own, ("vehicles", index, "failures")))


def vehicle_index(doc: Any, name: str) -> int:
    """The index of the ``vehicles:`` entry called ``name`` (FailureScheduleError saying which names there are)."""
    names = [str(e.get("name")) if isinstance(e, dict) else "" for e in vehicle_entries(doc)]
    if name in names:
        return names.index(name)
    if not names:
        raise FailureScheduleError(("vehicles",), f"no vehicle {name!r}: not a fleet world (no vehicles: list)")
    raise FailureScheduleError(("vehicles",), f"no vehicle named {name!r}; fix: {did_you_mean(name, names)}")
