"""The inputs a case flies with, checked and edited as the flight will read them (SPEC §14): a value set at a
dotted path of a mission document, a vehicle name, a parameter file resolved against its defaults, a failures list.
The campaign file's checks (:mod:`tools.campaign.spec`) and the cases (:mod:`tools.campaign.cases`) both use them.
"""

from __future__ import annotations

import functools
import json
from pathlib import Path
from typing import Any

import yaml


class CaseInputError(ValueError):
    """A value a case would fly with that the world, the vehicle or the autopilot refuses."""


def resolve_path(raw: str, campaign_path: Path) -> Path | None:
    """``raw`` as given (cwd-relative), else next to the campaign file; None when neither exists."""
    for candidate in (Path(raw), campaign_path.parent / raw):
        if candidate.is_file():
            return candidate
    return None


@functools.lru_cache(maxsize=16)
def _base_json(base: Path) -> str:
    return json.dumps(yaml.safe_load(base.read_text()))


def base_doc(base: Path) -> Any:
    """A fresh copy of the parsed mission file (parsed once per file)."""
    return json.loads(_base_json(base))


def with_override(base: Path, dotted: str, value: Any) -> dict:
    """A copy of the mission document ``base`` with ``dotted`` set to ``value`` (see :func:`set_path`)."""
    doc = base_doc(base)
    set_path(doc, dotted, value, base)
    return doc


def set_path(doc: Any, dotted: str, value: Any, base: Path) -> None:
    """Set ``dotted`` in the mission document ``doc`` (read from ``base``): integer segments index lists
    (``mission.1.waypoint.alt_m``); a missing last key is added, a missing parent refused."""
    parts = dotted.split(".")
    node: Any = doc
    for depth, part in enumerate(parts[:-1]):
        nxt = _child(node, part)
        if nxt is None:
            if not isinstance(node, dict):
                raise CaseInputError(f"{'.'.join(parts[: depth + 1])}: no such entry in {base}")
            nxt = node[part] = {}
        node = nxt
    last = parts[-1]
    if isinstance(node, list):
        if not last.isdigit() or int(last) >= len(node):
            raise CaseInputError(f"{dotted}: no list entry {last} in {base}")
        node[int(last)] = value
    elif isinstance(node, dict):
        node[last] = value
    else:
        raise CaseInputError(f"{dotted}: {'.'.join(parts[:-1])} is not a mapping in {base}")


def _child(node: Any, part: str) -> Any:
    if isinstance(node, dict):
        return node.get(part)
    if isinstance(node, list) and part.isdigit() and int(part) < len(node):
        return node[int(part)]
    return None


def check_vehicle(name: Any) -> None:
    from sim.vehicle_config import VehicleConfigError, load_vehicle

    try:
        load_vehicle(str(name))
    except VehicleConfigError as exc:
        raise CaseInputError(str(exc)) from None


def check_params(value: Any, campaign_path: Path) -> None:
    if value == "default":
        return
    found = resolve_path(str(value), campaign_path)
    if found is None:
        raise CaseInputError(f"params: no such file {value!r} (or 'default')")
    resolved_params(str(found), "x500")


def check_failures(value: Any) -> None:
    """A failures list as the world file's ``failures:`` takes it (``[{at_s: S, inject: gps_off, motor: N}]``)."""
    from mavlink_bridge.contract.failure_schedule import FailureScheduleError, parse_failures

    try:
        parse_failures(value, ("failures",))
    except FailureScheduleError as exc:
        raise CaseInputError(str(exc)) from None


def resolved_params(params_file: str | None, vehicle: str) -> dict[str, float]:
    """Every parameter the file sets away from its default, as the autopilot would load it."""
    return dict(_resolved_params(params_file, vehicle))


@functools.lru_cache(maxsize=64)
def _resolved_params(params_file: str | None, vehicle: str) -> tuple[tuple[str, float], ...]:
    from autopilot.control import load_airframe
    from autopilot.param_schema import make_param_store
    from autopilot.parameters.store import ParamError

    payload = load_airframe(vehicle).payload_nominal_kg
    try:
        store = make_param_store(params_file, payload_nominal_kg=payload)
    except (ParamError, OSError, ValueError) as exc:
        raise CaseInputError(f"params: {exc}") from None
    default = make_param_store(None, payload_nominal_kg=payload).values()
    return tuple((name, value) for name, value in store.values().items() if value != default.get(name))
