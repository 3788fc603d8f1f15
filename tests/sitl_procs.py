"""Helpers for the loopback SITL tests: start ``python -m sim`` and ``python -m autopilot`` on free ports."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

from conftest import REPO_ROOT, free_udp_port


@dataclass
class Ports:
    """One set of loopback ports: sim lockstep, autopilot GCS link and where it first sends."""

    sim: int
    gcs: int
    gcs_target: int

    @classmethod
    def free(cls) -> Ports:
        return cls(free_udp_port(), free_udp_port(), free_udp_port())


def _popen(args: list[str], log: Path) -> subprocess.Popen[bytes]:
    env = dict(os.environ, PYTHONUNBUFFERED="1")
    with open(log, "wb") as out:
        return subprocess.Popen([sys.executable, "-m", *args], cwd=REPO_ROOT, env=env, stdout=out, stderr=out)


def start_sim(log_dir: Path, port: int, *extra: str) -> subprocess.Popen[bytes]:
    log_dir.mkdir(parents=True, exist_ok=True)
    args = ["sim", "--listen", f"udp:127.0.0.1:{port}", "--speed", "max", "--log-dir", str(log_dir), *extra]
    return _popen(args, log_dir / "sim.log")


def start_autopilot(log_dir: Path, sim_port: int, ports: Ports | None, *extra: str) -> subprocess.Popen[bytes]:
    log_dir.mkdir(parents=True, exist_ok=True)
    args = ["autopilot", "--sim", f"udpout:127.0.0.1:{sim_port}", "--api", "off", "--log-dir", str(log_dir)]
    if ports is None:
        args += ["--gcs", "off"]
    else:
        args += ["--gcs", f"udpin:127.0.0.1:{ports.gcs}", "--gcs-target", f"udpout:127.0.0.1:{ports.gcs_target}"]
    return _popen([*args, *extra], log_dir / "autopilot.log")


def stop(proc: subprocess.Popen[bytes], timeout_s: float = 20.0) -> int:
    """SIGTERM, then wait (kill after ``timeout_s``); the exit status."""
    if proc.poll() is None:
        proc.send_signal(signal.SIGTERM)
        try:
            proc.wait(timeout=timeout_s)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
    return int(proc.returncode)


def read_json(path: Path) -> dict[str, object]:
    return json.loads(path.read_text())


def logs(log_dir: Path) -> str:
    """Both processes' output, for assertion messages."""
    return "\n".join(f"--- {p.name}\n{p.read_text(errors='replace')[-3000:]}" for p in sorted(log_dir.glob("*.log")))
