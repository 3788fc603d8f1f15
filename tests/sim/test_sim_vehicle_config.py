"""Vehicle YAML files (issue 2): shipped vehicles valid and documented; bad files refused with field + range."""

from __future__ import annotations

import math
from pathlib import Path

import pytest
import yaml

from sim.vehicle_config import VEHICLES_DIR, VehicleConfigError, load_vehicle, vehicle_names


def test_sim_shipped_vehicles_load_with_sources_and_twr_about_2() -> None:
    assert {"quad250", "x500", "delivery650"} <= set(vehicle_names())
    for name in vehicle_names():
        v = load_vehicle(name)
        assert v.name == name
        data = yaml.safe_load((VEHICLES_DIR / f"{name}.yaml").read_text())
        assert set(data) - {"name", "sources"} <= set(v.sources)
        assert 1.6 <= v.thrust_to_weight(v.payload_max_kg if name == "delivery650" else 0.0) <= 2.2


def test_sim_x500_and_delivery650_match_spec() -> None:
    x500 = load_vehicle("x500")
    assert x500.mass_kg == 2.0 and x500.inertia_kg_m2 == (0.0217, 0.0217, 0.040)
    assert x500.k_f_n_per_rad2_s2 == 8.55e-6 and x500.omega_max_rad_s == 1000.0
    assert x500.k_m_nm_per_rad2_s2 == pytest.approx(0.016 * 8.55e-6)
    assert all(abs(x) == 0.174 and abs(y) == 0.174 for x, y in x500.rotor_pos_frd_m)
    d650 = load_vehicle("delivery650")
    assert d650.mass_kg + d650.payload_max_kg == pytest.approx(3.5) and d650.payload_max_kg >= 1.0
    wheelbase = 2 * math.hypot(*d650.rotor_pos_frd_m[0])
    assert wheelbase == pytest.approx(0.65, abs=0.01)
    q250 = load_vehicle("quad250")
    assert q250.mass_kg == 0.6 and 2 * math.hypot(*q250.rotor_pos_frd_m[0]) == pytest.approx(0.25, abs=0.01)


def _write(tmp_path: Path, **changes) -> Path:
    data = yaml.safe_load((VEHICLES_DIR / "x500.yaml").read_text())
    for key, value in changes.items():
        if value is None:
            data.pop(key)
        else:
            data[key] = value
    path = tmp_path / "bad.yaml"
    path.write_text(yaml.safe_dump(data))
    return path


@pytest.mark.parametrize(
    ("changes", "fragments"),
    [
        ({"mass_kg": -1.0}, ["mass_kg", "[0.05, 50]"]),
        ({"mass_kg": "heavy"}, ["mass_kg", "expected a number"]),
        ({"mass_kg": float("nan")}, ["mass_kg", "range"]),
        ({"inertia_kg_m2": [0.02, 0.02]}, ["inertia_kg_m2", "3 numbers"]),
        ({"inertia_kg_m2": [0.02, 0.0, 0.04]}, ["inertia_kg_m2[1]", "[1e-06, 10]"]),
        ({"omega_max_rad_s": 1e9}, ["omega_max_rad_s", "[10, 10000]"]),
        ({"omega_min_rad_s": 900.0}, ["omega_min_rad_s", "hover"]),
        ({"motor_time_constant_s": 0.0}, ["motor_time_constant_s", "[0.001, 1]"]),
        ({"rotor_yaw_dir": [1, 1, 1, -1]}, ["rotor_yaw_dir", "summing to 0"]),
        (
            {"rotor_pos_frd_m": [[0.174, 0.174], [0.174, -0.174], [-0.174, -0.174], [-0.174, 0.174]]},
            ["rotor_pos_frd_m[1]", "quad-x"],
        ),
        ({"k_f_n_per_rad2_s2": 1e-7}, ["thrust-to-weight", "[1.2, 6]"]),
        ({"mass_kg": None}, ["missing", "mass_kg"]),
        ({"colour": "red"}, ["unknown field", "colour"]),
        ({"sources": {"mass_kg": "x"}}, ["sources", "inertia_kg_m2"]),
    ],
)
def test_sim_invalid_vehicle_file_refused_with_field_and_range(tmp_path: Path, changes, fragments) -> None:
    with pytest.raises(VehicleConfigError) as exc:
        load_vehicle(_write(tmp_path, **changes))
    for fragment in fragments:
        assert fragment in str(exc.value)


def test_sim_unknown_vehicle_name_and_bad_yaml(tmp_path: Path) -> None:
    with pytest.raises(VehicleConfigError, match="known vehicles"):
        load_vehicle("x900")
    bad = tmp_path / "v.yaml"
    bad.write_text("mass_kg: [1, 2\n")
    with pytest.raises(VehicleConfigError, match="not valid YAML"):
        load_vehicle(bad)
    bad.write_text("- 1\n- 2\n")
    with pytest.raises(VehicleConfigError, match="mapping"):
        load_vehicle(bad)
