"""``quadsitl up``: both processes start, stop together on SIGTERM, and the exit status tells the outcome; one
launcher for one vehicle and a fleet: both print their banner and stop cleanly on SIGINT."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from conftest import REPO_ROOT
from pymavlink import mavutil
from sitl_procs import Ports, free_instance_block, read_json

from mavlink_bridge.gcs_client.client import GcsClient

pytestmark = [pytest.mark.sitl, pytest.mark.slow]


def _up(tmp_path: Path, ports: Ports, *extra: str) -> subprocess.Popen[bytes]:
    args = [sys.executable, "-m", "quadsitl_cli", "up", "--listen", f"udp:127.0.0.1:{ports.sim}", "--api", "off"]
    args += ["--gcs", f"udpin:127.0.0.1:{ports.gcs}", "--gcs-target", f"udpout:127.0.0.1:{ports.gcs_target}"]
    args += ["--log-dir", str(tmp_path), "--speed", "max", *extra]
    with open(tmp_path / "up.log", "wb") as log:  # the child keeps its own copy of the descriptor
        return subprocess.Popen(args, cwd=REPO_ROOT, env=dict(os.environ, PYTHONUNBUFFERED="1"), stdout=log, stderr=log)


def test_up_runs_both_and_stops_both_on_sigterm(tmp_path: Path) -> None:
    ports = Ports.free()
    up = _up(tmp_path, ports)
    try:
        with GcsClient(f"udpin:127.0.0.1:{ports.gcs_target}", timeout_s=20.0) as gcs:
            gcs.wait_until(lambda s: (s.sim_time_s or 0.0) > 1.0, 120.0)  # the lockstep runs
            second_dir = tmp_path / "second"
            second_dir.mkdir()
            second = _up(second_dir, ports)  # the same ports again: refused at once, the first pair undisturbed
            assert second.wait(timeout=60) == 2
            second_log = (second_dir / "up.log").read_text(errors="replace").strip()
            assert f"UDP port {ports.sim} " in second_log and "--instance N" in second_log, second_log
            assert second_log.count("\n") == 0 and not (second_dir / "sim_summary.json").exists()
            before = gcs.telemetry().sim_time_s or 0.0
            gcs.wait_until(lambda s: (s.sim_time_s or 0.0) > before + 1.0, 60.0)  # still flying
        up.send_signal(signal.SIGTERM)
        rc = up.wait(timeout=60)
    finally:
        if up.poll() is None:
            up.kill()
            up.wait()
    log = (tmp_path / "up.log").read_text(errors="replace")
    assert rc == 0, log
    assert read_json(tmp_path / "sim_summary.json")["end_reason"] == "STOPPED"
    assert read_json(tmp_path / "autopilot_summary.json")["frames"] > 250  # type: ignore[operator]


def test_up_exit_status_reports_a_failed_start(tmp_path: Path) -> None:
    ports = Ports.free()
    up = _up(tmp_path, ports, "--vehicle", "no_such_vehicle")
    rc = up.wait(timeout=120)
    assert rc == 2, (tmp_path / "up.log").read_text(errors="replace")


@pytest.mark.parametrize(
    ("world", "names"),
    [("missions/delivery.yaml", []), ("missions/depot_fleet.yaml", ["alpha", "bravo", "charlie", "delta"])],
)
def test_one_vehicle_and_a_fleet_print_their_banner_and_stop_cleanly_on_sigint(
    tmp_path: Path, world: str, names: list[str]
) -> None:
    count = max(len(names), 1)
    block = free_instance_block(count)
    gcs = mavutil.mavlink_connection(f"udpin:127.0.0.1:{14550 + block}", source_system=255)
    args = [sys.executable, "-m", "quadsitl_cli", "up", "--world", world, "--instance", str(block), "--api", "off"]
    args += ["--speed", "max", "--log-dir", str(tmp_path / "logs"), "--sim-timeout-s", "60"]
    log = open(tmp_path / "up.log", "wb")  # noqa: SIM115 (the child keeps its own copy)
    up = subprocess.Popen(args, cwd=REPO_ROOT, env=dict(os.environ, PYTHONUNBUFFERED="1"), stdout=log, stderr=log)
    try:
        flying: set[int] = set()  # the systems whose autopilot reports sim time: the lockstep runs for each
        deadline = time.monotonic() + 180.0
        while len(flying) < count and time.monotonic() < deadline and up.poll() is None:
            msg = gcs.recv_match(type="ATTITUDE", blocking=True, timeout=1.0)
            if msg is not None and msg.time_boot_ms > 1000:
                flying.add(msg.get_srcSystem())
        assert sorted(flying) == list(range(1, count + 1)), (tmp_path / "up.log").read_text(errors="replace")
        up.send_signal(signal.SIGINT)
        rc = up.wait(timeout=90)
    finally:
        if up.poll() is None:
            up.kill()
            up.wait()
        log.close()
        gcs.close()
    text = (tmp_path / "up.log").read_text(errors="replace")
    assert rc == 0, text
    if names:
        assert f"one simulator + {count} autopilots" in text and "Ctrl-C stops every process." in text
        for i, name in enumerate(names):
            assert f"  {name:<10} sys id {i + 1}, x500: sim on 127.0.0.1:{14560 + block + i}" in text
    else:
        assert "simulator + autopilot" in text and f"lockstep on udp 127.0.0.1:{14560 + block}" in text
        assert f"GCS link   listens on 127.0.0.1:{18570 + block}, sends to 127.0.0.1:{14550 + block}" in text
    assert read_json(tmp_path / "logs" / "sim_summary.json")["end_reason"] == "STOPPED"
    for folder in [tmp_path / "logs" / name for name in names] or [tmp_path / "logs"]:
        assert read_json(folder / "autopilot_summary.json")["frames"] > 250  # type: ignore[operator]
