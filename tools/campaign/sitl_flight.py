"""One campaign case as real processes: ``python -m tools.campaign.sitl_flight CASE_DIR [--rerun PATH]``.

The campaign task starts this supervisor in a new session (its own process group) and kills the group at the
case's deadline; a watchdog kills the whole group if the parent (the Dask worker) disappears. A case is a world
of one vehicle or many (``case.json``'s ``fleet``: the world lists ``vehicles:``); ``CASE_DIR/flight.json`` gets
the flight record either way (the simulator's and the autopilot's summaries, the texts, any error).

One vehicle: the supervisor starts the autopilot (``python -m autopilot``, script + resolved params of the case,
a GCS link on free loopback ports), uploads the fence and the mission through the bundled ground-station client
(``mavlink_bridge.gcs_client.client.GcsClient``) *before* the simulator exists, then starts the simulator
(``python -m sim --speed max --duration-s SIM_TIME --end-when-landed``): the lockstep begins with the mission on
board, arm and mission start come from the script at fixed sim times, and the simulator ends the flight at the
first step its vehicle is disarmed on the ground after flying (or when it crashed, or at ``sim_time_s``), so the
whole flight (and its truth hash) is a function of the case's files alone (the same flight as ``inproc``). The
ground station stays on the link to collect STATUSTEXTs (failsafes).

A fleet: the fleet run command (``FLEET_RUN``: one simulator, one autopilot per vehicle, the fleet ground station
arming and starting them ``stagger_s`` apart on the wall clock), its summary folded into the record by
``tools.campaign.fleet_record.record`` (the same world and inputs on a re-flight, not the same bits).
"""

from __future__ import annotations

import argparse
import json
import os
import random
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path
from typing import Any

REPO_ROOT = Path(__file__).resolve().parent.parent.parent
#: The processes a case runs, by module (``python -m``): one vehicle's simulator and autopilot, or a fleet's run.
SIM, AUTOPILOT, FLEET_RUN = "sim", "autopilot", "tools.run"
#: Wall seconds a fleet run keeps for stopping its processes and writing its summary before the case's deadline.
FLEET_STOP_S = 30.0
#: Wall seconds the autopilot may take to answer its GCS link (imports and the cached numba kernels).
STARTUP_S = 120.0
FLIGHT_FILE = "flight.json"
#: ``quadsitl sim``'s status when the vehicle ended the run (collision, ground impact): the summary says why.
SIM_EXIT_VEHICLE_ENDED = 4


def _watch_parent(parent: int) -> None:
    """Kill this process group when ``parent`` (the Dask worker that started us) is gone. Its pid is passed in,
    not read here: a worker killed while this interpreter was still importing would already be replaced."""

    def watch() -> None:
        while True:
            time.sleep(0.5)
            if os.getppid() != parent:
                os.killpg(os.getpgrp(), signal.SIGKILL)

    threading.Thread(target=watch, daemon=True, name="parent-watchdog").start()


#: How often a single-vehicle case is started on new ports when one was taken before it was bound; the words of
#: both errors that say so (the link's "UDP port N on HOST is already in use", the OS's "Address already in use").
PORT_TRIES = 3
PORT_TAKEN = "already in use"


def _free_port() -> int:
    import socket

    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def _start(args: list[str], log: Path) -> subprocess.Popen[bytes]:
    env = dict(os.environ, PYTHONUNBUFFERED="1", PYTHONHASHSEED="0")
    with open(log, "ab") as out:
        return subprocess.Popen([sys.executable, "-m", *args], cwd=REPO_ROOT, env=env, stdout=out, stderr=out)


def _stop(proc: subprocess.Popen[bytes] | None, timeout_s: float = 20.0) -> int | None:
    if proc is None:
        return None
    from autopilot.launch_processes import stop_process

    return stop_process(proc, timeout_s)


def _read(path: Path) -> dict[str, Any]:
    try:
        data = json.loads(path.read_text())
    except (OSError, ValueError):
        return {}
    return data if isinstance(data, dict) else {}


def _tail(path: Path, n: int = 4) -> str:
    try:
        return " | ".join(path.read_text(errors="replace").strip().splitlines()[-n:])
    except OSError:
        return ""


def _wait_for_autopilot(gcs: Any, ap: subprocess.Popen[bytes], case_dir: Path) -> None:
    """Until the autopilot's GCS link is heard; an autopilot that exits (a refused input) ends the wait at once."""
    from mavlink_bridge.gcs_client.errors import GcsTimeoutError

    deadline = time.monotonic() + STARTUP_S
    while True:
        try:
            gcs.wait_heartbeat(1.0)
            return
        except GcsTimeoutError:
            if ap.poll() is not None:
                raise RuntimeError(f"autopilot exited {ap.returncode}: {_tail(case_dir / 'autopilot.log')}") from None
            if time.monotonic() > deadline:
                raise


def fly(case_dir: Path, rerun: str | None = None) -> dict[str, Any]:
    """Fly the case in ``case_dir`` (``case.json`` + the files of :func:`tools.campaign.cases.write_case_files`)."""
    case = json.loads((case_dir / "case.json").read_text())
    return _fly_fleet(case_dir, case) if case.get("fleet") else _fly_one(case_dir, case, rerun)


def _fly_fleet(case_dir: Path, case: dict[str, Any]) -> dict[str, Any]:
    """The fleet run command on the case's world and params; its summary folded into the flight record."""
    from tools.campaign.fleet_record import record

    out = case_dir / "fleet"
    (out / "summary.json").unlink(missing_ok=True)
    args = [
        FLEET_RUN, "--world", str(case_dir / "world.yaml"), "--out-dir", str(out),
        "--stagger-s", f"{case['stagger_s']:g}", "--params", str(case_dir / "params.yaml"), "--rerun", "off",
        "--timeout-s", f"{max(case['deadline_s'] - FLEET_STOP_S, 10.0):g}",
        "--block-from", str(random.randrange(100, 4000)),
    ]  # fmt: skip
    proc = _start(args, case_dir / "fleet.log")
    try:
        rc = proc.wait()
    finally:
        _stop(proc)
    summary = _read(out / "summary.json")
    if not summary:
        return {"error": f"{FLEET_RUN} exited {rc}: {_tail(case_dir / 'fleet.log', 3)}", "sim": {}, "autopilot": {}}
    return record(summary)


def _fly_one(case_dir: Path, case: dict[str, Any], rerun: str | None) -> dict[str, Any]:
    """One vehicle on free loopback ports, flown again on new ones (up to ``PORT_TRIES`` times) when a port was taken
    between choosing it and binding it: the simulator binds its port seconds after it is chosen (after the autopilot
    has started and taken the mission), and any socket on the machine may get it meanwhile as its ephemeral port.
    The flight is a function of the case's files, so flying it again gives the same one."""
    for _ in range(PORT_TRIES):
        flight = _fly_one_on_free_ports(case_dir, case, rerun)
        if PORT_TAKEN not in flight["error"]:
            break
    return flight


def _fly_one_on_free_ports(case_dir: Path, case: dict[str, Any], rerun: str | None) -> dict[str, Any]:
    """One vehicle: autopilot, mission upload, then the simulator (see the module docstring)."""
    from autopilot.mission.files import load_mission_file
    from mavlink_bridge.contract.vehicle_api import MissionType
    from mavlink_bridge.gcs_client.client import GcsClient

    world = case_dir / "world.yaml"
    sim_port, gcs_port, gcs_target = _free_port(), _free_port(), _free_port()
    ap_args = [
        AUTOPILOT, "--sim", f"udpout:127.0.0.1:{sim_port}", "--api", "off",
        "--gcs", f"udpin:127.0.0.1:{gcs_port}", "--gcs-target", f"udpout:127.0.0.1:{gcs_target}",
        "--vehicle", case["vehicle"], "--estimator", case["estimator"], "--params", str(case_dir / "params.yaml"),
        "--script", str(case_dir / "script.yaml"), "--world-failures", str(world), "--log-dir", str(case_dir),
        "--connect-timeout-s", str(STARTUP_S),
        "--sim-timeout-s", "30",
    ]  # fmt: skip
    if rerun:
        ap_args += ["--rerun", rerun, "--rerun-world", str(world)]
    sim_args = [
        SIM, "--listen", f"udp:127.0.0.1:{sim_port}", "--world", str(world), "--vehicle", case["vehicle"],
        "--seed", str(case["sim_seed"]), "--speed", "max", "--duration-s", f"{case['sim_time_s']!r}",
        "--end-when-landed", "--log-dir", str(case_dir), "--autopilot-timeout-s", "30",
        "--start-timeout-s", str(STARTUP_S),
    ]  # fmt: skip
    for stale in ("sim_summary.json", "autopilot_summary.json"):
        (case_dir / stale).unlink(missing_ok=True)
    texts: list[str] = []
    error = ""
    ap = sim = None
    gcs = None
    try:
        ap = _start(ap_args, case_dir / "autopilot.log")
        plan = load_mission_file(world)
        gcs = GcsClient(f"udpin:127.0.0.1:{gcs_target}", timeout_s=20.0)
        _wait_for_autopilot(gcs, ap, case_dir)
        gcs.upload_mission(plan.fence, MissionType.FENCE)  # first: the mission is checked against it
        gcs.upload_mission(plan.items, MissionType.MISSION)
        serial = gcs.statustext_serial
        sim = _start(sim_args, case_dir / "sim.log")
        while sim.poll() is None:
            gcs.pump(0.2)
            texts += [t.text for t in gcs.statustexts_since(serial)]
            serial = gcs.statustext_serial
            if ap.poll() is not None:
                error = f"autopilot exited {ap.returncode} during the flight: {_tail(case_dir / 'autopilot.log')}"
                break
        gcs.pump(0.3)  # the last texts
        texts += [t.text for t in gcs.statustexts_since(serial)]
    except Exception as exc:
        error = f"{type(exc).__name__}: {exc}"
    finally:
        sim_rc = _stop(sim)
        ap_rc = _stop(ap)
        if gcs is not None:
            gcs.close()
    if not error and sim_rc not in (0, SIM_EXIT_VEHICLE_ENDED, None):  # a crash is a flight, not an error
        error = f"sim exited {sim_rc}: {_tail(case_dir / 'sim.log')}"
    sim_summary = _read(case_dir / "sim_summary.json")
    if not error and not sim_summary:
        error = f"the simulator wrote no summary: {_tail(case_dir / 'sim.log')}"
    return {
        "error": error,
        "sim": sim_summary,
        "autopilot": _read(case_dir / "autopilot_summary.json"),
        "texts": texts,
        "exit_codes": {"sim": sim_rc, "autopilot": ap_rc},
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m tools.campaign.sitl_flight", description=__doc__.split("\n")[0])
    parser.add_argument("case_dir", type=Path)
    parser.add_argument("--rerun", default=None, help="autopilot --rerun (e.g. save:PATH.rrd)")
    parser.add_argument("--parent-pid", type=int, default=None, help="kill the flight when this process is gone")
    args = parser.parse_args(argv)
    _watch_parent(args.parent_pid if args.parent_pid is not None else os.getppid())
    signal.signal(signal.SIGTERM, lambda *_: sys.exit(143))  # run the finally blocks: children stopped
    t0 = time.monotonic()
    result = fly(args.case_dir, args.rerun)
    result["wall_s"] = time.monotonic() - t0
    (args.case_dir / FLIGHT_FILE).write_text(json.dumps(result, indent=1) + "\n")
    return 0 if not result["error"] else 1


if __name__ == "__main__":
    sys.exit(main())
