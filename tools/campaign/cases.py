"""Cases: what case k of a campaign flies, drawn from ``numpy.random.default_rng([k, seed])`` (SPEC §14).

A case depends only on (campaign file, k): never on the order cases run in or the machine. Draw order: the
simulator's seed first, then the base file (when ``base`` is a list), then every ``vary`` entry in the file's
order. :func:`materialise` writes everything a flight reads into the case's folder: ``world.yaml`` with the
overrides and the case's ``failures:`` in its ``world:`` (the autopilot injects them at their sim times),
``params.yaml`` fully resolved, ``script.yaml`` with the scripted arm and mission start. A case can be re-flown
from its files or from its results row alone.
"""

from __future__ import annotations

import functools
import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from tools.campaign.spec import CampaignSpec, Distribution, resolve_path

SEED_LIMIT = 2**31 - 1
MISSION_START_DELAY_S = 0.5


class CaseInputError(ValueError):
    """A value a case would fly with that the world, the vehicle or the autopilot refuses."""


@dataclass(frozen=True)
class Case:
    """Every input of one flight (what its results row records)."""

    case_id: int
    sim_seed: int
    base: str
    vehicle: str
    params: str  # "default" or a parameter / gains file
    failures_json: str  # the failures list as JSON ("[]": none)
    overrides: tuple[tuple[str, Any], ...]  # (dotted path into the base file, value) in the file's order

    @property
    def failures(self) -> list[dict[str, Any]]:
        return json.loads(self.failures_json)


@dataclass(frozen=True)
class CaseFiles:
    """The texts a flight reads, as :func:`materialise` writes them."""

    world_yaml: str
    params_yaml: str
    script_yaml: str


def draw(spec: CampaignSpec, case_id: int) -> Case:
    """Case ``case_id`` of ``spec``: a pure function of (spec, case_id)."""
    rng = np.random.default_rng([case_id, spec.seed])
    sim_seed = int(rng.integers(0, SEED_LIMIT))
    if spec.encounter is not None:  # the fleet world is drawn from the case's seed (tools.encounters)
        return _encounter_case(spec, case_id, sim_seed, rng)
    base = spec.bases[int(rng.integers(len(spec.bases)))] if len(spec.bases) > 1 else spec.bases[0]
    drawn = {key: _sample(rng, dist) for key, dist in spec.vary}
    vehicle = drawn.pop("vehicle", None) or _base_vehicle(base)
    params = str(drawn.pop("params", "default"))
    failures = drawn.pop("failures", [])
    return Case(case_id, sim_seed, base, str(vehicle), params, json.dumps(failures), tuple(drawn.items()))


def _encounter_case(spec: CampaignSpec, case_id: int, sim_seed: int, rng: np.random.Generator) -> Case:
    """Case ``case_id`` of an encounter campaign: what it drew (kind, vehicles, manned, stagger) as its overrides."""
    from tools.campaign.fleet_flight import ENCOUNTER_BASE
    from tools.encounters import encounter_world

    enc = encounter_world(sim_seed, **dict(spec.encounter or ()))
    drawn = {key: _sample(rng, dist) for key, dist in spec.vary}
    drawn_enc = (("encounter.kind", enc.kind), ("encounter.vehicles", enc.vehicles))
    drawn_enc += (("encounter.manned", enc.manned), ("encounter.stagger_s", enc.stagger_s))
    return Case(case_id, sim_seed, ENCOUNTER_BASE, "x500", str(drawn.get("params", "default")), "[]", drawn_enc)


def _sample(rng: np.random.Generator, dist: Distribution) -> Any:
    if dist.kind == "uniform":
        return float(rng.uniform(float(dist.args[0]), float(dist.args[1])))
    if dist.kind == "randint":
        return int(rng.integers(int(dist.args[0]), int(dist.args[1]), endpoint=True))
    return dist.args[int(rng.integers(len(dist.args)))]


def _base_vehicle(base: str) -> str:
    doc = yaml.safe_load(Path(base).read_text())
    vehicle = doc.get("vehicle") if isinstance(doc, dict) else None
    return vehicle if isinstance(vehicle, str) else "x500"


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


def materialise(spec: CampaignSpec, case: Case) -> CaseFiles:
    """The world, parameter and script files case ``case`` flies with (see the module docstring)."""
    if spec.encounter is not None:
        return _encounter_files(spec, case)
    base = Path(case.base)
    doc = base_doc(base)
    for dotted, value in case.overrides:
        set_path(doc, dotted, value, base)
    doc["vehicle"] = case.vehicle
    world = doc.get("world")
    if not isinstance(world, dict):
        world = doc["world"] = {}
    world["failures"] = case.failures  # the world file's schedule: the autopilot injects them (docs/failures.md)
    params_file = None if case.params == "default" else str(resolve_path(case.params, Path(spec.path)) or case.params)
    params = resolved_params(params_file, case.vehicle)
    steps = [
        {"at_s": spec.arm_at_s, "cmd": "arm"},
        {"at_s": spec.arm_at_s + MISSION_START_DELAY_S, "cmd": "mission_start"},
    ]
    return CaseFiles(
        world_yaml=yaml.safe_dump(doc, sort_keys=False),
        params_yaml=yaml.safe_dump(dict(sorted(params.items())), sort_keys=False) if params else "{}\n",
        script_yaml=yaml.safe_dump(steps, sort_keys=False),
    )


def _encounter_files(spec: CampaignSpec, case: Case) -> CaseFiles:
    """An encounter case's generated fleet world and its parameters (no script: the ground station arms)."""
    from tools.encounters import encounter_world

    world = encounter_world(case.sim_seed, **dict(spec.encounter or ())).yaml_text()
    params_file = None if case.params == "default" else str(resolve_path(case.params, Path(spec.path)) or case.params)
    params = resolved_params(params_file, case.vehicle)
    params_yaml = yaml.safe_dump(dict(sorted(params.items())), sort_keys=False) if params else "{}\n"
    return CaseFiles(world_yaml=world, params_yaml=params_yaml, script_yaml="[]\n")


def write_case_files(files: CaseFiles, case_dir: Path) -> dict[str, Path]:
    """Write the case's files into ``case_dir``; their paths by role."""
    case_dir.mkdir(parents=True, exist_ok=True)
    paths = {"world": case_dir / "world.yaml", "params": case_dir / "params.yaml", "script": case_dir / "script.yaml"}
    paths["world"].write_text(files.world_yaml)
    paths["params"].write_text(files.params_yaml)
    paths["script"].write_text(files.script_yaml)
    return paths
