"""Bad input files are refused before any process starts: one line naming the file, the line and the fix.

Covers the mission (YAML, QGC .waypoints, .plan), the world (the simulator's half of a mission YAML), the
``--params`` and ``--script`` files and the vehicle name, through the library readers, ``quadsitl sim --check``,
``quadsitl up`` and ``make run`` (``tools.run``), which must leave no run folder behind.
"""

from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path

import pytest
from conftest import REPO_ROOT

from autopilot.commander.script import ScriptError, load_script
from autopilot.mission.files import MissionFileError, load_mission_file
from autopilot.param_schema import make_param_store
from autopilot.parameters.store import ParamError
from autopilot.preflight import InputFileError, check_autopilot_inputs

DELIVERY = (REPO_ROOT / "missions" / "delivery.yaml").read_text()


def _typo_mission(tmp_path: Path) -> tuple[Path, int]:
    """The delivery mission with its second entry misspelt ``waypiont``; and that entry's line."""
    lines = DELIVERY.splitlines()
    line = next(n for n, text in enumerate(lines, start=1) if text.strip().startswith("- waypoint:"))
    lines[line - 1] = lines[line - 1].replace("waypoint", "waypiont")
    path = tmp_path / "typo.yaml"
    path.write_text("\n".join(lines) + "\n")
    return path, line


def _one_line(text: str) -> str:
    """The message itself, checked to be a single line without a traceback."""
    assert "Traceback" not in text
    lines = [ln for ln in text.strip().splitlines() if ln.strip()]
    assert len(lines) == 1, text
    return lines[0]


def test_a_misspelt_mission_entry_names_file_line_and_fix(tmp_path: Path) -> None:
    path, line = _typo_mission(tmp_path)
    with pytest.raises(MissionFileError) as err:
        load_mission_file(path)
    message = _one_line(str(err.value))
    assert message.startswith(f"{path}:{line}: mission item 1")
    assert message.endswith("fix: did you mean 'waypoint'?")


def test_a_yaml_syntax_error_names_the_file_not_a_unicode_string(tmp_path: Path) -> None:
    path = tmp_path / "broken.yaml"
    path.write_text("name: broken\nmission:\n  - takeoff: {alt_m: 10\n  - land: {}\n")
    with pytest.raises(MissionFileError) as err:
        load_mission_file(path)
    message = _one_line(str(err.value))
    assert "<unicode string>" not in message
    assert message.startswith(f"{path}:4: not valid YAML") and "; fix: check the indentation" in message


def test_a_bad_field_value_points_at_its_own_line(tmp_path: Path) -> None:
    path = tmp_path / "m.yaml"
    path.write_text(DELIVERY.replace("speed_m_s: 5.0", "speed_m_s: fast"))
    line = next(n for n, t in enumerate(path.read_text().splitlines(), start=1) if t.startswith("speed_m_s"))
    with pytest.raises(MissionFileError) as err:
        load_mission_file(path)
    assert _one_line(str(err.value)).startswith(f"{path}:{line}: field 'speed_m_s': expected a number, got 'fast'")


def test_an_item_refused_by_the_mission_checks_points_at_its_entry(tmp_path: Path) -> None:
    path = tmp_path / "high.yaml"
    path.write_text(DELIVERY.replace("{north_m: 120, east_m: 80, alt_m: 6,", "{north_m: 120, east_m: 80, alt_m: 900,"))
    line = next(n for n, t in enumerate(path.read_text().splitlines(), start=1) if "alt_m: 900" in t)
    with pytest.raises(MissionFileError) as err:
        load_mission_file(path)
    assert _one_line(str(err.value)).startswith(f"{path}:{line}: mission item ")


def test_a_waypoints_file_names_the_line(tmp_path: Path) -> None:
    path = tmp_path / "bad.waypoints"
    rows = (REPO_ROOT / "missions" / "delivery.waypoints").read_text().splitlines()
    rows[3] = rows[3].replace("\t", " ", 1).rsplit(maxsplit=1)[0]  # line 4: a column short
    path.write_text("\n".join(rows) + "\n")
    with pytest.raises(MissionFileError) as err:
        load_mission_file(path)
    message = _one_line(str(err.value))
    assert message.startswith(f"{path}:4: line item 2: expected 12 columns") and "; fix: " in message


def test_a_params_file_names_the_line_and_the_likely_name(tmp_path: Path) -> None:
    path = tmp_path / "params.yaml"
    path.write_text("CA_RSAFE_M: 3.0\nCA_RSAFE: 3.0\n")
    with pytest.raises(ParamError) as err:
        make_param_store(path)
    assert _one_line(str(err.value)) == f"{path}:2: unknown parameter 'CA_RSAFE'; fix: did you mean 'CA_RSAFE_M'?"
    path.write_text("CA_RSAFE_M: [4.0\n")
    with pytest.raises(ParamError) as err:
        make_param_store(path)
    assert _one_line(str(err.value)).startswith(f"{path}:2: not valid YAML")


def test_a_script_file_names_the_line_and_the_command(tmp_path: Path) -> None:
    path = tmp_path / "script.yaml"
    path.write_text("- {at_s: 1, cmd: arm}\n- {at_s: 2, cmd: takeof, alt_m: 5}\n")
    with pytest.raises(ScriptError) as err:
        load_script(path)
    message = _one_line(str(err.value))
    assert message.startswith(f"{path}:2: step 1: cmd must be one of") and message.endswith("did you mean 'takeoff'?")


def test_an_unknown_vehicle_in_a_mission_points_at_its_line(tmp_path: Path) -> None:
    path = tmp_path / "m.yaml"
    path.write_text(DELIVERY.replace("vehicle: delivery650", "vehicle: delivery65"))
    line = next(n for n, t in enumerate(path.read_text().splitlines(), start=1) if t.startswith("vehicle:"))
    with pytest.raises(InputFileError) as err:
        check_autopilot_inputs(mission=path)
    message = _one_line(str(err.value))
    assert message.startswith(f"{path}:{line}: vehicle: unknown vehicle 'delivery65'")
    assert message.endswith("did you mean 'delivery650'?")


def _run(*args: str, cwd: Path = REPO_ROOT, timeout_s: float = 120.0) -> subprocess.CompletedProcess[str]:
    """``python ARGS`` in ``cwd``; the repository on the path (``tools`` is not an installed package)."""
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(filter(None, [str(REPO_ROOT), os.environ.get("PYTHONPATH")]))}
    return subprocess.run([sys.executable, *args], cwd=cwd, env=env, capture_output=True, text=True, timeout=timeout_s)


def _world_typo(tmp_path: Path) -> tuple[Path, int]:
    text = (REPO_ROOT / "missions" / "city_block_delivery.yaml").read_text()
    lines = text.splitlines()
    line = next(n for n, t in enumerate(lines, start=1) if t.strip().startswith("- cylinder:"))
    lines[line - 1] = lines[line - 1].replace("cylinder", "cylindr")
    path = tmp_path / "world_typo.yaml"
    path.write_text("\n".join(lines) + "\n")
    return path, line


def test_sim_check_names_the_world_line(tmp_path: Path) -> None:
    path, line = _world_typo(tmp_path)
    proc = _run("-m", "sim", "--check", "--world", str(path))
    assert proc.returncode == 2
    message = _one_line(proc.stderr)
    assert message.startswith(f"quadsitl sim: {path}:{line}: world.obstacles[")
    assert message.endswith("fix: did you mean 'cylinder'?")
    assert _run("-m", "sim", "--check", "--world", str(REPO_ROOT / "missions" / "delivery.yaml")).returncode == 0


@pytest.mark.parametrize("kind", ["mission", "world", "params"])
def test_up_refuses_bad_files_before_starting_anything(tmp_path: Path, kind: str) -> None:
    if kind == "mission":
        path, line = _typo_mission(tmp_path)
        args = ["--world", str(path)]
    elif kind == "world":
        path, line = _world_typo(tmp_path)
        args = ["--world", str(path)]
    else:
        path, line = tmp_path / "p.yaml", 1
        path.write_text("NO_SUCH_PARAM: 1\n")
        args = ["--params", str(path)]
    t0 = time.monotonic()
    proc = _run("-m", "quadsitl_cli", "up", "--speed", "max", "--log-dir", str(tmp_path / "logs"), *args)
    assert proc.returncode == 2
    assert _one_line(proc.stderr).startswith(f"quadsitl up: {path}:{line}: ")
    assert "Ctrl-C" not in proc.stdout  # no banner: nothing was started
    assert not (tmp_path / "logs").exists()
    assert time.monotonic() - t0 < 30.0  # no process start-up (a JIT warm-up) before the answer


def test_make_run_refuses_a_bad_mission_and_leaves_no_run_folder(tmp_path: Path) -> None:
    path, line = _typo_mission(tmp_path)
    proc = _run("-m", "tools.run", "--mission", str(path), cwd=tmp_path)
    assert proc.returncode == 2
    assert _one_line(proc.stderr).startswith(f"run: error: {path}:{line}: mission item 1")
    assert "FAILED" not in proc.stdout and "?" not in proc.stdout
    assert not (tmp_path / "runs").exists()


def test_make_run_refuses_an_unknown_vehicle_at_once(tmp_path: Path) -> None:
    mission = REPO_ROOT / "missions" / "delivery.yaml"
    proc = _run("-m", "tools.run", "--mission", str(mission), "--vehicle", "no_such_vehicle", cwd=tmp_path)
    assert proc.returncode == 2
    message = _one_line(proc.stderr)
    assert message.startswith("run: error: --vehicle: unknown vehicle 'no_such_vehicle'")
    assert not (tmp_path / "runs").exists()
