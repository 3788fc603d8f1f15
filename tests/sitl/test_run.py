"""``make run`` (``python -m tools.run``): the default delivery flight end to end, and no hang when the SITL
processes die. (``make run-fleet``, the same command on a fleet world: tests/sitl/test_sitl_fleet_gcs.py.)"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest
from conftest import REPO_ROOT
from sitl_procs import free_instance_block

from autopilot.telemetry import entities as ent
from autopilot.telemetry.recording_reader import read_recording

pytestmark = [pytest.mark.sitl, pytest.mark.slow]


def _run(*args: str, timeout_s: float) -> subprocess.CompletedProcess[str]:
    # a block of its own: another pytest worker may be flying a run from block 0 at the same time
    cmd = [sys.executable, "-m", "tools.run", "--block-from", str(free_instance_block(1)), *args]
    return subprocess.run(cmd, cwd=REPO_ROOT, capture_output=True, text=True, timeout=timeout_s)


def test_run_delivery_flies_the_default_mission_and_writes_everything(tmp_path: Path) -> None:
    out_dir = tmp_path / "run"
    proc = _run("--out-dir", str(out_dir), timeout_s=280.0)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    summary = json.loads((out_dir / "summary.json").read_text())
    assert summary["ok"] is True and summary["errors"] == []
    assert summary["exit_codes"] == {"gcs": 0, "up": 0}
    for name in ("sim_summary.json", "autopilot_summary.json", "gcs_summary.json"):
        assert (out_dir / name).is_file(), name
    gcs, sim, ap = summary["gcs"], summary["sim"], summary["autopilot"]
    assert gcs["ok"] is True and gcs["items_reached"] == gcs["items_total"] > 0
    assert gcs["landed"] and gcs["disarmed"]
    assert sim["collisions"] == 0 and sim["end_reason"] == "STOPPED"
    assert sim["payload_released_at_s"] is not None and ap["payload_released"] is True
    # every frame the simulator stepped reached the autopilot; the stop (SIGTERM once the ground station is done)
    # can land while the simulator waits for the answer to one more frame, which the autopilot has then handled
    assert ap["frames"] - sim["frames"] in (0, 1), (ap["frames"], sim["frames"])

    rrd = out_dir / "flight.rrd"
    assert summary["recording"] == str(rrd) and rrd.stat().st_size > 0
    pos = read_recording(rrd).scalars(ent.POS_NED)
    assert len(pos.t_us) == ap["frames"]  # the whole flight is in the recording
    assert f"recording: {rrd}" in proc.stdout and f"rerun {rrd}" in proc.stdout  # where it is, how to open it
    assert "result                       OK" in proc.stdout


def test_run_delivery_stops_and_says_why_when_the_sitl_dies(tmp_path: Path) -> None:
    """``quadsitl up`` exits at once (the autopilot refuses its --rerun): the ground station is stopped, exit 3,
    one clear error. (A bad input file never gets this far: tests/test_input_errors.py.)"""
    out_dir = tmp_path / "run"
    proc = _run("--out-dir", str(out_dir), "--rerun", "no_such_sink", timeout_s=300.0)
    assert proc.returncode == 3, proc.stdout + proc.stderr
    assert "run: error: quadsitl up exited with status 2 before the mission was done" in proc.stderr
    assert "no_such_sink" in proc.stderr  # the tail of up.log says what went wrong
    assert "?/?" not in proc.stdout and "collisions" not in proc.stderr  # no table of unknowns, no spurious lines
    summary = json.loads((out_dir / "summary.json").read_text())
    assert summary["ok"] is False and summary["exit_codes"]["up"] == 2
    assert summary["exit_codes"]["gcs"] is None  # stopped by the run, not left waiting for a heartbeat
    assert "result                       FAILED" in proc.stdout


CRASH_ON_CLIMB = """\
name: crash_on_climb
home: {lat_deg: 30.2635, lon_deg: 120.1233, alt_m: 12.0}
vehicle: x500
mission:
  - takeoff: {alt_m: 10}
  - waypoint: {north_m: 20, east_m: 0, alt_m: 10}
  - land: {}
world:
  obstacles:
    - sphere: {north_m: 0, east_m: 0, alt_m: 4, radius_m: 1.5}   # right above the pad: the camera looks forward
"""


def test_run_delivery_ends_when_the_sim_ends_the_run_mid_flight(tmp_path: Path) -> None:
    """A collision on the climb ends the simulator's run: the ground station (still waiting) is stopped, exit 3."""
    mission = tmp_path / "crash.yaml"
    mission.write_text(CRASH_ON_CLIMB)
    out_dir = tmp_path / "run"
    proc = _run("--mission", str(mission), "--out-dir", str(out_dir), "--rerun", "off", timeout_s=300.0)
    assert proc.returncode == 3, proc.stdout + proc.stderr
    assert "quadsitl up exited with status 4 before the mission was done (sim end reason: COLLISION)" in proc.stderr
    assert "run: error: simulator: collisions = 1" in proc.stderr
    summary = json.loads((out_dir / "summary.json").read_text())
    assert summary["ok"] is False and summary["sim"]["end_reason"] == "COLLISION"
    assert summary["autopilot"]["armed"] is True  # it was flying, not refused on the ground
    assert summary["recording"] is None and "recording:" not in proc.stdout  # --rerun off: none promised


def test_run_delivery_refuses_a_missing_mission(tmp_path: Path) -> None:
    proc = _run("--mission", str(tmp_path / "none.yaml"), "--out-dir", str(tmp_path), timeout_s=60.0)
    assert proc.returncode == 2
    missing = tmp_path / "none.yaml"
    assert (
        proc.stderr.strip()
        == f"run: error: {missing}: no such file; fix: check the path (missions/ holds the examples)"
    )
