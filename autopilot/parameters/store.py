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

from mavlink_bridge.contract.source_lines import YamlSyntaxError, did_you_mean, read_yaml


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


def difflike(name: object, names: Iterable[str]) -> bool:
    """Whether ``name`` is close to one of ``names`` (a typo worth a "did you mean")."""
    return did_you_mean(name, names).startswith("did you mean")


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

        ParamError is one line ``FILE:LINE: what is wrong; fix: ...`` (a missing file, bad YAML, an unknown
        name, a value that is not a number or out of range). A file with a top-level ``format: F`` key is
        converted by ``formats[F]`` (e.g. a tuner's gains file, ``autopilot.param_schema``) into ``NAME: value``
        pairs first.
        """
        try:
            source = read_yaml(path)
        except OSError as exc:
            raise ParamError(f"{path}: cannot read: {exc.strerror}; fix: check the path given to --params") from None
        except YamlSyntaxError as exc:
            raise ParamError(str(exc)) from None
        data = source.data or {}
        if not isinstance(data, dict):
            raise ParamError(
                f"{source.where()}: expected a mapping of NAME: value, got {type(data).__name__}; "
                "fix: write one 'NAME: value' per line, e.g. 'MPC_XY_CRUISE: 5.0'"
            )
        if "format" in data:
            convert = (formats or {}).get(str(data["format"]))
            if convert is None:
                known = ", ".join(sorted(formats or {})) or "none"
                raise ParamError(
                    f"{source.where('format')}: unknown file format {data['format']!r}; fix: one of {known}, "
                    "or plain 'NAME: value' pairs"
                )
            try:
                data = convert(data)
            except (TypeError, ValueError) as exc:
                raise ParamError(
                    f"{source.where()}: {' '.join(str(exc).split())}; "
                    "fix: rewrite it with python -m tools.research.tune_es"
                ) from None
        checked = {}
        for name, value in data.items():
            where = source.where(str(name))
            spec = self._specs.get(str(name))
            if spec is None:
                fix = (
                    did_you_mean(name, self._specs) if difflike(name, self._specs) else "list the names: gcs param list"
                )
                raise ParamError(f"{where}: unknown parameter {name!r}; fix: {fix}")
            if isinstance(value, bool) or not isinstance(value, int | float):
                fix = f"write e.g. '{spec.name}: {spec.default:g}'"
                raise ParamError(f"{where}: {spec.name}: expected a number, got {value!r}; fix: {fix}")
            try:
                checked[spec.name] = spec.check(value)
            except (TypeError, ValueError) as exc:
                raise ParamError(f"{where}: {exc}; fix: use a value from {spec.min:g} to {spec.max:g}") from None
        for name, value in checked.items():
            self.set(name, value)
