"""The ES tuning config file (``tools/research/experiments/*.yaml``): what to tune, on which experiments, with
what budget.

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
      # - {kind: track, route: lissajous, duration_s: 20.0, weight: 1.0}   # whole cascade, mean |e_pos|²
    bounds: {kp: [0.5, 60.0], ki: [0.001, 5.0], kd: [0.3, 30.0]}
    es: {iterations: 20, restarts: 5, seed: 0}     # fields of CentralEsConfig / PerturbationEsConfig
    start_from_base: true              # restart 0 starts at the base gains (the paper's K), others random
    # optional, the noisy effort-aware setting (issue 14); defaults give the noise-free J above:
    noise_scale: 1.0                   # feedback noise = scale × DEFAULT_FEEDBACK_NOISE (0: truth)
    seeds: [1, 2]                      # training noise seeds, averaged (the same draws for every probe)
    eval_seeds: [101, 102, 103, 104]   # held-out seeds for the reported metrics
    effort_weight: 1.0e-4              # λ: J += λ·mean over experiments of chatter² (motor-command rate, 1/s)
    overshoot_weight: 0.0              # μ: J += μ·Σ overshoot² (fraction of the step)
    delta_bounds: {delta1: [0.002, 0.1], delta2: [0.15, 2.0]}   # learn δ1, δ2 (nlvg only)
    warm_start: gains_pid.yaml         # one more restart starts at these gains (k1 = k2 = a tuned PID)
    wind: {mean_ned_m_s: [2.0, 2.0, 0.0], gust_m_s: 1.5, seed: 1}   # the steps are flown in this wind
"""

from __future__ import annotations

from dataclasses import dataclass, fields, replace
from pathlib import Path
from typing import Any

import yaml

from autopilot.control.gains import CHANNELS, CascadeGains
from autopilot.tuning import CentralEsConfig, PerturbationEsConfig
from sim.world import WindConfig
from tools.research.experiments.feedback_noise import DEFAULT_FEEDBACK_NOISE, FeedbackNoise
from tools.research.experiments.gain_vector import TERMS, GainParametrisation, Structure

_KEYS = {
    "name", "vehicle", "structure", "method", "groups", "base_gains", "experiments", "bounds", "es",
    "start_from_base", "noise_scale", "seeds", "eval_seeds", "effort_weight", "overshoot_weight",
    "delta_bounds", "warm_start", "wind",
}  # fmt: skip


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
class TrackExperiment:
    """Follow ``route`` (``autopilot.flight_tasks.trajectories``, e.g. "lissajous") for ``duration_s`` with the
    whole cascade; cost: mean of the squared position-error norm (m²) over the route."""

    route: str
    duration_s: float
    weight: float = 1.0


@dataclass(frozen=True, slots=True)
class TuneConfig:
    name: str
    vehicle: str
    structure: Structure
    method: str
    groups: tuple[tuple[str, ...], ...]
    base_gains: CascadeGains
    experiments: tuple[StepExperiment | TrackExperiment, ...]
    bounds: dict[str, tuple[float, float]]
    es: CentralEsConfig | PerturbationEsConfig
    start_from_base: bool = True
    noise_scale: float = 0.0
    seeds: tuple[int, ...] = (0,)
    eval_seeds: tuple[int, ...] = (0,)
    effort_weight: float = 0.0
    overshoot_weight: float = 0.0
    delta_bounds: dict[str, tuple[float, float]] | None = None
    warm_start: CascadeGains | None = None
    wind: WindConfig | None = None

    def parametrisation(self) -> GainParametrisation:
        return GainParametrisation(self.base_gains, self.groups, self.structure, self.bounds, self.delta_bounds)

    @property
    def noise(self) -> FeedbackNoise | None:
        """The rollouts' feedback noise (None: the true state)."""
        return None if self.noise_scale == 0.0 else DEFAULT_FEEDBACK_NOISE.scaled(self.noise_scale)

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
    unknown_keys = set(data) - _KEYS
    if unknown_keys:
        raise TuneConfigError(f"{where}: unknown keys {sorted(unknown_keys)} (known: {sorted(_KEYS)})")
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
    experiments: list[StepExperiment | TrackExperiment] = []
    for i, e in enumerate(_require(data, "experiments", where)):
        kind = e.get("kind", "step") if isinstance(e, dict) else None
        if kind not in ("step", "track"):
            raise TuneConfigError(f"{where}: experiments[{i}] must be a mapping with kind: step or kind: track")
        try:
            if kind == "track":
                experiments.append(
                    TrackExperiment(
                        route=str(e["route"]), duration_s=float(e["duration_s"]), weight=float(e.get("weight", 1.0))
                    )
                )
                continue
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
        warm = None if data.get("warm_start") is None else load_base_gains(str(data["warm_start"]), relative_to)
        noise_scale = float(data.get("noise_scale", 0.0))
        seeds = tuple(int(v) for v in data.get("seeds", [0]))
        eval_seeds = tuple(int(v) for v in data.get("eval_seeds", list(seeds)))
        effort = float(data.get("effort_weight", 0.0))
        overshoot = float(data.get("overshoot_weight", 0.0))
        raw_w = data.get("wind")
        wind = None
        if raw_w is not None:
            raw_w = dict(raw_w)
            wind = WindConfig(
                mean_ned_m_s=tuple(float(v) for v in raw_w.get("mean_ned_m_s", (0.0, 0.0, 0.0))),
                gust_m_s=float(raw_w.get("gust_m_s", 0.0)),
                seed=int(raw_w.get("seed", 0)),
            )
        raw_d = data.get("delta_bounds")
        delta_bounds = None if raw_d is None else {k: (float(v[0]), float(v[1])) for k, v in dict(raw_d).items()}
    except (TypeError, ValueError, IndexError) as exc:
        raise TuneConfigError(f"{where}: {exc}") from None
    if not (noise_scale >= 0.0 and effort >= 0.0 and overshoot >= 0.0):
        raise TuneConfigError(f"{where}: noise_scale, effort_weight and overshoot_weight must be >= 0")
    if not seeds or not eval_seeds:
        raise TuneConfigError(f"{where}: seeds and eval_seeds must not be empty")
    if set(seeds) & set(eval_seeds) and noise_scale > 0.0 and "eval_seeds" in data:
        raise TuneConfigError(f"{where}: eval_seeds must be held out (not in seeds)")
    config = TuneConfig(
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
        noise_scale=noise_scale,
        seeds=seeds,
        eval_seeds=eval_seeds,
        effort_weight=effort,
        overshoot_weight=overshoot,
        delta_bounds=delta_bounds,
        warm_start=warm,
        wind=wind,
    )
    try:
        config.parametrisation()
    except ValueError as exc:
        raise TuneConfigError(f"{where}: {exc}") from None
    return config


def load_tune_config(path: str | Path) -> TuneConfig:
    path = Path(path)
    try:
        data = yaml.safe_load(path.read_text())
    except (OSError, yaml.YAMLError) as exc:
        raise TuneConfigError(f"{path}: {exc}") from None
    return tune_config_from_dict(data, str(path), path.parent)
