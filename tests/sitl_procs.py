"""Helpers for the loopback SITL tests: the public launcher (``tools.sitl``) plus what the tests share on top.

``sitl_pair`` is ``tools.sitl.sitl_run`` with the tests' defaults (seed 3, the world's vehicle, a 30 s
autopilot stall tolerated); the lower-level ``Ports``/``start_sim``/``start_autopilot``/``stop`` serve tests
that wire the processes themselves (a lossy proxy in between, a killed autopilot, MAVProxy on the GCS link).
The world builders write the tests' YAML worlds: ``fence_world_yaml`` one x500 flying a mission inside a fence,
``write_fleet_world`` a fleet of pads about one home; ``free_instance_block`` finds a ``--instance`` offset whose
fleet ports are all free.
"""

from __future__ import annotations

import random
import socket
import subprocess
import time
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path

from autopilot.launch_processes import stop_process
from autopilot.mission.plan import MissionPlan
from mavlink_bridge.contract.vehicle_api import LandedState, MissionType
from mavlink_bridge.gcs_client.client import CommandFailedError, GcsClient, VehicleStatus
from tools.sitl import (
    STARTUP_TIMEOUT_S,
    Ports,
    SitlRun,
    connect_gcs,
    logs,
    read_json,
    sitl_run,
    start_autopilot,
    start_sim,
)

__all__ = [
    "STARTUP_TIMEOUT_S",
    "Ports",
    "SitlRun",
    "connect_gcs",
    "fence_world_yaml",
    "free_instance_block",
    "landed_disarmed",
    "logs",
    "read_json",
    "sitl_pair",
    "start_autopilot",
    "start_sim",
    "stop",
    "upload_arm_start",
    "write_fleet_world",
]

#: The single-vehicle tests' home (Hangzhou) and the fleet tests' (PX4's default SITL home, Zurich), as YAML.
WORLD_HOME_YAML = "{lat_deg: 30.2635, lon_deg: 120.1233, alt_m: 12.0}"
FLEET_HOME_YAML = "{lat_deg: 47.3977, lon_deg: 8.5456, alt_m: 488}"
#: The launcher's per-vehicle port bases (+N+i; autopilot/launch_plan.py) and the one GCS port (+N).
_FLEET_PORT_BASES = (14560, 18570, 14580, 14540)
_FLEET_GCS_PORT = 14550


def stop(proc: subprocess.Popen[bytes], timeout_s: float = 20.0) -> int:
    """SIGTERM, then wait (kill after ``timeout_s``); the exit status."""
    return stop_process(proc, timeout_s)


@contextmanager
def sitl_pair(
    log_dir: Path, world: Path, *, seed: int = 3, api: bool = False, ap_extra: tuple[str, ...] = ()
) -> Iterator[SitlRun]:
    """``tools.sitl.sitl_run`` of ``world`` (its vehicle) with ``seed``; ``ap_extra`` goes to the autopilot.
    Both processes must exit 0 (``SitlError`` with both logs otherwise)."""
    with sitl_run(log_dir, world, seed=seed, api=api, autopilot_args=ap_extra) as run:
        yield run


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


def fence_world_yaml(
    name: str,
    *,
    mission: Sequence[str],
    fence: Sequence[str],
    speed_m_s: float | None = None,
    world: Sequence[str] = (),
) -> str:
    """A one-vehicle world at the tests' home: an x500 flying ``mission`` inside ``fence`` (both YAML list items,
    e.g. ``"takeoff: {alt_m: 10}"``); ``world`` lines go under ``world:`` (nested lines indented by the caller)."""
    lines = [f"name: {name}", f"home: {WORLD_HOME_YAML}", "vehicle: x500"]
    lines += [f"speed_m_s: {speed_m_s}"] if speed_m_s is not None else []
    lines += ["mission:", *(f"  - {item}" for item in mission), "fence:", *(f"  - {area}" for area in fence)]
    lines += ["world:", *(f"  {line}" for line in world)] if world else []
    return "\n".join(lines) + "\n"


def write_fleet_world(folder: Path, name: str, pads: Sequence[tuple[str, float, float]], extra: str = "") -> Path:
    """``folder/NAME.yaml``: a fleet world of ``(vehicle name, north_m, east_m)`` pads about the fleet home, with
    ``extra`` (top-level YAML such as a ``traffic:`` block) appended; its path."""
    lines = [f"name: {name}", f"home: {FLEET_HOME_YAML}", "vehicles:"]
    for vehicle, north_m, east_m in pads:
        lines += [f"  - name: {vehicle}", f"    home: {{north_m: {north_m:g}, east_m: {east_m:g}}}"]
    path = folder / f"{name}.yaml"
    path.write_text("\n".join(lines) + "\n" + extra)
    return path


def free_instance_block(count: int) -> int:
    """A ``--instance`` offset N whose ports for ``count`` vehicles (sim, GCS link, API link and API: base+N+i;
    the GCS: 14550+N) are all free on 127.0.0.1."""
    for _ in range(50):
        block = random.randrange(1000, 9000)
        ports = [base + block + i for base in _FLEET_PORT_BASES for i in range(count)] + [_FLEET_GCS_PORT + block]
        try:
            for port in ports:
                with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
                    sock.bind(("127.0.0.1", port))
        except OSError:
            continue
        return block
    raise RuntimeError("no free port block")
