"""Quadrotor vehicle configuration: a validated, frozen description loaded from YAML (SPEC §5).

A vehicle file (``sim/vehicles/<name>.yaml``) lists every physical value with its unit in the
key and a ``sources:`` mapping that says where each value comes from. Loading validates every
field (type, finiteness, range, geometry, thrust-to-weight) and raises :class:`VehicleConfigError`
whose message names the field and the allowed range.

Conventions: body FRD, PX4 quad-x motor order (0 front-right CCW, 1 rear-left CCW, 2 front-left CW,
3 rear-right CW); rotor thrust ``T = k_f ω²`` along body −z, reaction torque ``±k_m ω²`` about body z
(``rotor_yaw_dir`` = +1 for a CCW rotor, whose reaction torque is +z in FRD).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import Any

from mavlink_bridge.contract.frames import GRAVITY_M_S2
from mavlink_bridge.contract.source_lines import YamlSyntaxError, parse_yaml

VEHICLES_DIR = Path(__file__).resolve().parent / "vehicles"

#: Expected sign of (x, y) of each rotor in PX4 quad-x order (FRD): FR, RL, FL, RR.
QUAD_X_SIGNS = ((1, 1), (-1, -1), (1, -1), (-1, 1))
#: Bounds on the maximum thrust-to-weight ratio (at maximum payload) accepted for a file.
THRUST_TO_WEIGHT_RANGE = (1.2, 6.0)


class VehicleConfigError(ValueError):
    """A vehicle file or value was refused; the message names the field and the allowed range."""


@dataclass(frozen=True)
class VehicleConfig:
    """Physical parameters of one X quadrotor (SI, body FRD). See module docstring for conventions."""

    name: str
    mass_kg: float  # airframe without payload
    inertia_kg_m2: tuple[float, float, float]  # diagonal (Ixx, Iyy, Izz), body FRD
    rotor_pos_frd_m: tuple[tuple[float, float], ...]  # 4 x (x, y), PX4 quad-x order
    rotor_yaw_dir: tuple[int, int, int, int]  # +1: CCW rotor, reaction torque +z
    k_f_n_per_rad2_s2: float
    k_m_nm_per_rad2_s2: float
    omega_max_rad_s: float
    omega_min_rad_s: float  # idle speed while the command is > 0
    motor_time_constant_s: float
    drag_body_n_per_m2_s2: tuple[float, float, float]  # F_i = -c_i v_i |v_i| (air-relative, FRD)
    rotor_drag_n_s_per_m: float  # F_xy = -c v_xy (air-relative, FRD horizontal plane)
    payload_max_kg: float
    sources: dict[str, str] = field(compare=False)
    collision_radius_m: float = 0.0  # vehicle hull radius used for obstacle collisions
    ground_impact_speed_m_s: float = 3.0  # touchdown faster than this ends the run
    ground_friction_coeff: float = 0.8  # Coulomb friction of the landing gear

    @property
    def max_thrust_n(self) -> float:
        """All four rotors at ω_max."""
        return 4.0 * self.k_f_n_per_rad2_s2 * self.omega_max_rad_s**2

    def thrust_to_weight(self, payload_kg: float = 0.0) -> float:
        """Maximum thrust over weight with ``payload_kg`` attached."""
        return self.max_thrust_n / ((self.mass_kg + payload_kg) * GRAVITY_M_S2)

    def hover_omega_rad_s(self, payload_kg: float = 0.0) -> float:
        """Rotor speed that balances weight: ``sqrt(m g / (4 k_f))``."""
        return math.sqrt((self.mass_kg + payload_kg) * GRAVITY_M_S2 / (4.0 * self.k_f_n_per_rad2_s2))


# field -> (low, high) inclusive range of each scalar (or of each element of a vector field)
_RANGES: dict[str, tuple[float, float]] = {
    "mass_kg": (0.05, 50.0),
    "inertia_kg_m2": (1e-6, 10.0),
    "rotor_pos_frd_m": (-2.0, 2.0),
    "k_f_n_per_rad2_s2": (1e-10, 1e-2),
    "k_m_nm_per_rad2_s2": (1e-12, 1e-3),
    "omega_max_rad_s": (10.0, 10000.0),
    "omega_min_rad_s": (0.0, 5000.0),
    "motor_time_constant_s": (1e-3, 1.0),
    "drag_body_n_per_m2_s2": (0.0, 10.0),
    "rotor_drag_n_s_per_m": (0.0, 10.0),
    "payload_max_kg": (0.0, 50.0),
    "collision_radius_m": (0.0, 5.0),
    "ground_impact_speed_m_s": (0.1, 50.0),
    "ground_friction_coeff": (0.0, 5.0),
}
_VECTOR_LEN = {"inertia_kg_m2": 3, "drag_body_n_per_m2_s2": 3}
_OPTIONAL = {"collision_radius_m", "ground_impact_speed_m_s", "ground_friction_coeff"}


def _range_text(name: str) -> str:
    lo, hi = _RANGES[name]
    return f"[{lo:g}, {hi:g}]"


def _scalar(name: str, value: Any, label: str | None = None) -> float:
    label = label or name
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise VehicleConfigError(f"{label}: expected a number in {_range_text(name)}, got {value!r}")
    v = float(value)
    lo, hi = _RANGES[name]
    if not math.isfinite(v) or not lo <= v <= hi:
        raise VehicleConfigError(f"{label}: {value!r} is outside the allowed range {_range_text(name)}")
    return v


def _vector(name: str, value: Any, length: int) -> tuple[float, ...]:
    if not isinstance(value, list | tuple) or len(value) != length:
        raise VehicleConfigError(f"{name}: expected a list of {length} numbers in {_range_text(name)}, got {value!r}")
    return tuple(_scalar(name, v, f"{name}[{i}]") for i, v in enumerate(value))


def _rotor_positions(value: Any) -> tuple[tuple[float, float], ...]:
    name = "rotor_pos_frd_m"
    if not isinstance(value, list | tuple) or len(value) != 4:
        raise VehicleConfigError(f"{name}: expected 4 [x, y] pairs (PX4 quad-x order FR, RL, FL, RR), got {value!r}")
    rotors = tuple(tuple(_vector(name, p, 2)) for p in value)
    for i, ((x, y), (sx, sy)) in enumerate(zip(rotors, QUAD_X_SIGNS, strict=True)):
        if x * sx <= 0.0 or y * sy <= 0.0:
            raise VehicleConfigError(
                f"{name}[{i}]: ({x}, {y}) is not in the quad-x quadrant (sign x {sx:+d}, sign y {sy:+d}) "
                "of PX4 motor order FR, RL, FL, RR"
            )
    return rotors  # type: ignore[return-value]


def _yaw_dirs(value: Any) -> tuple[int, int, int, int]:
    name = "rotor_yaw_dir"
    ok = (
        isinstance(value, list | tuple)
        and len(value) == 4
        and all(not isinstance(v, bool) and v in (-1, 1) for v in value)
        and sum(value) == 0
    )
    if not ok:
        raise VehicleConfigError(
            f"{name}: expected 4 values in {{-1, +1}} summing to 0 (PX4: [1, 1, -1, -1]), got {value!r}"
        )
    return tuple(int(v) for v in value)  # type: ignore[return-value]


def vehicle_config_from_dict(data: dict[str, Any], origin: str = "<dict>") -> VehicleConfig:
    """Validate a mapping (as read from YAML) and build a :class:`VehicleConfig`."""
    if not isinstance(data, dict):
        raise VehicleConfigError(f"{origin}: a vehicle file must be a mapping of fields, got {type(data).__name__}")
    known = {f.name for f in fields(VehicleConfig)}
    unknown = sorted(set(data) - known)
    if unknown:
        raise VehicleConfigError(f"{origin}: unknown field(s) {unknown}; allowed fields are {sorted(known)}")
    missing = sorted(k for k in known - _OPTIONAL if k not in data)
    if missing:
        raise VehicleConfigError(f"{origin}: missing required field(s) {missing}")
    name = data["name"]
    if not isinstance(name, str) or not name.strip():
        raise VehicleConfigError(f"name: expected a non-empty string, got {name!r}")
    values: dict[str, Any] = {"name": name}
    for key in _RANGES:
        if key not in data:
            continue
        if key == "rotor_pos_frd_m":
            values[key] = _rotor_positions(data[key])
        elif key in _VECTOR_LEN:
            values[key] = _vector(key, data[key], _VECTOR_LEN[key])
        else:
            values[key] = _scalar(key, data[key])
    values["rotor_yaw_dir"] = _yaw_dirs(data["rotor_yaw_dir"])
    sources = data["sources"]
    if not isinstance(sources, dict) or not all(isinstance(v, str) and v for v in sources.values()):
        raise VehicleConfigError(
            "sources: expected a mapping field -> non-empty text naming where the value comes from"
        )
    undocumented = sorted(k for k in known - {"name", "sources"} if k in data and k not in sources)
    if undocumented:
        raise VehicleConfigError(f"sources: no source given for field(s) {undocumented}")
    values["sources"] = dict(sources)
    cfg = VehicleConfig(**values)
    if cfg.omega_min_rad_s >= cfg.omega_max_rad_s:
        raise VehicleConfigError(
            f"omega_min_rad_s: {cfg.omega_min_rad_s} must be below omega_max_rad_s ({cfg.omega_max_rad_s})"
        )
    if cfg.hover_omega_rad_s() <= cfg.omega_min_rad_s:
        raise VehicleConfigError(
            f"omega_min_rad_s: {cfg.omega_min_rad_s} must be below the empty hover speed {cfg.hover_omega_rad_s():.1f}"
        )
    twr = cfg.thrust_to_weight(cfg.payload_max_kg)
    lo, hi = THRUST_TO_WEIGHT_RANGE
    if not lo <= twr <= hi:
        raise VehicleConfigError(
            f"k_f_n_per_rad2_s2/omega_max_rad_s: thrust-to-weight at payload_max_kg is {twr:.2f}, "
            f"allowed range [{lo:g}, {hi:g}]"
        )
    return cfg


def vehicle_names() -> list[str]:
    """Names of the vehicle files shipped in ``sim/vehicles``."""
    return sorted(p.stem for p in VEHICLES_DIR.glob("*.yaml"))


def load_vehicle(name_or_path: str | Path) -> VehicleConfig:
    """Load a shipped vehicle by name (``"x500"``) or any vehicle YAML by path; validated."""
    path = Path(name_or_path)
    if not path.suffix and isinstance(name_or_path, str) and "/" not in name_or_path:
        path = VEHICLES_DIR / f"{name_or_path}.yaml"
        if not path.is_file():
            raise VehicleConfigError(f"vehicle: unknown name {name_or_path!r}; known vehicles are {vehicle_names()}")
    if not path.is_file():
        raise VehicleConfigError(f"vehicle: no such file {str(path)!r}")
    try:
        data = parse_yaml(path.read_text(), path).data  # parsed once per process (a campaign worker's cases)
    except YamlSyntaxError as exc:
        raise VehicleConfigError(str(exc)) from exc
    return vehicle_config_from_dict(data, origin=str(path))
