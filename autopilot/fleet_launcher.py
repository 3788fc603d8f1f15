"""``quadsitl up``: one simulator and one autopilot per vehicle of a fleet world (SPEC §13); else the pair.

A world whose file lists ``vehicles:`` starts one ``python -m sim`` (every vehicle, one lockstep time) and one
``python -m autopilot`` per vehicle, with PX4's multi-vehicle SITL conventions. Instance i of block N
(``--instance N``):

=========  =====================================  ================================================
link       vehicle i listens on (127.0.0.1)       sends to
=========  =====================================  ================================================
sim        14560+N+i (the simulator)              (the autopilot sends there)
GCS        18570+N+i                              14550+N, the same for every vehicle (one GCS sees
                                                  the fleet by system id); ``--gcs-target`` moves it
API        14580+N+i                              14540+N+min(i, 9) (PX4 pins i > 9 to 14549)
=========  =====================================  ================================================

and MAV_SYS_ID i+1. Vehicles 20 and beyond would listen for the simulator where vehicles 0.. listen for their
API, so a fleet of more than 20 vehicles needs ``--api off``; every planned port is checked free before anything
starts. A world without ``vehicles:`` runs ``autopilot.launcher`` (one simulator, one autopilot), unchanged.

When an autopilot exits the others fly on (the simulator drops its vehicle); the run ends when the simulator
exits (``--duration-s``, every autopilot gone) or on SIGINT/SIGTERM, which stops every child. Summaries:
``--log-dir D`` gets the simulator's ``sim_summary.json`` and ``D/<vehicle name>/autopilot_summary.json``.
Each autopilot gets the world as ``--world-failures`` and its name as ``--fleet-vehicle``: it injects the world's
``failures:`` and its own entry's.
"""

from __future__ import annotations

import argparse
import copy
import hashlib
import os
import signal
import subprocess
import sys
import time
import uuid
from dataclasses import dataclass
from pathlib import Path
from types import FrameType
from typing import Any

import yaml

from autopilot import launcher
from autopilot.launcher import EXIT_USAGE, build_parser, stop_process
from autopilot.preflight import InputFileError, check_autopilot_inputs
from mavlink_bridge.contract.about import version_text
from mavlink_bridge.lockstep import DEFAULT_LISTEN_URL
from mavlink_bridge.wire.link import LinkMode, LinkUrl, LinkUrlError, check_ports_free, resolve_url

SIM_PORT = 14560
GCS_LOCAL_PORT = 18570
GCS_PORT = 14550
API_LOCAL_PORT = 14580
API_PORT = 14540
#: PX4: the API link's remote port stops at 14540 + 9 (14549), below the GCS port.
API_PORT_LAST_OFFSET = 9
#: API local ports (14580+i) meet the simulator's (14560+j) at j = i + 20.
MAX_VEHICLES_WITH_API = 20


@dataclass(frozen=True, slots=True)
class VehicleLinks:
    """Where vehicle ``index`` of a fleet listens and sends (host 127.0.0.1 unless ``--listen`` says otherwise)."""

    index: int
    name: str
    airframe: str
    host: str
    sim_port: int
    gcs_local_port: int | None  # None: --gcs off
    gcs_port: int
    api_local_port: int | None  # None: --api off
    api_port: int
    home_ne_m: tuple[float, float] | None = None  # about the world's home; None: given as lat_deg/lon_deg

    @property
    def sys_id(self) -> int:
        return self.index + 1


def fleet_entries(world: str | None) -> list[dict[str, Any]]:
    """The ``vehicles:`` entries of a world file (empty: not a fleet world, or unreadable: the checks say why)."""
    if world is None or not world.endswith((".yaml", ".yml")):
        return []
    try:
        data = yaml.safe_load(Path(world).read_text())
    except (OSError, yaml.YAMLError):
        return []
    entries = data.get("vehicles") if isinstance(data, dict) else None
    return [e for e in entries if isinstance(e, dict)] if isinstance(entries, list) else []


def plan_links(args: argparse.Namespace, entries: list[dict[str, Any]], default_airframe: str) -> list[VehicleLinks]:
    """Every vehicle's ports for the parsed ``up`` options (LinkUrlError for options a fleet cannot take)."""
    for option in ("sim", "api_target"):
        if getattr(args, option) is not None:
            raise LinkUrlError(
                f"--{option.replace('_', '-')}: a fleet world gives each vehicle its own; use --instance N"
            )
    for option in ("gcs", "api"):
        value = getattr(args, option)
        if value is not None and value != "off":
            raise LinkUrlError(f"--{option}: a fleet world gives each vehicle its own ({option} off is allowed)")
    listen = LinkUrl.parse(resolve_url(args.listen, DEFAULT_LISTEN_URL, args.instance))
    if listen.mode is not LinkMode.LISTEN:
        raise LinkUrlError(f"--listen must be udp:HOST:PORT or udpin:HOST:PORT, got {args.listen!r}")
    n, block = len(entries), args.instance
    gcs_port = GCS_PORT + block
    if args.gcs_target is not None:
        target = LinkUrl.parse(args.gcs_target)
        gcs_port = target.port
    api_on = args.api != "off"
    if api_on and n > MAX_VEHICLES_WITH_API:
        raise LinkUrlError(
            f"{n} vehicles: the API links of vehicles 0..{n - MAX_VEHICLES_WITH_API - 1} would take the simulator "
            f"ports of vehicles {MAX_VEHICLES_WITH_API}..{n - 1}; fix: --api off"
        )
    plan = [
        VehicleLinks(
            index=i,
            name=str(e.get("name", f"vehicle{i}")),
            airframe=str(e.get("vehicle") or default_airframe),
            host=listen.host,
            sim_port=listen.port + i,
            gcs_local_port=None if args.gcs == "off" else GCS_LOCAL_PORT + block + i,
            gcs_port=gcs_port,
            api_local_port=API_LOCAL_PORT + block + i if api_on else None,
            api_port=API_PORT + block + min(i, API_PORT_LAST_OFFSET),
            home_ne_m=home_offset_ne_m(e),
        )
        for i, e in enumerate(entries)
    ]
    bound = [p for v in plan for p in (v.sim_port, v.gcs_local_port, v.api_local_port) if p is not None]
    bound += [gcs_port] if args.gcs_target is None else []  # the GCS's own port must stay free for the GCS
    taken = sorted({p for p in bound if bound.count(p) > 1})
    if taken:
        raise LinkUrlError(f"ports {taken} would be used twice by this fleet; fix: another --instance or --listen port")
    return plan


_RECORDING_NAMESPACE = uuid.UUID("6f1d2c3a-9b4e-4f5a-8c7d-0e1f2a3b4c5d")


def fleet_recording_id(world_path: str | Path, seed: int) -> str:
    """The Rerun recording id shared by every part of one fleet run: a UUID of the world file's bytes and the seed."""
    digest = hashlib.sha256(Path(world_path).read_bytes()).hexdigest()
    return str(uuid.uuid5(_RECORDING_NAMESPACE, f"{digest}:{int(seed)}"))


def home_offset_ne_m(entry: dict[str, Any]) -> tuple[float, float] | None:
    """A ``vehicles:`` entry's ``home: {north_m, east_m}`` about the world's home (None: given otherwise)."""
    home = entry.get("home")
    if not isinstance(home, dict) or not ({"north_m", "east_m"} & set(home)):
        return None
    try:
        return float(home.get("north_m", 0.0)), float(home.get("east_m", 0.0))
    except (TypeError, ValueError):
        return None  # the simulator's check refuses the file and says why


def world_rerun_path(spec: str) -> str | None:
    """The simulator's part of a fleet recording, beside the autopilots': ``save:PATH.rrd`` -> ``PATH_world.rrd``."""
    return vehicle_rerun_spec(spec, "world").removeprefix("save:") if spec.startswith("save:") else None


def vehicle_rerun_spec(spec: str, name: str) -> str:
    """A vehicle's ``--rerun``: ``save:PATH.rrd`` becomes ``save:PATH_<name>.rrd`` (one file per autopilot)."""
    if not spec.startswith("save:"):
        return spec
    path = Path(spec.removeprefix("save:"))
    suffix = path.suffix or ".rrd"
    return f"save:{path.with_name(f'{path.stem}_{name}{suffix}')}"


def commands(args: argparse.Namespace, plan: list[VehicleLinks]) -> tuple[list[str], list[list[str]]]:
    """The simulator's command line and one autopilot command line per vehicle."""
    base = copy.copy(args)
    base.vehicle = args.vehicle or plan[0].airframe
    sim, _ = launcher.commands(base)
    recording_id = fleet_recording_id(args.world, args.seed) if args.rerun != "off" else ""
    world_rrd = world_rerun_path(args.rerun)
    if world_rrd is not None:
        sim += ["--recording", world_rrd, "--recording-id", recording_id]
    autopilots = []
    for v in plan:
        one = copy.copy(args)
        one.vehicle, one.instance, one.listen = v.airframe, 0, None
        one.sim = f"udpout:{v.host}:{v.sim_port}"
        one.gcs = "off" if v.gcs_local_port is None else f"udpin:{v.host}:{v.gcs_local_port}"
        one.gcs_target = args.gcs_target or f"udpout:{v.host}:{v.gcs_port}"
        one.api = "off" if v.api_local_port is None else f"udpin:{v.host}:{v.api_local_port}"
        one.api_target = f"udpout:{v.host}:{v.api_port}"
        one.rerun = vehicle_rerun_spec(args.rerun, v.name)
        one.log_dir = str(Path(args.log_dir) / v.name) if args.log_dir else None
        _, ap = launcher.commands(one)
        ap += ["--sys-id", str(v.sys_id)]
        if "--world-failures" in ap:  # the world's failures and this vehicle's own (its vehicles: entry)
            ap += ["--fleet-vehicle", v.name]
        if args.rerun != "off":  # one recording: under its name, about the world's home, the fleet's id
            if v.home_ne_m is None:
                raise LinkUrlError(
                    f"vehicle {v.name}: a fleet recording (--rerun) needs its home as north_m/east_m about the "
                    "world's home; fix: home: {north_m: N, east_m: E}, or --rerun off"
                )
            north_m, east_m = v.home_ne_m
            ap += ["--rerun-fleet", f"{v.name}:{north_m!r}:{east_m!r}:{recording_id}"]
        autopilots.append(ap)
    return sim, autopilots  # the sim's --vehicle is the airframe of entries without their own


def banner(args: argparse.Namespace, plan: list[VehicleLinks]) -> str:
    """What ``quadsitl up`` prints for a fleet: pace, world, and every vehicle's ports as they are."""
    speed = "as fast as possible (--speed max)" if args.speed == "max" else f"{args.speed}x real time"
    lines = [
        f"{version_text('quadsitl up')}: one simulator + {len(plan)} autopilots, {speed}",
        f"  world      {args.world}",
    ]
    for v in plan:
        gcs = "GCS off" if v.gcs_local_port is None else f"GCS from {v.host}:{v.gcs_local_port} to :{v.gcs_port}"
        api = "API off" if v.api_local_port is None else f"API from {v.host}:{v.api_local_port} to :{v.api_port}"
        lines.append(f"  {v.name:<10} sys id {v.sys_id}, {v.airframe}: sim on {v.host}:{v.sim_port}, {gcs}, {api}")
    lines += [
        f"  summaries  {args.log_dir or 'not written (--log-dir DIR)'}",
        "  Ctrl-C stops every process.",
    ]
    return "\n".join(lines)


def _check(args: argparse.Namespace, plan: list[VehicleLinks], sim_cmd: list[str]) -> str | None:
    """The files (simulator check, each airframe) and the ports, before anything starts; the problem or None."""
    problem = launcher.preflight(args, sim_cmd)  # the world (both sides), --params, --script
    if problem is not None:
        return problem
    try:
        for airframe in dict.fromkeys(v.airframe for v in plan):
            check_autopilot_inputs(vehicle=airframe)
    except InputFileError as exc:
        return str(exc)
    urls = [f"udpin:{v.host}:{p}" for v in plan for p in (v.sim_port, v.gcs_local_port, v.api_local_port) if p]
    try:
        check_ports_free(urls)
    except (LinkUrlError, OSError) as exc:
        return str(exc)
    return None


def run_fleet(args: argparse.Namespace, entries: list[dict[str, Any]], spin_given: bool = False) -> int:
    """Start, watch and stop the fleet's processes; the exit status (see ``autopilot.launcher``).

    With more processes than cores and no ``--lockstep-spin-us`` given, nobody spins for the peer's datagram: a
    spinning waiter would hold the core the process it waits for needs."""
    if not spin_given and len(entries) + 1 > (os.cpu_count() or 1):
        args.lockstep_spin_us = 0.0
    try:
        plan = plan_links(args, entries, args.vehicle or launcher.world_vehicle(args.world) or "x500")
        sim_cmd, ap_cmds = commands(args, plan)
    except LinkUrlError as exc:
        print(f"quadsitl up: {exc}", file=sys.stderr)
        return EXIT_USAGE
    problem = _check(args, plan, sim_cmd)
    if problem is not None:
        print(f"quadsitl up: {problem}", file=sys.stderr)
        return EXIT_USAGE
    print(banner(args, plan), flush=True)
    if args.log_dir:
        for v in plan:
            (Path(args.log_dir) / v.name).mkdir(parents=True, exist_ok=True)
    stop = {"signal": 0}

    def _on_signal(signum: int, _frame: FrameType | None) -> None:
        stop["signal"] = signum

    previous = {sig: signal.signal(sig, _on_signal) for sig in (signal.SIGINT, signal.SIGTERM)}
    env = dict(os.environ, PYTHONUNBUFFERED="1")
    sim = subprocess.Popen(sim_cmd, env=env)
    autopilots = [subprocess.Popen(cmd, env=env) for cmd in ap_cmds]
    reported: set[int] = set()
    try:
        while stop["signal"] == 0 and sim.poll() is None:
            for v, proc in zip(plan, autopilots, strict=True):
                if proc.poll() is not None and v.index not in reported:
                    reported.add(v.index)
                    print(f"quadsitl up: {v.name}'s autopilot exited {proc.returncode}; the others fly on", flush=True)
            time.sleep(0.05)
        signalled = stop["signal"] != 0
        if signalled:
            for proc in (*autopilots, sim):
                if proc.poll() is None:
                    proc.send_signal(stop["signal"])
        for proc in autopilots:
            stop_process(proc, signalled=signalled)
        stop_process(sim, signalled=signalled)
    finally:
        for proc in (*autopilots, sim):
            if proc.poll() is None:
                proc.kill()
                proc.wait()
        for sig, handler in previous.items():
            signal.signal(sig, handler)
    codes = ", ".join(f"{v.name} {p.returncode}" for v, p in zip(plan, autopilots, strict=True))
    print(f"quadsitl up: sim exited {sim.returncode}, autopilots exited {codes}", file=sys.stderr)
    rc = sim.returncode
    return 128 - rc if rc < 0 else rc


def main(argv: list[str] | None = None) -> int:
    """``quadsitl up``: a fleet world runs here, any other world through ``autopilot.launcher``."""
    args = build_parser().parse_args(argv)
    entries = fleet_entries(args.world)
    if not entries:
        return launcher.main(argv)
    spin_given = any(a.startswith("--lockstep-spin-us") for a in (sys.argv[1:] if argv is None else argv))
    return run_fleet(args, entries, spin_given)
