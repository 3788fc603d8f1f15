"""The command lines ``quadsitl up`` starts: one ``python -m sim`` and one ``python -m autopilot`` per vehicle.

The simulator gets ``--instance N`` and ``--listen`` only when typed, so it shifts its own defaults (a fleet world's
simulator listens for vehicle i on its port + i by itself). Each autopilot gets its plan's links
(:mod:`autopilot.launch_plan`), MAV_SYS_ID i+1, the world as ``--world-failures`` (it injects the world's
``failures:``) and the options both sides share. A named vehicle (a ``vehicles:`` entry) also gets ``--fleet-vehicle
NAME`` (its entry's own failures), ``--log-dir D/NAME``, ``--rerun save:PATH_NAME.rrd`` and its place in the fleet's
one recording; the one vehicle of a world without ``vehicles:`` writes to ``D`` and ``PATH`` themselves.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from autopilot.launch_plan import LaunchPlan, VehicleLinks
from autopilot.launch_recording import fleet_recording_id, vehicle_rerun_spec, world_rerun_path
from mavlink_bridge.wire.link import LinkUrlError


def _is_yaml(path: str | None) -> bool:
    return bool(path) and str(path).endswith((".yaml", ".yml"))


def sim_command(args: argparse.Namespace, plan: LaunchPlan) -> list[str]:
    """``python -m sim`` for every vehicle of ``plan`` (``--vehicle``: the airframe of entries without their own)."""
    sim = [sys.executable, "-m", "sim", "--seed", str(args.seed), "--speed", args.speed]
    sim += ["--instance", str(args.instance), "--vehicle", args.vehicle or plan.vehicles[0].airframe]
    if args.listen is not None:
        sim += ["--listen", args.listen]
    if args.sim_loss > 0.0:
        sim += ["--sim-loss", repr(args.sim_loss)]
    if args.world:
        sim += ["--world", args.world]
    if args.duration_s is not None:
        sim += ["--duration-s", str(args.duration_s)]
    if args.physics_hz is not None:
        sim += ["--physics-hz", str(args.physics_hz)]
    if args.control_hz is not None:
        sim += ["--control-hz", str(args.control_hz)]
    if args.no_sensor_noise:
        sim.append("--no-sensor-noise")
    sim += ["--lockstep-spin-us", str(args.lockstep_spin_us)]
    if args.log_dir:
        sim += ["--log-dir", args.log_dir]
    world_rrd = world_rerun_path(args.rerun) if plan.fleet else None
    if world_rrd is not None:
        sim += ["--recording", world_rrd, "--recording-id", fleet_recording_id(args.world, args.seed)]
    return sim


def autopilot_command(args: argparse.Namespace, v: VehicleLinks) -> list[str]:
    """``python -m autopilot`` for vehicle ``v`` (LinkUrlError: a fleet recording without the vehicle's home)."""
    ap = [sys.executable, "-m", "autopilot", "--instance", str(v.instance), "--vehicle", v.airframe]
    links = (("--sim", v.sim), ("--gcs", v.gcs), ("--gcs-target", v.gcs_target), ("--api", v.api))
    for option, url in (*links, ("--api-target", v.api_target)):
        if url is not None:
            ap += [option, url]
    rerun = args.rerun if v.name is None else vehicle_rerun_spec(args.rerun, v.name)
    ap += ["--sys-id", str(v.sys_id), "--rerun", rerun, "--estimator", args.estimator, "--speed", args.speed]
    rerun_world = args.rerun_world or (args.world if _is_yaml(args.world) else None)
    if rerun_world and rerun != "off":  # drawn in the recording only (the autopilot never plans with it)
        ap += ["--rerun-world", rerun_world]
    if args.signing_key is not None:
        ap += ["--signing-key", args.signing_key]
    if args.require_signing:
        ap.append("--require-signing")
    ap += ["--sim-timeout-s", str(args.sim_timeout_s), "--connect-timeout-s", str(args.connect_timeout_s)]
    ap += ["--lockstep-spin-us", str(args.lockstep_spin_us)]
    if args.params:
        ap += ["--params", args.params]
    if args.script:
        ap += ["--script", args.script]
    if _is_yaml(args.world):  # the world's failures (and a named vehicle's own entry's): the autopilot injects them
        ap += ["--world-failures", args.world]
        if v.name is not None:
            ap += ["--fleet-vehicle", v.name]
    if args.log_dir:
        ap += ["--log-dir", args.log_dir if v.name is None else str(Path(args.log_dir) / v.name)]
    if v.name is not None and args.rerun != "off":  # one recording: under its name, about the world's home
        if v.home_ne_m is None:
            raise LinkUrlError(
                f"vehicle {v.name}: a fleet recording (--rerun) needs its home as north_m/east_m about the "
                "world's home; fix: home: {north_m: N, east_m: E}, or --rerun off"
            )
        north_m, east_m = v.home_ne_m
        ap += ["--rerun-fleet", f"{v.name}:{north_m!r}:{east_m!r}:{fleet_recording_id(args.world, args.seed)}"]
    return ap


def commands(args: argparse.Namespace, plan: LaunchPlan) -> tuple[list[str], list[list[str]]]:
    """The simulator's command line and one autopilot command line per vehicle of ``plan``."""
    return sim_command(args, plan), [autopilot_command(args, v) for v in plan.vehicles]
