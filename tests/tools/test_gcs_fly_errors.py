"""``tools.gcs fly`` with a fleet world fails in one line, never a traceback: no fleet heard, a bad stagger."""

from __future__ import annotations

import socket
import subprocess
import sys

from conftest import REPO_ROOT


def _free_udp_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
        sock.bind(("127.0.0.1", 0))
        return int(sock.getsockname()[1])


def _gcs(*args: str) -> subprocess.CompletedProcess[str]:
    cmd = [sys.executable, "-m", "tools.gcs", *args]
    return subprocess.run(cmd, cwd=REPO_ROOT, capture_output=True, text=True, timeout=60, check=False)


def test_no_fleet_heard_is_one_line_naming_the_missing_system_ids() -> None:
    port = _free_udp_port()
    done = _gcs("--connect", f"udpin:127.0.0.1:{port}", "--wait-s", "1", "fly", "missions/depot_fleet.yaml")
    assert done.returncode == 1 and "Traceback" not in done.stderr, done.stderr
    assert done.stderr.strip().splitlines()[-1] == (
        f"gcs: error: no vehicle with system id [1, 2, 3, 4] heard on udpin:127.0.0.1:{port} within 1 s; "
        "fix: start the fleet (quadsitl up --world FILE) with the same --instance"
    )


def test_a_negative_stagger_is_refused_before_listening() -> None:
    done = _gcs("--wait-s", "1", "fly", "missions/depot_fleet.yaml", "--stagger-s", "-2")
    assert (
        done.returncode == 1 and done.stderr.strip() == "gcs: error: --stagger-s must be a finite number >= 0, got -2"
    )
