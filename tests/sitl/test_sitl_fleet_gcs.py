"""The bundled ground station flies a fleet (issue 23 item 6) over one GCS port, and third-party clients fly
vehicles of a fleet on their own links: ``tools.gcs fly`` with a fleet world flies every vehicle by system id
(one killed mid-flight fails alone, the others land), ``make run-fleet`` (``tools.run`` on a fleet world) flies a
world end to end, and MAVSDK-Python on vehicle 2's API port flies a mission while the bundled client flies
vehicle 1's."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from conftest import REPO_ROOT
from interop_clients import MAVSDK_DRIVER, MISSING_CLIENT, mavsdk4_python
from interop_clients.missions import short_delivery
from sitl_procs import free_instance_block, read_json

from autopilot.mission.files import load_fleet_missions
from mavlink_bridge.contract.frames import LocalNedFrame
from mavlink_bridge.contract.vehicle_api import MissionItem
from mavlink_bridge.gcs_client.fleet_link import FleetLink
from tools.gcs.fly import FlyOptions, fly
from tools.run.processes import ground_station_done

pytestmark = [pytest.mark.sitl, pytest.mark.slow]

HEAD = """\
name: {name}
home: {{lat_deg: 47.3977, lon_deg: 8.5456, alt_m: 488}}
vehicle: x500
speed_m_s: 6
vehicles:
"""
VEHICLE = """\
  - name: {name}
    home: {{north_m: 0, east_m: {east}}}
    mission:
      - takeoff: {{alt_m: {alt}}}
      - waypoint: {{north_m: 20, east_m: {to_east}, alt_m: {alt}, accept_radius_m: 1.5}}
      - waypoint: {{north_m: 0, east_m: {east}, alt_m: {alt}, accept_radius_m: 1.0}}
      - land: {{}}
    fence:
      - inclusion_circle: {{north_m: 0, east_m: 0, radius_m: 200}}
"""


def _world(tmp_path: Path, name: str, vehicles: list[tuple[str, float, float, float]]) -> Path:
    """A fleet world of (name, pad east_m, drop east_m, alt_m) vehicles, each out 20 m north and back."""
    text = HEAD.format(name=name) + "".join(VEHICLE.format(name=n, east=e, to_east=t, alt=a) for n, e, t, a in vehicles)
    path = tmp_path / f"{name}.yaml"
    path.write_text(text)
    return path


def _up(world: Path, block: int, log_dir: Path, *extra: str) -> subprocess.Popen[bytes]:
    args = [sys.executable, "-m", "quadsitl_cli", "up", "--world", str(world), "--instance", str(block)]
    args += ["--speed", "max", "--log-dir", str(log_dir), "--sim-timeout-s", "30", *extra]
    log = open(log_dir.parent / "up.log", "wb")  # noqa: SIM115 (the child keeps its own copy)
    env = dict(os.environ, PYTHONUNBUFFERED="1")
    return subprocess.Popen(args, cwd=REPO_ROOT, env=env, stdout=log, stderr=subprocess.STDOUT)


def _stop(up: subprocess.Popen[bytes]) -> None:
    if up.poll() is None:
        up.send_signal(signal.SIGTERM)
        try:
            up.wait(timeout=60)
        except subprocess.TimeoutExpired:
            up.kill()
            up.wait()


def _autopilot_pid(parent: int, sys_id: int) -> int:
    out = subprocess.run(["ps", "-o", "pid=", "--ppid", str(parent)], capture_output=True, text=True, check=True)
    for pid in out.stdout.split():
        args = Path(f"/proc/{pid}/cmdline").read_bytes().decode().split("\0")
        if "autopilot" in args and "--sys-id" in args and args[args.index("--sys-id") + 1] == str(sys_id):
            return int(pid)
    raise AssertionError(f"no autopilot child with --sys-id {sys_id}")


def test_one_gcs_port_flies_every_vehicle_and_one_killed_mid_flight_fails_alone(tmp_path: Path) -> None:
    world = _world(tmp_path, "trio", [("alpha", 0, 10, 8), ("bravo", 12, -2, 12), ("charlie", 24, 24, 16)])
    block, log_dir = free_instance_block(3), tmp_path / "logs"
    log_dir.mkdir()
    up = _up(world, block, log_dir, "--api", "off")
    gcs_cmd = [sys.executable, "-u", "-m", "tools.gcs", "--instance", str(block), "fly", str(world)]
    gcs_cmd += ["--stagger-s", "2", "--summary", str(tmp_path / "gcs.json"), "--no-progress", "--timeout-s", "300"]
    gcs = subprocess.Popen(gcs_cmd, cwd=REPO_ROOT, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    lines: list[str] = []
    try:
        assert gcs.stdout is not None
        for line in gcs.stdout:  # charlie (system 3) starts last: kill its autopilot once it flies
            lines.append(line)
            if "charlie: mission started" in line:
                time.sleep(3.0)  # wall: several sim seconds at --speed max, airborne
                os.kill(_autopilot_pid(up.pid, 3), signal.SIGKILL)
                break
        # stop the flight once the ground station is done, not at its exit, as tools.run does (the VM's kernel has
        # held exiting processes for minutes while their flight ran on at full speed)
        deadline = time.monotonic() + 300.0
        while not ground_station_done(gcs, tmp_path / "gcs.json") and time.monotonic() < deadline:
            time.sleep(0.2)
        _stop(up)
        rest, _ = gcs.communicate(timeout=300)
        lines.append(rest)
    finally:
        if gcs.poll() is None:
            gcs.kill()
        _stop(up)
    output = "".join(lines)
    assert gcs.returncode == 1, output
    assert "gcs: error: 1 of 3 vehicles failed: charlie: no telemetry from the vehicle" in output, output
    assert "Traceback" not in output, output
    summary = json.loads((tmp_path / "gcs.json").read_text())
    rows = {row["name"]: row for row in summary["vehicles"]}
    assert [rows[n]["sys_id"] for n in ("alpha", "bravo", "charlie")] == [1, 2, 3]
    for name in ("alpha", "bravo"):  # uploaded to their own system ids, flown, landed while charlie fell
        row, ap = rows[name], read_json(log_dir / name / "autopilot_summary.json")
        assert row["ok"] and row["items_total"] == 5 and row["items_reached"] == ap["items_reached"], (row, ap)
        # every item reached, or passed with its reason: the obstacle sensor sees the other vehicles; one that
        # reports is a track (its detections are fixes, not obstacles), but charlie's wreck stops reporting and is
        # an obstacle once its track ages out, so a waypoint near it can fall inside its safety volume (before the
        # detections were associated with tracks, 1 clean-clone run in 4 bypassed bravo's item 2 around alpha)
        assert ap["items_reached"] + ap["items_bypassed"] == 5 and ap["items_bypassed"] <= 1, ap
        assert all("safety volume" in reason for reason in ap["bypass_reasons"].values()), ap["bypass_reasons"]
    assert not rows["charlie"]["ok"] and 1 <= rows["charlie"]["items_reached"] < 5
    assert summary["min_separation_seen_m"] is not None and summary["stagger_s"] == 2.0
    sim = read_json(log_dir / "sim_summary.json")
    truth = {v["name"]: v for v in sim["vehicles"]}  # type: ignore[union-attr]
    assert truth["charlie"]["autopilot_lost_at_s"] is not None
    assert truth["alpha"]["autopilot_lost_at_s"] is None and truth["alpha"]["contacts"] == []
    assert truth["bravo"]["autopilot_lost_at_s"] is None and truth["bravo"]["contacts"] == []


def test_run_fleet_flies_a_world_end_to_end(tmp_path: Path) -> None:
    world = _world(tmp_path, "pair", [("alpha", 0, 12, 10), ("bravo", 12, 0, 10)])  # their routes cross
    out = tmp_path / "run"
    cmd = [sys.executable, "-m", "tools.run", "--world", str(world), "--out-dir", str(out)]
    cmd += ["--stagger-s", "3", "--timeout-s", "300", "--block-from", str(free_instance_block(2))]
    done = subprocess.run(cmd, cwd=REPO_ROOT, capture_output=True, text=True, timeout=600, check=False)
    assert done.returncode == 0, done.stdout + done.stderr + (out / "up.log").read_text(errors="replace")
    summary = json.loads((out / "summary.json").read_text())
    assert summary["ok"] and [r["name"] for r in summary["vehicles"]] == ["alpha", "bravo"]
    assert all(r["ok"] and r["contacts"] == [] for r in summary["vehicles"])
    assert summary["min_separation_m"] > 0.0 and summary["sim"]["vehicle_contacts"] == 0
    assert (out / "alpha" / "autopilot_summary.json").is_file() and (out / "bravo" / "autopilot_summary.json").is_file()
    assert "fleet min separation" in done.stdout and "alpha      OK" in done.stdout


def test_run_refuses_a_broken_vehicle_entry_in_one_line(tmp_path: Path) -> None:
    world = _world(tmp_path, "broken", [("alpha", 0, 10, 8)])
    world.write_text(world.read_text().replace("takeoff: {alt_m: 8}", "takeoff: {alt_m: high}"))
    cmd = [sys.executable, "-m", "tools.run", "--world", str(world), "--out-dir", str(tmp_path / "r")]
    done = subprocess.run(cmd, cwd=REPO_ROOT, capture_output=True, text=True, timeout=120, check=False)
    assert done.returncode == 2 and not (tmp_path / "r").exists(), done.stderr
    assert done.stderr.count("\n") == 1 and done.stderr.startswith(f"run: error: {world}:"), done.stderr


def test_mavsdk_on_vehicle_2s_api_port_while_the_bundled_client_flies_vehicle_1(tmp_path: Path) -> None:
    python = mavsdk4_python()
    if python is None:
        pytest.fail(MISSING_CLIENT.format(client="mavsdk>=4 is"))
    world = _world(tmp_path, "duo", [("alpha", 0, 0, 8), ("bravo", 40, 40, 8)])
    alpha_plan = load_fleet_missions(world)[0]
    bravo_home = LocalNedFrame(alpha_plan.home).geodetic_from_ned(0.0, 40.0, 0.0)
    sent = [_item_json(item) for item in short_delivery(bravo_home)]  # about bravo's own pad
    (tmp_path / "items.json").write_text(json.dumps(sent))
    block, log_dir = free_instance_block(2), tmp_path / "logs"
    log_dir.mkdir()
    up = _up(world, block, log_dir)
    driver = None
    try:
        with FleetLink(f"udpin:127.0.0.1:{14550 + block}") as link:
            alpha, bravo = link.client(1, timeout_s=20.0), link.client(2, timeout_s=20.0)
            for client in (alpha, bravo):
                client.wait_until(lambda s: s.home is not None, 240.0)
            driver_cmd = [
                python, str(MAVSDK_DRIVER), "--connect", f"udpin://127.0.0.1:{14541 + block}",
                "--items", str(tmp_path / "items.json"), "--result", str(tmp_path / "mavsdk.json"),
                "--set-param", "MIS_RTL_ALT", "12", "--timeout-s", "120",
            ]  # fmt: skip
            with open(tmp_path / "mavsdk.log", "wb") as log:
                driver = subprocess.Popen(driver_cmd, cwd=tmp_path, stdout=log, stderr=subprocess.STDOUT)
            flown = fly(link, [alpha], [alpha_plan], FlyOptions(timeout_s=240.0, progress=False)).vehicles[0].summary
            driver.wait(timeout=150)
            held = bravo.download_mission()  # the bundled client sees bravo's MAVSDK mission on its own system id
    finally:
        if driver is not None and driver.poll() is None:
            driver.kill()
        _stop(up)
    result = read_json(tmp_path / "mavsdk.json")
    assert driver.returncode == 0 and result["ok"], (tmp_path / "mavsdk.log").read_text(errors="replace")
    assert flown.ok and flown.items_reached == flown.items_total == 5, flown
    assert [h.seq for h in held] == [s["seq"] for s in sent]
    assert read_json(log_dir / "alpha" / "autopilot_summary.json")["reached_seqs"] == list(range(5))
    assert read_json(log_dir / "bravo" / "autopilot_summary.json")["reached_seqs"] == list(range(len(sent)))
    assert read_json(log_dir / "sim_summary.json")["vehicle_contacts"] == 0


def _item_json(item: MissionItem) -> dict[str, object]:
    """MISSION_ITEM_INT fields as MAVSDK's MissionRaw takes them (x/y in degE7, seq 0 current)."""
    fields = ("seq", "param1", "param2", "param3", "param4", "z")
    values = dict(
        zip(fields, (item.seq, item.param1, item.param2, item.param3, item.param4, item.z_alt_m), strict=True)
    )
    return {
        **values,
        "frame": int(item.frame),
        "command": int(item.command),
        "current": int(item.seq == 0),
        "autocontinue": int(item.autocontinue),
        "x": round(item.x_lat_deg * 1e7),
        "y": round(item.y_lon_deg * 1e7),
        "mission_type": 0,
    }
