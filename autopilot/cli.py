"""``quadsitl autopilot`` / ``python -m autopilot``: the autopilot process (SPEC §3, §12).

Links (``--instance N`` adds N to every default port; an address given explicitly is used as typed):

- ``--sim``  lockstep client of the simulator, default ``udpout:127.0.0.1:14560``;
- ``--gcs``  GCS link, default ``udpin:127.0.0.1:18570`` sending to ``127.0.0.1:14550`` until someone
  talks to it, then replying to whoever talks (PX4's "local 18570 → 14550");
- ``--api``  API/offboard link (MAVSDK, scripts), default ``udpin:127.0.0.1:14580`` → ``127.0.0.1:14540``.

``--gcs off`` / ``--api off`` disable a link. ``--signing-key TEXT`` signs everything both links send
(64 hex digits, or any text hashed with SHA-256 as MAVProxy's ``signing setup`` does);
``--require-signing`` also drops every unsigned or wrongly signed message they receive (SPEC §10).

``--rerun-world MISSION.yaml`` is for the *recording only*: the file's route and fence, and its
``world:`` obstacles drawn as the "true" obstacles beside the sensed ones. The autopilot itself
never reads the world: the planner only ever sees the simulator's detections (SPEC §7).

SIGINT/SIGTERM stop the loop cleanly; the
summary is written to ``--log-dir/autopilot_summary.json`` in every case after start-up.
Exit status: 0 stopped by a signal, 3 the simulator was lost or never came, 2 bad options, 1 error.
"""

from __future__ import annotations

import argparse
import logging
import signal
import sys
import time
from pathlib import Path
from types import FrameType

from autopilot.commander.script import CommandScript, ScriptError, load_script, load_world_failures, merged
from autopilot.control.airframe import AirframeError
from autopilot.estimation import DEFAULT_ESTIMATOR, ESTIMATORS
from autopilot.io_loop import Links, run_loop
from autopilot.parameters.store import ParamError
from autopilot.reporting.report import AutopilotEndReason
from autopilot.runner import Autopilot, AutopilotConfig
from autopilot.vehicle_adapter import VehicleAdapter
from mavlink_bridge.contract.about import version_text
from mavlink_bridge.gcs_server.server import GcsServer
from mavlink_bridge.lockstep import LockstepClient, add_spin_option
from mavlink_bridge.wire.link import LinkUrlError, resolve_url
from mavlink_bridge.wire.signing import SigningKeyError, signing_key_from_text

EXIT_OK = 0
EXIT_ERROR = 1
EXIT_USAGE = 2
EXIT_SIM_LOST = 3

DEFAULT_SIM = "udpout:127.0.0.1:14560"
DEFAULT_GCS = "udpin:127.0.0.1:18570"
DEFAULT_GCS_TARGET = "udpout:127.0.0.1:14550"
DEFAULT_API = "udpin:127.0.0.1:14580"
DEFAULT_API_TARGET = "udpout:127.0.0.1:14540"

_log = logging.getLogger("autopilot")


def _speed(text: str) -> float:
    if text == "max":
        return 0.0
    value = float(text)
    if not value > 0.0:
        raise argparse.ArgumentTypeError(f"expected 'max' or a positive number, got {text!r}")
    return value


def add_autopilot_options(p: argparse.ArgumentParser) -> None:
    """The autopilot's options (shared with ``quadsitl up``)."""
    p.add_argument("--sim", default=None, metavar="URL", help=f"simulator address (default {DEFAULT_SIM})")
    p.add_argument("--gcs", default=None, metavar="URL|off", help=f"GCS link (default {DEFAULT_GCS})")
    p.add_argument(
        "--gcs-target",
        default=None,
        metavar="URL",
        help=f"where the GCS link sends first (default {DEFAULT_GCS_TARGET})",
    )
    p.add_argument("--api", default=None, metavar="URL|off", help=f"API link (default {DEFAULT_API})")
    p.add_argument(
        "--api-target",
        default=None,
        metavar="URL",
        help=f"where the API link sends first (default {DEFAULT_API_TARGET})",
    )
    p.add_argument("--params", default=None, metavar="FILE", help="YAML of NAME: value applied at start")
    p.add_argument("--rerun", default="off", metavar="off|save:PATH|connect:URL", help="Rerun telemetry")
    p.add_argument(
        "--rerun-world",
        default=None,
        metavar="MISSION.yaml",
        help="draw this mission's route, fence and true obstacles in the recording (never given to the planner)",
    )
    p.add_argument(
        "--rerun-fleet",
        default=None,
        metavar="NAME:NORTH_M:EAST_M:RECORDING_ID",
        help="record as vehicle NAME of a fleet (quadsitl up sets it): entities under its name, positions about "
        "the world's home (this vehicle's home at NORTH_M, EAST_M), the fleet's shared recording id",
    )
    p.add_argument("--signing-key", default=None, metavar="TEXT", help="MAVLink 2 signing key of the GCS and API links")
    p.add_argument(
        "--require-signing", action="store_true", help="reject unsigned or wrongly signed messages on GCS and API links"
    )
    p.add_argument(
        "--estimator",
        default=DEFAULT_ESTIMATOR,
        choices=sorted(ESTIMATORS),
        help="state estimator: ekf (sensor fusion, default) or truth (the sim's ground truth, controller studies)",
    )
    p.add_argument("--script", default=None, metavar="FILE", help="commands at fixed sim times (YAML)")
    p.add_argument(
        "--world-failures",
        default=None,
        metavar="MISSION.yaml",
        help="inject this file's world: failures: at their sim times (sets SYS_FAILURE_EN 1; up passes its --world)",
    )
    p.add_argument(
        "--fleet-vehicle",
        default=None,
        metavar="NAME",
        help="in a fleet world, the vehicles: entry this autopilot flies: its own failures: are injected too",
    )
    p.add_argument(
        "--sim-timeout-s", type=float, default=3.0, metavar="S", help="wall s of sim silence that ends the run"
    )
    p.add_argument(
        "--connect-timeout-s", type=float, default=60.0, metavar="S", help="wall s to wait for the first frame"
    )
    add_spin_option(p, "the next frame")


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="quadsitl autopilot",
        description="The autopilot: flies the simulator's vehicle (lockstep client) and serves ground stations.",
        epilog="Usually started by 'quadsitl up' together with the simulator. --gcs off / --api off disable a link.",
    )
    p.add_argument("--version", action="version", version=version_text("quadsitl autopilot"))
    add_autopilot_options(p)
    p.add_argument("--instance", type=int, default=0, metavar="N", help="add N to every default port")
    p.add_argument("--vehicle", default="x500", metavar="NAME", help="airframe the controller assumes")
    p.add_argument(
        "--sys-id",
        type=int,
        default=1,
        metavar="ID",
        help="MAV_SYS_ID on every link, 1..254 (default 1; quadsitl up gives a fleet's instance i the id i+1)",
    )
    p.add_argument("--log-dir", type=Path, default=None, metavar="DIR", help="where autopilot_summary.json goes")
    p.add_argument(
        "--speed",
        type=_speed,
        default=0.0,
        metavar="{max|FLOAT}",
        help="the simulator's pace, to scale the ground-station link timeouts (default max)",
    )
    p.add_argument("-v", "--verbose", action="store_true", help="log link and mission events")
    return p


def link_urls(args: argparse.Namespace) -> dict[str, str]:
    """The URL of each link option (``sim``, ``gcs``, ``gcs_target``, ``api``, ``api_target``): as typed when given,
    else its default shifted by ``--instance``; ``off`` stays ``off`` (LinkUrlError for a malformed one)."""
    defaults = {
        "sim": DEFAULT_SIM,
        "gcs": DEFAULT_GCS,
        "gcs_target": DEFAULT_GCS_TARGET,
        "api": DEFAULT_API,
        "api_target": DEFAULT_API_TARGET,
    }
    return {
        name: "off" if getattr(args, name) == "off" else resolve_url(getattr(args, name), default, args.instance)
        for name, default in defaults.items()
    }


def parse_rerun_fleet(text: str) -> tuple[str, tuple[float, float, float], str]:
    """``NAME:NORTH_M:EAST_M:RECORDING_ID`` -> (name, home offset NED m, recording id); ValueError says why."""
    parts = text.split(":", 3)
    try:
        if len(parts) != 4 or not parts[0] or "/" in parts[0] or not parts[3]:
            raise ValueError
        offset = (float(parts[1]), float(parts[2]), 0.0)
    except ValueError:
        raise ValueError(f"--rerun-fleet {text!r}: expected NAME:NORTH_M:EAST_M:RECORDING_ID") from None
    return parts[0], offset, parts[3]


def _make_listener(
    spec: str,
    vehicle: str,
    world: str | None,
    safety_radius_m: float,
    rtl_alt_m: float | None = None,
    fleet: str | None = None,
) -> object | None:
    """The Rerun telemetry listener for ``--rerun`` (None for ``off``); ``world`` is drawn only."""
    if spec == "off":
        return None
    from autopilot.telemetry import make_listener  # imports rerun: only when a recording is asked for

    if fleet is None:
        return make_listener(
            spec, vehicle=vehicle, mission_file=world, safety_radius_m=safety_radius_m, rtl_alt_m=rtl_alt_m
        )
    name, offset, recording_id = parse_rerun_fleet(fleet)
    return make_listener(
        spec,
        vehicle=vehicle,
        safety_radius_m=safety_radius_m,
        rtl_alt_m=rtl_alt_m,
        recording_id=recording_id,
        fleet_name=name,
        home_offset_ned_m=offset,
    )


def _signing_key(args: argparse.Namespace) -> bytes | None:
    """The links' signing key (SigningKeyError for an empty one); ``--require-signing`` needs a key."""
    if args.signing_key is None:
        if args.require_signing:
            raise SigningKeyError("--require-signing needs --signing-key")
        return None
    return signing_key_from_text(args.signing_key)


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    logging.basicConfig(level=logging.INFO if args.verbose else logging.WARNING, format="autopilot %(message)s")
    if args.instance < 0:
        print("quadsitl autopilot: --instance must be >= 0", file=sys.stderr)
        return EXIT_USAGE
    if not 1 <= args.sys_id <= 254:
        print(f"quadsitl autopilot: --sys-id must be 1..254 (MAV_SYS_ID), got {args.sys_id}", file=sys.stderr)
        return EXIT_USAGE
    if args.fleet_vehicle is not None and args.world_failures is None:
        print("quadsitl autopilot: --fleet-vehicle names a vehicle of the --world-failures file", file=sys.stderr)
        return EXIT_USAGE
    config = AutopilotConfig(
        vehicle=args.vehicle,
        estimator=args.estimator,
        params_file=args.params,
        log_dir=str(args.log_dir) if args.log_dir is not None else None,
        speed_factor=args.speed,
        system_id=args.sys_id,
    )
    servers: list[GcsServer] = []
    client: LockstepClient | None = None
    autopilot: Autopilot | None = None
    try:
        urls = link_urls(args)
        failures = load_world_failures(args.world_failures, args.fleet_vehicle) if args.world_failures else []
        steps = merged(load_script(args.script) if args.script else [], failures)
        key = _signing_key(args)
        autopilot = Autopilot(config, script=CommandScript(steps) if steps else None)
        if failures:  # a world that schedules failures asks for them: the injection is enabled
            autopilot.params.set("SYS_FAILURE_EN", 1.0)
        autopilot.listener = _make_listener(  # type: ignore[assignment]
            args.rerun,
            args.vehicle,
            args.rerun_world,
            autopilot.params.get("CA_RSAFE_M"),
            autopilot.params.get("MIS_RTL_ALT"),
            args.rerun_fleet,
        )
        client = LockstepClient(
            urls["sim"],
            sim_lost_timeout_s=args.sim_timeout_s,
            spin_s=args.lockstep_spin_us * 1e-6,
            system_id=args.sys_id,
        )
        vehicle = VehicleAdapter(autopilot)
        for url, target in ((urls["gcs"], urls["gcs_target"]), (urls["api"], urls["api_target"])):
            if url != "off":
                servers.append(
                    GcsServer(
                        url,
                        vehicle,
                        system_id=args.sys_id,
                        speed_factor=args.speed if args.speed > 0.0 else 1.0,
                        default_target_url=target,
                        signing_key=key,
                        require_signing=args.require_signing,
                    )
                )
    except (AirframeError, ParamError, ScriptError, LinkUrlError, OSError, ValueError) as exc:
        # (ValueError covers RerunSpecError, MissionFileError of --rerun-world and SigningKeyError)
        print(f"quadsitl autopilot: {exc}", file=sys.stderr)
        close_listener = getattr(autopilot.listener, "close", None) if autopilot is not None else None
        if close_listener is not None:
            close_listener()
        for server in servers:
            server.close()
        if client is not None:
            client.close()
        return EXIT_USAGE

    stop = {"requested": False}

    def _stop(signum: int, _frame: FrameType | None) -> None:
        stop["requested"] = True

    previous = {sig: signal.signal(sig, _stop) for sig in (signal.SIGINT, signal.SIGTERM)}
    links = ", ".join(f"{name} {urls[key]}" for name, key in (("GCS", "gcs"), ("API", "api")) if urls[key] != "off")
    print(
        f"quadsitl autopilot: {args.vehicle}, simulator at {urls['sim']}{', ' + links if links else ''}; Ctrl-C stops",
        flush=True,
    )
    t0 = time.monotonic()
    try:
        reason = run_loop(
            autopilot, Links(client, servers), lambda: stop["requested"], connect_timeout_s=args.connect_timeout_s
        )
    except Exception:
        _log.exception("autopilot loop failed")
        autopilot.end_reason = reason = AutopilotEndReason.ERROR
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)
        wall_s = time.monotonic() - t0
        autopilot.write_summary(wall_s, lockstep=client.stats.as_dict())
        close = getattr(autopilot.listener, "close", None)
        if close is not None:
            close()
        for server in servers:
            server.close()
        client.close()
    sim_s = autopilot.state.time_us * 1e-6 if autopilot.state is not None else 0.0
    print(f"quadsitl autopilot: {reason.value} after {sim_s:.2f} s sim, {wall_s:.1f} s wall", file=sys.stderr)
    if reason in (AutopilotEndReason.SIM_LOST, AutopilotEndReason.SIM_NEVER_CONNECTED):
        return EXIT_SIM_LOST
    return EXIT_ERROR if reason is AutopilotEndReason.ERROR else EXIT_OK
