"""``quadsitl up`` with a fleet world (SPEC §13): one simulator, one autopilot per vehicle, PX4's port block; one
pymavlink GCS on one port sees every vehicle by system id; a killed autopilot leaves the others flying."""

from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest
from conftest import REPO_ROOT
from pymavlink import mavutil
from sitl_procs import free_instance_block, read_json, write_fleet_world

pytestmark = [pytest.mark.sitl, pytest.mark.slow]


def _free_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
        sock.bind(("127.0.0.1", 0))
        return int(sock.getsockname()[1])


def test_one_gcs_port_sees_the_whole_fleet_and_a_killed_autopilot_leaves_the_others(tmp_path: Path) -> None:
    world = write_fleet_world(tmp_path, "pair", [("alpha", 0, 0), ("bravo", 0, 8)])
    block, gcs_port = free_instance_block(2), _free_port()
    gcs = mavutil.mavlink_connection(f"udpin:127.0.0.1:{gcs_port}", source_system=255)
    args = [sys.executable, "-m", "quadsitl_cli", "up", "--world", str(world), "--instance", str(block)]
    args += ["--gcs-target", f"udpout:127.0.0.1:{gcs_port}", "--api", "off", "--speed", "max"]
    args += ["--log-dir", str(tmp_path / "logs"), "--sim-timeout-s", "30"]
    log = open(tmp_path / "up.log", "wb")  # noqa: SIM115 (the child keeps its own copy)
    up = subprocess.Popen(args, cwd=REPO_ROOT, env=dict(os.environ, PYTHONUNBUFFERED="1"), stdout=log, stderr=log)
    try:
        seen: dict[int, float] = {}
        relayed = 0
        deadline = time.monotonic() + 120.0
        while len(seen) < 2 and time.monotonic() < deadline and up.poll() is None:
            msg = gcs.recv_match(type=["HEARTBEAT", "UTM_GLOBAL_POSITION", "ADSB_VEHICLE"], blocking=True, timeout=1.0)
            if msg is not None and msg.get_type() != "HEARTBEAT":
                relayed += 1
            elif msg is not None and msg.get_srcComponent() == 1:
                seen[msg.get_srcSystem()] = time.monotonic()
        assert sorted(seen) == [1, 2], (tmp_path / "up.log").read_text(errors="replace")
        before = _sim_time_s(gcs, 1, 5.0)
        assert relayed == 0  # received traffic reports are never re-broadcast (also checked in _sim_time_s)
        banner = (tmp_path / "up.log").read_text(errors="replace")
        assert f"alpha      sys id 1, x500: sim on 127.0.0.1:{14560 + block}" in banner
        assert (
            f"bravo      sys id 2, x500: sim on 127.0.0.1:{14561 + block}, GCS from 127.0.0.1:{18571 + block}" in banner
        )
        # kill bravo's autopilot: alpha's keeps being stepped (its sim time keeps growing on the GCS)
        os.kill(_autopilot_pid(up.pid, "--sys-id", "2"), signal.SIGKILL)
        time.sleep(3.5)  # time waits for bravo for the simulator's 3 s autopilot timeout, then goes on without
        later = _sim_time_s(gcs, 1, 3.0)
        assert later > before + 1.0, (before, later)
        up.send_signal(signal.SIGTERM)
        rc = up.wait(timeout=60)
    finally:
        if up.poll() is None:
            up.kill()
            up.wait()
        log.close()
        gcs.close()
    text = (tmp_path / "up.log").read_text(errors="replace")
    assert rc == 0, text
    summary = read_json(tmp_path / "logs" / "sim_summary.json")
    alpha, bravo = summary["vehicles"]  # type: ignore[misc]
    assert alpha["autopilot_lost_at_s"] is None and bravo["autopilot_lost_at_s"] is not None
    assert read_json(tmp_path / "logs" / "alpha" / "autopilot_summary.json")["frames"] > 250  # type: ignore[operator]


def _sim_time_s(gcs: mavutil.mavfile, sys_id: int, window_s: float = 1.5) -> float:
    """The latest sim time system ``sys_id`` reported (ATTITUDE) in the next ``window_s`` (wall)."""
    latest, end = -1.0, time.monotonic() + window_s
    while time.monotonic() < end:
        msg = gcs.recv_match(type=["ATTITUDE", "UTM_GLOBAL_POSITION", "ADSB_VEHICLE"], blocking=True, timeout=0.2)
        assert msg is None or msg.get_type() == "ATTITUDE", f"a traffic report re-broadcast on the GCS link: {msg}"
        if msg is not None and msg.get_srcSystem() == sys_id:
            latest = max(latest, msg.time_boot_ms / 1000.0)
    assert latest >= 0.0, f"no ATTITUDE from system {sys_id}"
    return latest


def _autopilot_pid(parent: int, *words: str) -> int:
    out = subprocess.run(["ps", "-o", "pid=", "--ppid", str(parent)], capture_output=True, text=True, check=True)
    for pid in out.stdout.split():
        cmd = Path(f"/proc/{pid}/cmdline").read_bytes().split(b"\0")
        args = [a.decode() for a in cmd]
        if "autopilot" in args and " ".join(words) in " ".join(args):
            return int(pid)
    raise AssertionError(f"no autopilot child with {words}")


FLEET_FAILURES = """\
name: pair
home: {lat_deg: 47.3977, lon_deg: 8.5456, alt_m: 488}
world:
  failures: [{at_s: 3, inject: mag_off}]
vehicles:
  - name: alpha
    home: {north_m: 0, east_m: 0}
    failures: [{at_s: 2, inject: motor_off, motor: 2}]
  - name: bravo
    home: {north_m: 0, east_m: 8}
"""


def test_a_vehicles_own_failures_reach_that_vehicle_alone_and_the_worlds_reach_all(tmp_path: Path) -> None:
    world = tmp_path / "pair.yaml"
    world.write_text(FLEET_FAILURES)
    block, gcs_port = free_instance_block(2), _free_port()
    gcs = mavutil.mavlink_connection(f"udpin:127.0.0.1:{gcs_port}", source_system=255)
    args = [sys.executable, "-m", "quadsitl_cli", "up", "--world", str(world), "--instance", str(block)]
    args += ["--gcs-target", f"udpout:127.0.0.1:{gcs_port}", "--api", "off", "--speed", "2", "--duration-s", "6"]
    log = open(tmp_path / "up.log", "wb")  # noqa: SIM115 (the child keeps its own copy)
    up = subprocess.Popen(args, cwd=REPO_ROOT, env=dict(os.environ, PYTHONUNBUFFERED="1"), stdout=log, stderr=log)
    texts: dict[int, list[str]] = {1: [], 2: []}
    try:
        deadline = time.monotonic() + 120.0
        while up.poll() is None and time.monotonic() < deadline:
            msg = gcs.recv_match(type="STATUSTEXT", blocking=True, timeout=0.5)
            if msg is not None and msg.text.startswith("Failure injected"):
                texts[msg.get_srcSystem()].append(msg.text)
        rc = up.wait(timeout=60)
    finally:
        if up.poll() is None:
            up.kill()
            up.wait()
        log.close()
        gcs.close()
    assert rc == 0, (tmp_path / "up.log").read_text(errors="replace")
    assert texts == {
        1: ["Failure injected: motor 2 off (motor output failed", "Failure injected: mag off"],  # 50 chars
        2: ["Failure injected: mag off"],
    }
