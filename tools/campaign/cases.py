"""Cases: what case k of a campaign flies, drawn from ``numpy.random.default_rng([k, seed])`` (SPEC §14).

A case depends only on (campaign file, k): never on the order cases run in or the machine. Draw order: the
simulator's seed first, then the base file (when ``base`` is a list), then every ``vary`` entry in the file's
order. :func:`materialise` writes everything a flight reads into the case's folder: ``world.yaml`` with the
overrides and the case's ``failures:`` in its ``world:`` (the autopilot injects them at their sim times),
``params.yaml`` fully resolved, ``script.yaml`` with the scripted arm and mission start. A case can be re-flown
from its files or from its results row alone.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from mavlink_bridge.contract.source_lines import parse_yaml
from tools.campaign.inputs import base_doc, resolve_path, resolved_params, set_path
from tools.campaign.spec import ENCOUNTER_BASE, CampaignSpec, Distribution
from tools.encounters import encounter_world

SEED_LIMIT = 2**31 - 1
MISSION_START_DELAY_S = 0.5


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

    @property
    def stagger_s(self) -> float:
        """Seconds between a fleet's vehicles' starts (an encounter's draw; 0: all at once)."""
        return float(dict(self.overrides).get("encounter.stagger_s", 0.0))


@dataclass(frozen=True)
class CaseFiles:
    """The texts a flight reads, as :func:`materialise` writes them."""

    world_yaml: str
    params_yaml: str
    script_yaml: str

    @property
    def fleet(self) -> bool:
        """True when the world lists ``vehicles:`` (one simulator, one autopilot per vehicle; else one vehicle)."""
        doc = parse_yaml(self.world_yaml, "world.yaml").data  # parsed once per process (libyaml), not per call
        return isinstance(doc, dict) and bool(doc.get("vehicles"))


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
    """Case ``case_id`` of an encounter campaign: what it drew (kind, vehicles, manned, traffic class, stagger) as its
    overrides."""
    enc = encounter_world(sim_seed, **dict(spec.encounter or ()))
    drawn = {key: _sample(rng, dist) for key, dist in spec.vary}
    drawn_enc = (("encounter.kind", enc.kind), ("encounter.vehicles", enc.vehicles))
    drawn_enc += (("encounter.manned", enc.manned), ("encounter.traffic", enc.traffic))
    drawn_enc += (("encounter.stagger_s", enc.stagger_s),)
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
