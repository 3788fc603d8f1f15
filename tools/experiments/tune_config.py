"""The ES tuning config file (``tools/experiments/*.yaml``): what to tune, on which experiments, with what budget.

Example (keys and meaning)::

    name: attitude_nlvg
    vehicle: x500                      # sim vehicle and autopilot airframe of the same name
    structure: nlvg                    # nlvg: learn k1 and k2 (6 per group) | pid: k1 == k2 (3 per group)
    method: central                    # central (paper) | perturbation (classic dither ES)
    groups: [[roll, pitch]]            # channels sharing one learned gain set
    base_gains: paper                  # paper | <gains.yaml> (relative to this file): the untuned channels
    experiments:                       # J = sum over these of 1/(tf-t0) ∫ e² dt
      - {kind: step, channel: roll, amplitude: 0.5, duration_s: 1.0}
      - {kind: step, channel: pitch, amplitude: 0.5, duration_s: 1.0}
    bounds: {kp: [0.5, 60.0], ki: [0.001, 5.0], kd: [0.3, 30.0]}
    es: {iterations: 20, restarts: 5, seed: 0}     # fields of CentralEsConfig / PerturbationEsConfig
    start_from_base: true              # restart 0 starts at the base gains (the paper's K), others random
"""

from __future__ import annotations

from dataclasses import dataclass, fields, replace
from pathlib import Path
from typing import Any

import yaml

from autopilot.control.gains import CHANNELS, CascadeGains
from autopilot.tuning import CentralEsConfig, PerturbationEsConfig
from tools.experiments.gain_vector import TERMS, GainParametrisation, Structure


class TuneConfigError(ValueError):
    """A tuning config is malformed; the message names the file and the key."""


@dataclass(frozen=True, slots=True)
class StepExperiment:
    """A step of ``amplitude`` (rad or m) on ``channel`` from hover, cost over ``[t0_s, duration_s]``."""

    channel: str
    amplitude: float
    duration_s: float
    t0_s: float = 0.0
    weight: float = 1.0


@dataclass(frozen=True, slots=True)
class TuneConfig:
    name: str
    vehicle: str
    structure: Structure
    method: str
    groups: tuple[tuple[str, ...], ...]
    base_gains: CascadeGains
    experiments: tuple[StepExperiment, ...]
    bounds: dict[str, tuple[float, float]]
    es: CentralEsConfig | PerturbationEsConfig
    start_from_base: bool = True

    def parametrisation(self) -> GainParametrisation:
        return GainParametrisation(self.base_gains, self.groups, self.structure, self.bounds)

    def with_budget(self, iterations: int | None = None, restarts: int | None = None) -> TuneConfig:
        """The same config with another ES budget (e.g. a quick run)."""
        es = self.es
        if iterations is not None:
            es = replace(es, iterations=iterations)
        if restarts is not None:
            es = replace(es, restarts=restarts)
        return replace(self, es=es)


def _require(data: dict[str, Any], key: str, where: str) -> Any:
    if key not in data:
        raise TuneConfigError(f"{where}: missing key {key!r}")
    return data[key]


def load_base_gains(spec: str | None, relative_to: Path | None = None) -> CascadeGains:
    """``paper`` (the paper's starting PID gains on every channel) or a gains YAML path."""
    if spec in (None, "paper"):
        return CascadeGains.fixed_pid()
    path = Path(spec)
    if not path.is_absolute() and relative_to is not None and not path.is_file():
        path = relative_to / path
    return CascadeGains.from_yaml(path)


def tune_config_from_dict(data: dict[str, Any], where: str = "<dict>", relative_to: Path | None = None) -> TuneConfig:
    """Validate a parsed config mapping (see the module docstring for the keys)."""
    if not isinstance(data, dict):
        raise TuneConfigError(f"{where}: expected a mapping")
    try:
        structure = Structure(str(data.get("structure", "nlvg")))
    except ValueError:
        raise TuneConfigError(f"{where}: structure must be 'nlvg' or 'pid'") from None
    method = str(data.get("method", "central"))
    if method not in ("central", "perturbation"):
        raise TuneConfigError(f"{where}: method must be 'central' or 'perturbation', got {method!r}")
    groups = tuple(tuple(str(c) for c in g) for g in _require(data, "groups", where))
    for g in groups:
        for c in g:
            if c not in CHANNELS:
                raise TuneConfigError(f"{where}: groups: unknown channel {c!r} (channels: {CHANNELS})")
    experiments = []
    for i, e in enumerate(_require(data, "experiments", where)):
        if not isinstance(e, dict) or e.get("kind", "step") != "step":
            raise TuneConfigError(f"{where}: experiments[{i}] must be a mapping with kind: step")
        try:
            experiments.append(
                StepExperiment(
                    channel=str(e["channel"]),
                    amplitude=float(e["amplitude"]),
                    duration_s=float(e["duration_s"]),
                    t0_s=float(e.get("t0_s", 0.0)),
                    weight=float(e.get("weight", 1.0)),
                )
            )
        except (KeyError, TypeError, ValueError) as exc:
            raise TuneConfigError(f"{where}: experiments[{i}]: {exc}") from None
    raw_bounds = _require(data, "bounds", where)
    if not isinstance(raw_bounds, dict) or sorted(raw_bounds) != sorted(TERMS):
        raise TuneConfigError(f"{where}: bounds must give [lower, upper] for each of {TERMS}")
    bounds = {t: (float(raw_bounds[t][0]), float(raw_bounds[t][1])) for t in TERMS}
    es_raw = dict(data.get("es", {}))
    es_cls = CentralEsConfig if method == "central" else PerturbationEsConfig
    allowed = {f.name for f in fields(es_cls)}
    unknown = set(es_raw) - allowed
    if unknown:
        raise TuneConfigError(f"{where}: es: unknown keys {sorted(unknown)} for method {method}")
    try:
        es = es_cls(**es_raw)
        base = load_base_gains(data.get("base_gains"), relative_to)
    except ValueError as exc:
        raise TuneConfigError(f"{where}: {exc}") from None
    return TuneConfig(
        name=str(data.get("name", "tune")),
        vehicle=str(_require(data, "vehicle", where)),
        structure=structure,
        method=method,
        groups=groups,
        base_gains=base,
        experiments=tuple(experiments),
        bounds=bounds,
        es=es,
        start_from_base=bool(data.get("start_from_base", True)),
    )


def load_tune_config(path: str | Path) -> TuneConfig:
    path = Path(path)
    try:
        data = yaml.safe_load(path.read_text())
    except (OSError, yaml.YAMLError) as exc:
        raise TuneConfigError(f"{path}: {exc}") from None
    return tune_config_from_dict(data, str(path), path.parent)
