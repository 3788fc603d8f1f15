"""Parameters: declared once with a schema, validated, changeable in flight (SPEC §8).

Every component declares its parameters as :class:`ParamSpec` entries; the
:class:`ParamStore` holds the values in force, refuses out-of-range or non-finite values
with a message that names the range, and notifies listeners of accepted changes.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass
from pathlib import Path

import yaml


class ParamError(ValueError):
    """A parameter name or value was refused; the message says why."""


@dataclass(frozen=True, slots=True)
class ParamSpec:
    """One parameter: PX4-style name (<= 16 chars), float default, inclusive range, unit, description."""

    name: str
    default: float
    min: float
    max: float
    unit: str
    description: str

    def __post_init__(self) -> None:
        name_ok = 1 <= len(self.name) <= 16 and self.name.replace("_", "").isalnum() and self.name.upper() == self.name
        if not name_ok:
            raise ParamError(f"parameter name {self.name!r} must be 1-16 upper-case letters, digits or '_'")
        if not (self.min <= self.default <= self.max):
            raise ParamError(f"{self.name}: default {self.default} outside [{self.min}, {self.max}]")

    def check(self, value: float) -> float:
        """The value as float if it is finite and in range, else ParamError."""
        v = float(value)
        if not math.isfinite(v):
            raise ParamError(f"{self.name}: value {value!r} is not a finite number")
        if not (self.min <= v <= self.max):
            raise ParamError(
                f"{self.name}: {v:g} {self.unit} is outside the allowed range [{self.min:g}, {self.max:g}]"
            )
        return v


Listener = Callable[[str, float], None]
#: Converts a parsed parameter file with a ``format`` key into ``NAME: value`` pairs.
FileFormat = Callable[[dict], Mapping[str, float]]


class ParamStore:
    """The parameter values in force, keyed by name, in declaration order."""

    def __init__(self, specs: Iterable[ParamSpec]) -> None:
        self._specs: dict[str, ParamSpec] = {}
        for spec in specs:
            if spec.name in self._specs:
                raise ParamError(f"parameter {spec.name} declared twice")
            self._specs[spec.name] = spec
        self._values: dict[str, float] = {name: spec.default for name, spec in self._specs.items()}
        self._listeners: list[Listener] = []
        #: Counts accepted changes: a reader may cache values derived from parameters while it is unchanged.
        self.version = 0

    @property
    def specs(self) -> Mapping[str, ParamSpec]:
        return self._specs

    def names(self) -> list[str]:
        return list(self._specs)

    def __contains__(self, name: str) -> bool:
        return name in self._specs

    def get(self, name: str) -> float:
        try:
            return self._values[name]
        except KeyError:
            raise ParamError(f"unknown parameter {name!r}") from None

    def values(self) -> dict[str, float]:
        return dict(self._values)

    def set(self, name: str, value: float) -> float:
        """Validate and set; listeners hear about accepted changes. Raises ParamError."""
        spec = self._specs.get(name)
        if spec is None:
            raise ParamError(f"unknown parameter {name!r}")
        v = spec.check(value)
        if v != self._values[name]:
            self._values[name] = v
            self.version += 1
            for listener in self._listeners:
                listener(name, v)
        return v

    def subscribe(self, listener: Listener) -> None:
        self._listeners.append(listener)

    def load_file(self, path: str | Path, formats: Mapping[str, FileFormat] | None = None) -> None:
        """Apply a YAML file of ``NAME: value`` pairs; all are checked before any is set.

        A file with a top-level ``format: F`` key is converted by ``formats[F]`` (e.g. a tuner's gains file,
        ``autopilot.param_schema``) into ``NAME: value`` pairs first. Every refusal is a one-line ParamError.
        """
        try:
            data = yaml.safe_load(Path(path).read_text()) or {}
        except (OSError, yaml.YAMLError) as exc:
            raise ParamError(f"{path}: {' '.join(str(exc).split())}") from None
        if not isinstance(data, dict):
            raise ParamError(f"{path}: expected a mapping of NAME: value, got {type(data).__name__}")
        if "format" in data:
            convert = (formats or {}).get(str(data["format"]))
            if convert is None:
                known = ", ".join(sorted(formats or {})) or "none"
                raise ParamError(f"{path}: unknown file format {data['format']!r} (known: {known})")
            try:
                data = convert(data)
            except (TypeError, ValueError) as exc:
                raise ParamError(f"{path}: {' '.join(str(exc).split())}") from None
        checked = {}
        for name, value in data.items():
            spec = self._specs.get(str(name))
            if spec is None:
                raise ParamError(f"{path}: unknown parameter {name!r}")
            try:
                checked[spec.name] = spec.check(value)
            except (TypeError, ValueError) as exc:
                raise ParamError(f"{path}: {exc}") from None
        for name, value in checked.items():
            self.set(name, value)
