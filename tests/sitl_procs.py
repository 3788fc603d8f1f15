"""Helpers for the loopback SITL tests: start ``python -m sim`` and ``python -m autopilot`` on free ports."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

from conftest import REPO_ROOT, free_udp_port

from autopilot.launcher import stop_process
from autopilot.mission.files import load_mission_file
from autopilot.mission.plan import MissionPlan
from mavlink_bridge.gcs_client import CommandFailedError, GcsClient, VehicleStatus
from mavlink_bridge.gcs_types import LandedState, MissionType


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
    return stop_process(proc, timeout_s)


def read_json(path: Path) -> dict[str, object]:
    return json.loads(path.read_text())


def logs(log_dir: Path) -> str:
    """Both processes' output, for assertion messages."""
    return "\n".join(f"--- {p.name}\n{p.read_text(errors='replace')[-3000:]}" for p in sorted(log_dir.glob("*.log")))


@dataclass(frozen=True)
class SitlPair:
    """A running sim + autopilot pair: the processes and where a ground station listens (GCS, API links)."""

    log_dir: Path
    gcs_url: str
    api_url: str | None
    sim: subprocess.Popen[bytes]
    autopilot: subprocess.Popen[bytes]


@contextmanager
def sitl_pair(
    log_dir: Path, world: Path, *, seed: int = 3, api: bool = False, ap_extra: tuple[str, ...] = ()
) -> Iterator[SitlPair]:
    """``python -m sim --world WORLD`` + ``python -m autopilot`` (the mission's vehicle) on free ports.

    Both are stopped on the way out and must exit 0 (AssertionError with both logs otherwise).
    The sim tolerates 30 s autopilot stalls (a loaded machine); ``ap_extra`` goes to the autopilot.
    """
    vehicle = load_mission_file(world).vehicle
    ports = Ports.free()
    extra = list(ap_extra)
    api_url = None
    if api:
        api_in, api_out = free_udp_port(), free_udp_port()
        extra += ["--api", f"udpin:127.0.0.1:{api_in}", "--api-target", f"udpout:127.0.0.1:{api_out}"]
        api_url = f"udpin:127.0.0.1:{api_out}"
    sim_args = ("--world", str(world), "--vehicle", vehicle, "--seed", str(seed), "--autopilot-timeout-s", "30")
    sim = start_sim(log_dir, ports.sim, *sim_args)
    ap = start_autopilot(log_dir, ports.sim, ports, "--vehicle", vehicle, *extra)
    try:
        yield SitlPair(log_dir, f"udpin:127.0.0.1:{ports.gcs_target}", api_url, sim, ap)
    finally:
        ap_rc, sim_rc = stop(ap), stop(sim)
    assert (ap_rc, sim_rc) == (0, 0), logs(log_dir)


#: Wall seconds a fresh autopilot may take to be heard and get a GPS fix: a cold JIT cache compiles the
#: controller first, which takes a minute or more on a loaded 2-core machine.
STARTUP_TIMEOUT_S = 180.0


def connect_gcs(url: str, heartbeat_timeout_s: float = STARTUP_TIMEOUT_S) -> GcsClient:
    """A ground-station client on ``url`` that has heard the vehicle (long exchange timeouts: a loaded machine)."""
    client = GcsClient(url, timeout_s=20.0)
    client.wait_heartbeat(heartbeat_timeout_s)
    return client


def landed_disarmed(status: VehicleStatus) -> bool:
    return not status.armed and status.landed_state is LandedState.ON_GROUND


def upload_arm_start(client: GcsClient, plan: MissionPlan, timeout_s: float = STARTUP_TIMEOUT_S) -> None:
    """Upload mission + fence once the vehicle has a GPS fix and home, arm (retrying while refused), start."""
    client.wait_until(lambda s: s.gps_fix_type >= 3 and s.home is not None, timeout_s)
    client.upload_mission(plan.items, MissionType.MISSION)
    client.upload_mission(plan.fence, MissionType.FENCE)
    deadline = time.monotonic() + timeout_s
    while True:
        try:
            client.arm()
            break
        except CommandFailedError:
            if time.monotonic() > deadline:
                raise
            client.pump(0.5)
    client.start_mission()
