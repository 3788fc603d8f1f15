"""Loopback SITL runs for integration tests: the simulator and the autopilot as two processes on free ports.

For a CI suite that tests against the real processes, as the project's own SITL tests do::

    from tools.sitl import sitl_run

    def test_delivery(tmp_path):
        with sitl_run(tmp_path, world=Path("missions/delivery.yaml"), seed=4) as run, run.gcs_client() as gcs:
            gcs.wait_until(lambda s: s.home is not None, 120.0)
            ...  # upload, arm, fly: mavlink_bridge.gcs_client.client.GcsClient
        assert run.sim_summary["collisions"] == 0

``python -m sim`` and ``python -m autopilot`` run with this interpreter at ``--speed max``, bind 127.0.0.1
only, on ports the OS reports free, and write their logs (``sim.log``, ``autopilot.log``) and summaries to
``log_dir``. Leaving the block stops both (SIGTERM, then a kill after ``stop_timeout_s``) and reads their
summaries; :class:`SitlError` carries both logs' tails when either did not exit 0. The simulator waits up to
``autopilot_timeout_s`` for a silent autopilot (a cold numba cache compiles the controller first).
"""

from __future__ import annotations

import json
import os
import socket
import subprocess
import sys
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from autopilot.estimation import DEFAULT_ESTIMATOR
from autopilot.launch_processes import stop_process
from autopilot.mission.files import load_mission_file
from mavlink_bridge.gcs_client.client import GcsClient

REPO_ROOT = Path(__file__).resolve().parent.parent
#: Wall seconds a fresh autopilot may take to be heard: a cold JIT cache compiles the controller first, which
#: takes a minute or more on a loaded 2-core machine.
STARTUP_TIMEOUT_S = 180.0


class SitlError(RuntimeError):
    """A SITL process did not exit cleanly; the message holds the tails of both logs."""


def free_udp_port() -> int:
    """A UDP port on 127.0.0.1 that is free right now."""
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


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
    """``python -m sim`` listening on 127.0.0.1:``port`` at ``--speed max`` (``extra``: more options)."""
    log_dir.mkdir(parents=True, exist_ok=True)
    args = ["sim", "--listen", f"udp:127.0.0.1:{port}", "--speed", "max", "--log-dir", str(log_dir), *extra]
    return _popen(args, log_dir / "sim.log")


def start_autopilot(log_dir: Path, sim_port: int, ports: Ports | None, *extra: str) -> subprocess.Popen[bytes]:
    """``python -m autopilot`` on the sim at ``sim_port``; its GCS link on ``ports`` (None: no GCS link)."""
    log_dir.mkdir(parents=True, exist_ok=True)
    args = ["autopilot", "--sim", f"udpout:127.0.0.1:{sim_port}", "--api", "off", "--log-dir", str(log_dir)]
    if ports is None:
        args += ["--gcs", "off"]
    else:
        args += ["--gcs", f"udpin:127.0.0.1:{ports.gcs}", "--gcs-target", f"udpout:127.0.0.1:{ports.gcs_target}"]
    return _popen([*args, *extra], log_dir / "autopilot.log")


def connect_gcs(url: str, heartbeat_timeout_s: float = STARTUP_TIMEOUT_S) -> GcsClient:
    """A ground-station client on ``url`` that has heard the vehicle (20 s exchange timeouts: a loaded machine)."""
    client = GcsClient(url, timeout_s=20.0)
    try:
        client.wait_heartbeat(heartbeat_timeout_s)
    except BaseException:
        client.close()
        raise
    return client


def logs(log_dir: Path) -> str:
    """The tails of the processes' logs in ``log_dir``, for error messages."""
    return "\n".join(f"--- {p.name}\n{p.read_text(errors='replace')[-3000:]}" for p in sorted(log_dir.glob("*.log")))


def read_json(path: Path) -> dict[str, Any]:
    return json.loads(path.read_text())


@dataclass
class SitlRun:
    """A running sim + autopilot pair: the loopback ports a ground station listens on (GCS link, unless it was
    turned off; API link when asked for) with their pymavlink URLs, the processes, and after the ``sitl_run``
    block their summaries (``sim_summary.json``, ``autopilot_summary.json``)."""

    log_dir: Path
    gcs_port: int | None
    api_port: int | None
    sim: subprocess.Popen[bytes]
    autopilot: subprocess.Popen[bytes]
    sim_summary: dict[str, Any] = field(default_factory=dict)
    autopilot_summary: dict[str, Any] = field(default_factory=dict)

    @property
    def gcs_url(self) -> str | None:
        """``udpin:127.0.0.1:PORT`` where the autopilot's GCS link sends (pymavlink / GcsClient form)."""
        return None if self.gcs_port is None else f"udpin:127.0.0.1:{self.gcs_port}"

    @property
    def api_url(self) -> str | None:
        """``udpin:127.0.0.1:PORT`` where the API link sends (MAVSDK: ``udpin://127.0.0.1:PORT``)."""
        return None if self.api_port is None else f"udpin:127.0.0.1:{self.api_port}"

    def gcs_client(self, heartbeat_timeout_s: float = STARTUP_TIMEOUT_S) -> GcsClient:
        """A ground-station client on the GCS link that has heard the vehicle (20 s exchange timeouts)."""
        if self.gcs_url is None:
            raise ValueError("this run has no GCS link (sitl_run(gcs=False))")
        return connect_gcs(self.gcs_url, heartbeat_timeout_s)


@contextmanager
def sitl_run(
    log_dir: Path,
    world: Path | None = None,
    *,
    vehicle: str | None = None,
    seed: int = 0,
    gcs: bool = True,
    api: bool = False,
    sim_args: Sequence[str] = (),
    autopilot_args: Sequence[str] = (),
    estimator: str = DEFAULT_ESTIMATOR,
    autopilot_timeout_s: float = 30.0,
    stop_timeout_s: float = 20.0,
) -> Iterator[SitlRun]:
    """Start the pair (``world``'s vehicle unless ``vehicle`` is given; ``gcs``/``api``: open those links; the
    autopilot runs ``estimator``, the EKF by default);
    stop both on the way out, read their summaries, and raise :class:`SitlError` if either exited non-zero (see
    the module docstring)."""
    if vehicle is None and world is not None:
        vehicle = load_mission_file(world).vehicle
    ports = Ports.free()
    extra = ["--estimator", estimator, *autopilot_args]  # a later --estimator in autopilot_args wins
    if world is not None and world.suffix in (".yaml", ".yml"):  # its failures: are injected by the autopilot
        extra += ["--world-failures", str(world)]
    api_port = None
    if api:
        api_in, api_port = free_udp_port(), free_udp_port()
        extra += ["--api", f"udpin:127.0.0.1:{api_in}", "--api-target", f"udpout:127.0.0.1:{api_port}"]
    common = ["--vehicle", vehicle] if vehicle is not None else []
    sim_opts = [*(["--world", str(world)] if world is not None else []), *common, "--seed", str(seed)]
    sim_opts += ["--autopilot-timeout-s", f"{autopilot_timeout_s:g}", *sim_args]
    sim = start_sim(log_dir, ports.sim, *sim_opts)
    ap = start_autopilot(log_dir, ports.sim, ports if gcs else None, *common, *extra)
    run = SitlRun(log_dir, ports.gcs_target if gcs else None, api_port, sim, ap)
    try:
        yield run
    finally:
        ap_rc, sim_rc = stop_process(ap, stop_timeout_s), stop_process(sim, stop_timeout_s)
    if (ap_rc, sim_rc) != (0, 0):
        raise SitlError(f"autopilot exited {ap_rc}, sim exited {sim_rc}\n{logs(log_dir)}")
    run.sim_summary = read_json(log_dir / "sim_summary.json")
    run.autopilot_summary = read_json(log_dir / "autopilot_summary.json")
