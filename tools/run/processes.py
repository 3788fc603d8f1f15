"""The processes of a run: a free ``--instance`` block for its vehicles, the inputs checked as the simulator and the
autopilot will check them, and ``quadsitl up`` with the ground station's ``fly`` side by side until it is done.

Never hangs: when ``quadsitl up`` exits before the ground station is done (a process died, the lockstep was lost,
the simulator ended the run on a collision) the ground station is stopped too, and a wall-clock limit ends
everything. No child outlives :func:`fly`.
"""

from __future__ import annotations

import contextlib
import json
import os
import socket
import subprocess
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from autopilot.launch_plan import API_LOCAL_PORT, API_PORT, GCS_LOCAL_PORT, GCS_PORT, SIM_PORT
from autopilot.launch_processes import stop_process
from autopilot.mission.files import MissionFileError, load_mission_file
from autopilot.preflight import InputFileError, check_autopilot_inputs
from sim.vehicle_config import VehicleConfigError, load_vehicle
from sim.world import WorldConfigError, load_world

#: Wall seconds the ground station gets to notice a finished flight after ``quadsitl up`` exits.
_GCS_GRACE_S = 2.0
_POLL_S = 0.2


def block_ports(block: int, count: int, api: bool) -> list[int]:
    """The UDP ports ``quadsitl up --instance block`` binds or sends to for ``count`` vehicles (SPEC §3, §13)."""
    ports = [GCS_PORT + block] + [
        base + block + i for base in (SIM_PORT, GCS_LOCAL_PORT, API_LOCAL_PORT) for i in range(count)
    ]
    return [*ports, API_PORT + block] if api else ports


def _ports_free(ports: list[int]) -> bool:
    for port in ports:
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
            try:
                s.bind(("127.0.0.1", port))
            except OSError:
                return False
    return True


def free_block(count: int, api: bool, start: int = 0, limit: int = 400) -> int:
    """The smallest ``--instance`` block >= ``start`` whose ports for ``count`` vehicles are all free."""
    for block in range(start, start + limit, max(count, 1)):
        if _ports_free(block_ports(block, count, api)):
            return block
    raise RuntimeError(f"no free block of {count} quadsitl instances in {start}..{start + limit - 1}")


def check_inputs(world: Path, vehicle: str | None) -> str | None:
    """Every input of the flight checked as the simulator and the autopilot will (None: all fine)."""
    try:
        check_autopilot_inputs(mission=world, vehicle=vehicle)
        if world.suffix.lower() in (".yaml", ".yml"):
            load_world(world)
        load_vehicle(vehicle or load_mission_file(world).vehicle)
    except (InputFileError, WorldConfigError, VehicleConfigError, MissionFileError) as exc:
        return str(exc)
    return None


def read_json(path: Path) -> dict[str, object]:
    """A JSON object from ``path`` ({} when it is missing or not an object)."""
    try:
        data = json.loads(path.read_text())
    except (OSError, ValueError):
        return {}
    return data if isinstance(data, dict) else {}


def tail(path: Path, lines: int = 6) -> list[str]:
    """The last ``lines`` lines of a log ([] when unreadable)."""
    try:
        return path.read_text(errors="replace").splitlines()[-lines:]
    except OSError:
        return []


@dataclass(frozen=True)
class FlightOutcome:
    """How the two child processes ended: the ground station's status (None: it was stopped), ``up``'s, and why."""

    gcs_rc: int | None
    up_rc: int | None
    up_died_first: bool
    timed_out: bool
    interrupted: bool


def ground_station_done(gcs: subprocess.Popen[Any], summary: Path | None) -> bool:
    """The ground station has exited, or has written its ``--summary`` (its last act before it exits): the flight
    it flew may be stopped now."""
    return gcs.poll() is not None or (summary is not None and summary.is_file())


def fly(
    up_cmd: list[str], gcs_cmd: list[str], out_dir: Path, wall_limit_s: float, gcs_summary: Path | None = None
) -> FlightOutcome:
    """Run ``quadsitl up`` (its output to ``out_dir/up.log``) and the ground station side by side until the ground
    station is done.

    The ground station being done stops ``up`` (SIGTERM: every summary is written): its exit, or ``gcs_summary``
    (its ``--summary`` file, written as its last act; removed first if an earlier run left one) appearing, whichever
    comes first, so that a ground-station process slow to exit never leaves the flight running at full speed
    (the 2-core VM's kernel has held exiting processes for minutes, dmesg: ``exit_mmap`` behind ``kdamond``,
    while two such flights kept both CPUs busy). ``up`` ending first gives the ground station ``_GCS_GRACE_S`` and
    then stops it; ``wall_limit_s`` or Ctrl-C stops both.
    """
    env = dict(os.environ, PYTHONUNBUFFERED="1")
    deadline = time.monotonic() + wall_limit_s
    up_died_first = timed_out = interrupted = False
    if gcs_summary is not None:
        gcs_summary.unlink(missing_ok=True)
    with open(out_dir / "up.log", "wb") as up_log:
        up = subprocess.Popen(up_cmd, stdout=up_log, stderr=subprocess.STDOUT, env=env)
        gcs = subprocess.Popen(gcs_cmd, env=env)  # its progress bars and result line go to the terminal
        try:
            while not (done := ground_station_done(gcs, gcs_summary)):
                if time.monotonic() > deadline:
                    timed_out = True
                    break
                if up.poll() is not None:
                    up_died_first = True
                    with contextlib.suppress(subprocess.TimeoutExpired):
                        gcs.wait(timeout=_GCS_GRACE_S)
                    break
                time.sleep(_POLL_S)
            if done:  # the flight is over: stop it now, then let the ground station finish its exit
                stop_process(up)
                with contextlib.suppress(subprocess.TimeoutExpired):
                    gcs.wait(timeout=max(deadline - time.monotonic(), _GCS_GRACE_S))
        except KeyboardInterrupt:
            interrupted = True
        finally:
            gcs_rc = gcs.returncode if gcs.poll() is not None else None
            stop_process(gcs, 10.0)
            up_rc = stop_process(up)
    return FlightOutcome(gcs_rc, up_rc, up_died_first, timed_out, interrupted)
