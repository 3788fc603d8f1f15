"""The controller's NOMINAL airframe model (what the autopilot believes, not the simulated truth).

Values live in ``autopilot/airframes/<name>.yaml`` with their source; they copy the nominal numbers
of the simulator's vehicle files (the autopilot never imports ``sim``; a test compares both).
Rotor order is PX4 quad-x: 0 front-right (CCW), 1 rear-left (CCW), 2 front-left (CW), 3 rear-right (CW);
``rotor_yaw_dir`` is +1 where the rotor's reaction torque is +yaw (about FRD +z), i.e. CCW rotors.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from mavlink_bridge.contract.source_lines import YamlSyntaxError, parse_yaml

AIRFRAME_DIR = Path(__file__).resolve().parent.parent / "airframes"


class AirframeError(ValueError):
    """An airframe file is missing, malformed, or has an out-of-range value (the message says which)."""


@dataclass(frozen=True, slots=True)
class Airframe:
    """Nominal quad-x model: mass (incl. nominal payload), principal inertia, rotor geometry and constants.

    ``k_f`` [N/(rad/s)²]: rotor thrust = k_f·ω²; ``k_m`` [N·m/(rad/s)²]: rotor drag torque = k_m·ω²;
    motor command u ∈ [0, 1] commands ω = u·omega_max_rad_s. ``payload_nominal_kg`` is the part of
    ``mass_kg`` that is a droppable payload (the default of the ``PLD_MASS_KG`` parameter).
    """

    name: str
    mass_kg: float
    inertia_kg_m2: tuple[float, float, float]
    rotor_pos_frd_m: tuple[tuple[float, float, float], ...]
    rotor_yaw_dir: tuple[int, int, int, int]
    k_f: float
    k_m: float
    omega_max_rad_s: float
    payload_nominal_kg: float = 0.0

    def __post_init__(self) -> None:
        positive = {"mass_kg": self.mass_kg, "k_f": self.k_f, "k_m": self.k_m, "omega_max_rad_s": self.omega_max_rad_s}
        for key, value in positive.items():
            if not (math.isfinite(value) and value > 0.0):
                raise AirframeError(f"airframe {self.name}: {key} must be a finite positive number, got {value!r}")
        if not (math.isfinite(self.payload_nominal_kg) and 0.0 <= self.payload_nominal_kg < self.mass_kg):
            raise AirframeError(
                f"airframe {self.name}: payload_nominal_kg must be in [0, mass_kg), got {self.payload_nominal_kg!r}"
            )
        if len(self.inertia_kg_m2) != 3 or not all(math.isfinite(v) and v > 0.0 for v in self.inertia_kg_m2):
            raise AirframeError(f"airframe {self.name}: inertia_kg_m2 must be 3 finite positive numbers")
        if len(self.rotor_pos_frd_m) != 4 or any(len(p) != 3 for p in self.rotor_pos_frd_m):
            raise AirframeError(f"airframe {self.name}: rotor_pos_frd_m must be 4 [x, y, z] positions")
        if not all(math.isfinite(c) for p in self.rotor_pos_frd_m for c in p):
            raise AirframeError(f"airframe {self.name}: rotor_pos_frd_m must be finite")
        if sorted(self.rotor_yaw_dir) != [-1, -1, 1, 1]:
            raise AirframeError(f"airframe {self.name}: rotor_yaw_dir must hold two +1 and two -1")

    @property
    def max_rotor_thrust_n(self) -> float:
        """Thrust of one rotor at omega_max."""
        return self.k_f * self.omega_max_rad_s**2

    @property
    def thrust_to_weight(self) -> float:
        """Total maximum thrust over nominal weight (g = 9.80665 m/s²)."""
        return 4.0 * self.max_rotor_thrust_n / (self.mass_kg * 9.80665)

    def allocation_matrix(self) -> np.ndarray:
        """A (4×4): [thrust_n, τx, τy, τz]ᵀ = A · rotor thrusts (N); thrust along −z FRD."""
        a = np.empty((4, 4))
        for i, (x, y, _z) in enumerate(self.rotor_pos_frd_m):
            a[0, i] = 1.0
            a[1, i] = -y  # r × (0, 0, −T): τx = −y·T
            a[2, i] = x  # τy = x·T
            a[3, i] = self.rotor_yaw_dir[i] * self.k_m / self.k_f
        return a


def _tuple3(value: object, key: str, path: Path) -> tuple[float, float, float]:
    if not isinstance(value, list | tuple) or len(value) != 3:
        raise AirframeError(f"{path}: {key} must be a list of 3 numbers")
    try:
        return (float(value[0]), float(value[1]), float(value[2]))
    except (TypeError, ValueError):
        raise AirframeError(f"{path}: {key} must be a list of 3 numbers") from None


def load_airframe(name_or_path: str | Path) -> Airframe:
    """Load ``autopilot/airframes/<name>.yaml`` ("quad250", "x500", "delivery650") or a YAML path."""
    path = Path(name_or_path)
    if path.suffix not in (".yaml", ".yml"):
        path = AIRFRAME_DIR / f"{name_or_path}.yaml"
    if not path.is_file():
        known = sorted(p.stem for p in AIRFRAME_DIR.glob("*.yaml"))
        raise AirframeError(f"airframe {name_or_path!r} not found (known: {known})")
    try:
        data = parse_yaml(path.read_text(), path).data  # parsed once per process (a campaign worker's cases)
    except YamlSyntaxError as exc:
        raise AirframeError(str(exc)) from exc
    if not isinstance(data, dict):
        raise AirframeError(f"{path}: expected a mapping")
    required = ("mass_kg", "inertia_kg_m2", "rotor_pos_frd_m", "rotor_yaw_dir", "k_f", "k_m", "omega_max_rad_s")
    missing = [k for k in required if k not in data]
    if missing:
        raise AirframeError(f"{path}: missing {missing}")
    rotors = data["rotor_pos_frd_m"]
    if not isinstance(rotors, list) or len(rotors) != 4:
        raise AirframeError(f"{path}: rotor_pos_frd_m must be a list of 4 positions")
    try:
        return Airframe(
            name=str(data.get("name", path.stem)),
            mass_kg=float(data["mass_kg"]),
            inertia_kg_m2=_tuple3(data["inertia_kg_m2"], "inertia_kg_m2", path),
            rotor_pos_frd_m=tuple(_tuple3(p, "rotor_pos_frd_m[i]", path) for p in rotors),
            rotor_yaw_dir=tuple(int(d) for d in data["rotor_yaw_dir"]),
            k_f=float(data["k_f"]),
            k_m=float(data["k_m"]),
            omega_max_rad_s=float(data["omega_max_rad_s"]),
            payload_nominal_kg=float(data.get("payload_nominal_kg", 0.0)),
        )
    except (TypeError, ValueError) as exc:
        if isinstance(exc, AirframeError):
            raise
        raise AirframeError(f"{path}: {exc}") from None
