"""Helpers for the loopback SITL tests: the public launcher (``tools.sitl``) plus what the tests share on top.

``sitl_pair`` is ``tools.sitl.sitl_run`` with the tests' defaults (seed 3, the world's vehicle, a 30 s
autopilot stall tolerated); the lower-level ``Ports``/``start_sim``/``start_autopilot``/``stop`` serve tests
that wire the processes themselves (a lossy proxy in between, a killed autopilot, MAVProxy on the GCS link).
"""

from __future__ import annotations

import subprocess
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from autopilot.launcher import stop_process
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
    "landed_disarmed",
    "logs",
    "read_json",
    "sitl_pair",
    "start_autopilot",
    "start_sim",
    "stop",
    "upload_arm_start",
]


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
