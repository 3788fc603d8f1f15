"""``quadsitl up``: one simulator and one autopilot per vehicle, as separate processes; a world without
``vehicles:`` is a fleet of one.

Checks every input file first (mission or world, ``--params``, ``--script``, each vehicle's airframe; one line
naming the file, the line and the fix), plans every vehicle's ports (:mod:`autopilot.launch_plan`: ``--instance N``
offsets every default port; an address given explicitly is used as typed), checks that every port a process will
listen on is free (one line naming a taken port and the fix), prints where they listen, then starts the
simulator and the autopilots (:mod:`autopilot.launch_commands`) and supervises them
(:mod:`autopilot.launch_processes`): SIGINT/SIGTERM stop every process; the run ends when the simulator exits or
every autopilot has exited (with one vehicle: when either one exits, the other is stopped); an autopilot of a
fleet that exits leaves the others flying. Real time by default, like PX4 SITL (``--speed max``: as fast as the
machine goes). Exit status: 0 when all ended cleanly (a signal, ``--duration-s``), else the non-zero status of
the process whose exit ended the run, else the simulator's non-zero status (3 autopilot lost, 4 vehicle ended
the run), else an autopilot's; 2 for bad options or input files. ``--log-dir D`` gets the simulator's
``sim_summary.json`` and the autopilot's ``autopilot_summary.json`` (a fleet's: ``D/<vehicle name>/``).
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
from pathlib import Path

from autopilot.cli import add_autopilot_options
from autopilot.launch_commands import commands
from autopilot.launch_plan import LaunchPlan, plan_launch
from autopilot.launch_processes import run_status, supervise
from autopilot.preflight import InputFileError, check_autopilot_inputs
from mavlink_bridge.contract.about import version_text
from mavlink_bridge.lockstep import DEFAULT_LISTEN_URL
from mavlink_bridge.wire.link import LinkMode, LinkUrl, LinkUrlError, check_ports_free
from mavlink_bridge.wire.lossy import loss_fraction

EXIT_USAGE = 2
#: ``quadsitl up``'s default pace: real time, like PX4 SITL (a person flies it from a ground station).
DEFAULT_SPEED = "1"


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="quadsitl up",
        description=(
            "Start the simulator and the autopilot (one per vehicle of a world with vehicles:) as separate "
            "processes; Ctrl-C stops all."
        ),
        epilog="Example: quadsitl up --world missions/delivery.yaml --log-dir runs/me --rerun save:runs/me/flight.rrd",
    )
    p.add_argument("--version", action="version", version=version_text("quadsitl up"))
    p.add_argument(
        "--world", default=None, metavar="MISSION.yaml", help="mission file whose world: (obstacles, wind) is simulated"
    )
    p.add_argument(
        "--vehicle", default=None, metavar="NAME", help="vehicle for both sides (default: the mission's, else x500)"
    )
    p.add_argument("--seed", type=int, default=0, metavar="N", help="seed of sensor noise and gusts (default 0)")
    p.add_argument(
        "--speed",
        default=DEFAULT_SPEED,
        metavar="{max|FLOAT}",
        help="sim seconds per wall second: 1 is real time (default), max as fast as possible",
    )
    p.add_argument("--instance", type=int, default=0, metavar="N", help="add N to every port of both processes")
    p.add_argument(
        "--listen", default=None, metavar="URL", help=f"the simulator's lockstep address (default {DEFAULT_LISTEN_URL})"
    )
    p.add_argument(
        "--sim-loss",
        type=loss_fraction,
        default=0.0,
        metavar="FRACTION",
        help="drop this share of lockstep datagrams each way at the sim, seeded (to test loss; default 0)",
    )
    p.add_argument("--log-dir", default=None, metavar="DIR", help="where both processes write their summaries (JSON)")
    p.add_argument("--duration-s", type=float, default=None, metavar="S", help="stop after this much sim time")
    p.add_argument("--physics-hz", type=int, default=None, metavar="HZ", help="physics rate (default 1000)")
    p.add_argument("--control-hz", type=int, default=None, metavar="HZ", help="lockstep/control rate (default 250)")
    p.add_argument("--no-sensor-noise", action="store_true", help="noiseless sensors (truth plus quantisation)")
    add_autopilot_options(p)
    return p


def check_inputs(args: argparse.Namespace, plan: LaunchPlan, sim_cmd: list[str]) -> str | None:
    """The input files (the world on both sides, ``--params``, ``--script``, each airframe) and then the ports,
    before anything starts; the one-line problem, or None when all are fine."""
    try:
        check_autopilot_inputs(mission=args.world, params=args.params, script=args.script, vehicle=args.vehicle)
        if args.rerun_world and args.rerun_world != args.world:
            check_autopilot_inputs(mission=args.rerun_world)
    except InputFileError as exc:
        return str(exc)
    if args.world is not None or args.vehicle is not None:
        env = dict(os.environ, PYTHONUNBUFFERED="1")
        check = subprocess.run([*sim_cmd, "--check"], env=env, capture_output=True, text=True, check=False)
        if check.returncode != 0:
            lines = check.stderr.strip().splitlines()
            return (
                lines[-1].removeprefix("quadsitl sim: ")
                if lines
                else f"the simulator refused the inputs ({check.returncode})"
            )
    try:
        for airframe in dict.fromkeys(v.airframe for v in plan.vehicles):  # a fleet's entries may name their own
            check_autopilot_inputs(vehicle=airframe)
    except InputFileError as exc:
        return str(exc)
    try:  # the files first: a typo is the user's to fix whatever the ports
        check_ports_free(plan.listen_urls())
    except (LinkUrlError, OSError) as exc:  # OSError: PortInUseError naming the port and --instance
        return str(exc)
    return None


def link_text(url: str, target: str, peer: str) -> str:
    """A GCS/API link as it really is: a ``udpin:`` link listens (and sends to ``target`` until ``peer`` talks),
    a ``udpout:`` link sends to its address from a free local port; ``off`` is off."""
    if url == "off":
        return "off"
    link = LinkUrl.parse(url)
    if link.mode is LinkMode.LISTEN:
        to = LinkUrl.parse(target)
        return f"listens on {link.host}:{link.port}, sends to {to.host}:{to.port} until someone talks ({peer})"
    return f"sends to {link.host}:{link.port} from a free local port ({peer})"


def _speed_text(speed: str) -> str:
    return "as fast as possible (--speed max)" if speed == "max" else f"{speed}x real time"


def banner(args: argparse.Namespace, plan: LaunchPlan) -> str:
    """What ``quadsitl up`` prints at start: speed, world, each vehicle's ports, where the logs go, how to stop."""
    if plan.fleet:
        return _fleet_banner(args, plan)
    vehicle = plan.vehicles[0]
    urls = vehicle.urls()
    gcs = link_text(urls["gcs"], urls["gcs_target"], "QGroundControl, tools.gcs")
    api = link_text(urls["api"], urls["api_target"], "MAVSDK, scripts")
    recording = "off (--rerun save:PATH.rrd to record)" if args.rerun == "off" else args.rerun
    lines = [
        f"{version_text('quadsitl up')}: simulator + autopilot, {_speed_text(args.speed)}",
        f"  world      {args.world or 'empty (no --world)'}, vehicle {vehicle.airframe}",
        f"  simulator  lockstep on udp {plan.listen.host}:{plan.listen.port}",
        f"  GCS link   {gcs}",
        f"  API link   {api}",
        f"  summaries  {args.log_dir or 'not written (--log-dir DIR)'}",
        f"  recording  {recording}",
        "  Ctrl-C stops both processes.",
    ]
    return "\n".join(lines)


def _fleet_banner(args: argparse.Namespace, plan: LaunchPlan) -> str:
    lines = [
        f"{version_text('quadsitl up')}: one simulator + {len(plan.vehicles)} autopilots, {_speed_text(args.speed)}",
        f"  world      {args.world}",
    ]
    for v in plan.vehicles:
        urls = {name: LinkUrl.parse(url) if url != "off" else None for name, url in v.urls().items()}
        gcs, gcs_to, api, api_to = urls["gcs"], urls["gcs_target"], urls["api"], urls["api_target"]
        gcs_text = "GCS off" if gcs is None or gcs_to is None else f"GCS from {gcs.host}:{gcs.port} to :{gcs_to.port}"
        api_text = "API off" if api is None or api_to is None else f"API from {api.host}:{api.port} to :{api_to.port}"
        sim = plan.sim_listen(v).removeprefix("udpin:")
        lines.append(f"  {v.name:<10} sys id {v.sys_id}, {v.airframe}: sim on {sim}, {gcs_text}, {api_text}")
    lines += [f"  summaries  {args.log_dir or 'not written (--log-dir DIR)'}", "  Ctrl-C stops every process."]
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    spin_given = any(a.startswith("--lockstep-spin-us") for a in (sys.argv[1:] if argv is None else argv))
    try:
        plan = plan_launch(args)
        if not spin_given and len(plan.vehicles) + 1 > (os.cpu_count() or 1):
            args.lockstep_spin_us = 0.0  # more processes than cores: a spinning waiter holds the core its peer needs
        sim_cmd, autopilot_cmds = commands(args, plan)
    except LinkUrlError as exc:
        print(f"quadsitl up: {exc}", file=sys.stderr)
        return EXIT_USAGE
    problem = check_inputs(args, plan, sim_cmd)
    if problem is not None:
        print(f"quadsitl up: {problem}", file=sys.stderr)
        return EXIT_USAGE
    print(banner(args, plan), flush=True)
    if args.log_dir:
        for v in plan.vehicles:
            Path(args.log_dir, v.name or "").mkdir(parents=True, exist_ok=True)
    outcome = supervise(sim_cmd, autopilot_cmds, [v.name or "the vehicle" for v in plan.vehicles])
    if plan.fleet:
        codes = ", ".join(f"{v.name} {rc}" for v, rc in zip(plan.vehicles, outcome.autopilot_rcs, strict=True))
        print(f"quadsitl up: sim exited {outcome.sim_rc}, autopilots exited {codes}", file=sys.stderr)
    else:
        print(f"quadsitl up: sim exited {outcome.sim_rc}, autopilot exited {outcome.autopilot_rcs[0]}", file=sys.stderr)
    return run_status(outcome)
