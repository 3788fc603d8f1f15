"""One Rerun recording for a fleet world (issue 23 item 7): ``quadsitl up --rerun save:`` writes one file per
autopilot and one for the world, all with one recording id; each vehicle under its name, about the world's home;
the simulator's traffic tracks and a separation series per vehicle pair."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from conftest import REPO_ROOT
from rerun.chunk import RrdReader
from sitl_procs import free_instance_block, write_fleet_world

from autopilot.launch_recording import fleet_recording_id
from autopilot.telemetry.recording_reader import read_layout, read_recording

pytestmark = [pytest.mark.sitl, pytest.mark.slow]

TRAFFIC = """\
traffic:
  - callsign: HELI1
    icao: 0xA1B2C3
    emitter: rotorcraft
    path: [{north_m: -300, east_m: 60, alt_m: 40}, {north_m: 300, east_m: 60, alt_m: 40}]
    speed_m_s: 40
    start_s: 0
"""


def test_a_fleet_run_writes_one_recording_under_each_vehicles_name_about_the_worlds_home(tmp_path: Path) -> None:
    world = write_fleet_world(tmp_path, "trio", [("alpha", 0, 0), ("bravo", 0, 8), ("charlie", -5, 0)], TRAFFIC)
    out = tmp_path / "rec"
    block = free_instance_block(3)
    args = [sys.executable, "-m", "quadsitl_cli", "up", "--world", str(world), "--instance", str(block)]
    args += ["--gcs", "off", "--api", "off", "--speed", "max", "--duration-s", "4", "--seed", "3"]
    args += ["--no-sensor-noise"]  # the poses are the EKF's: noiseless sensors keep them on the vehicle's home
    args += ["--rerun", f"save:{out / 'flight.rrd'}", "--sim-timeout-s", "30"]
    done = subprocess.run(args, cwd=REPO_ROOT, capture_output=True, text=True, timeout=240)
    assert done.returncode == 0, done.stdout + done.stderr
    files = sorted(out.glob("*.rrd"))
    names = ["flight_alpha.rrd", "flight_bravo.rrd", "flight_charlie.rrd", "flight_world.rrd"]
    assert [f.name for f in files] == names
    recs = {f.stem.removeprefix("flight_"): read_recording(f) for f in files}
    assert {r.recording_id for r in recs.values()} == {fleet_recording_id(world, 3)}
    assert {r.application_id for r in recs.values()} == {"quadsitl_fleet"}  # not the single-vehicle layout's id
    assert [f.name for f in files if RrdReader(f).blueprints()] == ["flight_world.rrd"]  # the one layout: the world's
    layout = read_layout(out / "flight_world.rrd")
    assert {"fleet", "alpha", "bravo", "charlie"} <= set(layout.containers)
    assert layout.view("fleet world (NED)").origin == "/"
    homes = {"alpha": (0.0, 0.0), "bravo": (0.0, 8.0), "charlie": (-5.0, 0.0)}
    for name, (north_m, east_m) in homes.items():
        rec = recs[name]
        mine = (f"vehicles/{name}", f"plots/{name}/", "__")  # "__properties": rerun's own
        others = [e for e in rec.entities if not e.startswith(mine)]
        assert others == ["vehicles"], others  # only the shared NED declaration is outside its name
        radius = rec.rows(f"vehicles/{name}/separation_volume", "Cylinders3D:radii")[0][1]
        assert radius == [10.0]  # its own volume: NAV_TRAFF_U_HOR (default)
        assert f"plots/{name}/position/pos_ned_m" in rec.entities
        offset = np.asarray(rec.static_component(f"vehicles/{name}", "Transform3D:translation")[0])
        np.testing.assert_allclose(offset, (north_m, east_m, 0.0))
        pose = rec.translations(f"vehicles/{name}/vehicle").values  # about its own home (its EKF origin)
        about_world = (
            np.median(pose, axis=0) + offset
        )  # what the viewer draws: the transform of vehicles/<name> applied
        np.testing.assert_allclose(about_world[:2], (north_m, east_m), atol=0.5)
    sim = recs["world"]
    pairs = sorted(e for e in sim.entities if e.startswith("separation/"))
    assert pairs == ["separation/alpha-bravo", "separation/alpha-charlie", "separation/bravo-charlie"]
    ab = sim.scalars("separation/alpha-bravo").values  # horizontal, vertical (m): on the ground, 8 m apart
    np.testing.assert_allclose(ab[:, 0], 8.0, atol=0.3)
    assert sim.scalars("separation/bravo-charlie").values[0, 0] == pytest.approx(np.hypot(5.0, 8.0), abs=0.3)
    heli = sim.translations("traffic/HELI1").values
    assert len(heli) >= 10 and heli[0][0] < heli[-1][0]  # flying north along its path at 40 m up
    np.testing.assert_allclose(heli[:, 1:], np.tile((60.0, -40.0), (len(heli), 1)), atol=1e-3)
    assert "traffic/HELI1/nmac_volume" in sim.entities
