"""``quadsitl up``: both processes start, stop together on SIGTERM, and the exit status tells the outcome."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
from pathlib import Path

import pytest
from conftest import REPO_ROOT
from sitl_procs import Ports, read_json

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
