"""A recording reads at first sight: one blueprint framed on the route (not a wide fence), the RTL leg at the
height it is flown, named k_p/k_i/k_d legends, battery charge and voltage on their own axes, the clearance
panel saying "no obstacles", and few chunks; and the headless screenshot tool says what it needs."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from conftest import REPO_ROOT

from autopilot.mission.files import load_mission_file
from autopilot.telemetry import entities as ent
from autopilot.telemetry import make_listener
from autopilot.telemetry.blueprint import Framing, flight_blueprint, tick_spacing_m
from autopilot.telemetry.recording_reader import read_recording
from autopilot.telemetry.rerun_logger import SERIES
from autopilot.telemetry.scene import route_points_ned
from tools import screenshot
from tools.benchmarks.telemetry import synthetic_records

MISSION = """\
name: framed
home: {lat_deg: 30.0, lon_deg: 120.0, alt_m: 10.0}
mission:
  - takeoff: {alt_m: 10}
  - waypoint: {north_m: 100, east_m: 40, alt_m: 10}
  - return_to_launch: {}
fence:
  - inclusion_circle: {north_m: 0, east_m: 0, radius_m: 500}
"""


def test_rtl_climbs_to_its_return_altitude_in_the_route() -> None:
    plan = load_mission_file(REPO_ROOT / "missions" / "city_block_delivery.yaml")
    route = route_points_ned(plan.items, plan.home, rtl_alt_m=30.0)  # ... waypoint at 15 m, RTL, land
    last_wp, climb, home_high, home_low = route[-5], route[-4], route[-3], route[-2]  # route[-1]: the land item
    assert tuple(climb) == (*last_wp[:2], -30.0) and last_wp[2] == -15.0  # climbed in place first
    assert tuple(home_high) == (0.0, 0.0, -30.0) and tuple(home_low) == (0.0, 0.0, 0.0)
    low = route_points_ned(plan.items, plan.home, rtl_alt_m=5.0)  # already above it: home at 15 m
    assert tuple(low[-3]) == (0.0, 0.0, -15.0) and len(low) == len(route) - 1


def _view_names(container: object) -> list[str]:
    names = []
    for item in getattr(container, "contents", []):
        names += [str(item.name)] if hasattr(item, "origin") else _view_names(item)  # a view, or a container
    return names


def test_framing_is_the_route_not_the_fence() -> None:
    framing = Framing.of_route(np.array([[0, 0, 0], [100, 40, -10], [0, 0, -10]]), obstacles=False)
    assert framing.center_ne_m == (50.0, 20.0) and 100.0 <= framing.span_m <= 150.0
    assert tick_spacing_m(framing.span_m) in (10.0, 20.0)
    assert tick_spacing_m(1000.0) == 200.0 and tick_spacing_m(30.0) == 5.0
    names = _view_names(flight_blueprint(framing).root_container)
    assert "clearance (m): no obstacles in this world" in names
    assert "battery charge (%)" in names and "battery voltage (V)" in names
    assert "clearance to obstacles (m)" in _view_names(flight_blueprint(Framing(obstacles=True)).root_container)


def test_one_blueprint_named_legends_and_few_chunks(tmp_path: Path) -> None:
    mission = tmp_path / "m.yaml"
    mission.write_text(MISSION)
    path = tmp_path / "flight.rrd"
    telemetry = make_listener(f"save:{path}", vehicle="x500", mission_file=mission, rtl_alt_m=30.0)
    assert telemetry is not None
    for record in synthetic_records(5000):  # 20 s at 250 Hz
        telemetry.on_step(record)
    telemetry.on_mission([], load_mission_file(mission).home)  # a GCS upload later: no second blueprint
    telemetry.close()
    r = read_recording(path)
    assert r.blueprints == 1
    gains = {names for p, _, _, names in SERIES if p.startswith("gains/")}
    assert ("k_p x", "k_p y", "k_p z") in gains and ("k_d roll", "k_d pitch", "k_d yaw") in gains
    assert {p for p, *_ in SERIES} >= {ent.BATTERY_REMAINING, ent.BATTERY_VOLTAGE}
    stats = subprocess.run([sys.executable, "-m", "rerun", "rrd", "stats", str(path)], capture_output=True, text=True)
    assert stats.returncode == 0, stats.stderr[-400:]  # the CLI ships with rerun-sdk: the count the issue measured
    chunks = int(next(ln for ln in stats.stdout.splitlines() if ln.startswith("num_chunks")).split("=")[1])
    assert chunks < 150, stats.stdout[:400]


def test_screenshot_without_chromium_says_how_to_install_it(monkeypatch: pytest.MonkeyPatch, capsys) -> None:
    monkeypatch.setattr(screenshot.shutil, "which", lambda name: None)
    assert screenshot.main(["--recording", "nowhere.rrd"]) == 2
    err = capsys.readouterr().err.strip()
    assert err == "screenshot: no Chromium found; fix: apt-get update && apt-get install -y chromium"


def test_viewer_url_points_at_the_local_grpc_server() -> None:
    assert (
        screenshot.viewer_url(9090, 9876) == "http://127.0.0.1:9090/?url=rerun%2Bhttp%3A%2F%2F127.0.0.1%3A9876%2Fproxy"
    )
