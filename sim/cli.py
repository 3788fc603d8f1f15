"""``quadsitl sim`` / ``python -m sim``: the lockstep simulator process (SPEC §12).

One server (``sim.server.SimServer``) for a world of one vehicle and a fleet world alike. Exit status: 0 when
the run completed or was stopped (SIGINT/SIGTERM, ``--duration-s``, ``--end-when-landed``), 3 when the autopilot
vanished (a fleet: every autopilot; AUTOPILOT_LOST), 4 when the vehicle (every vehicle) ended the run (collision,
ground impact, non-finite state), 2 for bad options or files. In every case
after start-up ``--log-dir/sim_summary.json`` is written.
"""

from __future__ import annotations

import argparse
import logging
import signal
import sys
from pathlib import Path
from types import FrameType

from mavlink_bridge.contract.about import version_text
from mavlink_bridge.lockstep import DEFAULT_SIM_PORT, add_spin_option
from mavlink_bridge.wire.link import LinkMode, LinkUrl, LinkUrlError, resolve_url
from mavlink_bridge.wire.lossy import loss_fraction
from sim.end_reason import EndReason
from sim.fleet_world import load_fleet
from sim.server import DEFAULT_VEHICLE, SimConfig, SimServer, SimSetupError, mission_vehicle
from sim.traffic_link import TrafficLinkConfig
from sim.vehicle_config import load_vehicle
from sim.world import load_world

EXIT_OK = 0
EXIT_USAGE = 2
EXIT_AUTOPILOT_LOST = 3
EXIT_VEHICLE_ENDED = 4
DEFAULT_LISTEN = f"udp:127.0.0.1:{DEFAULT_SIM_PORT}"


def _speed(text: str) -> float | None:
    if text == "max":
        return None
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected 'max' or a positive number, got {text!r}") from None
    if not value > 0.0 or value == float("inf"):
        raise argparse.ArgumentTypeError(f"expected 'max' or a positive number, got {text!r}")
    return value


def build_parser() -> argparse.ArgumentParser:
    """The simulator's options: world, vehicle, pace, address, logs, plus run length, rates and test helpers."""
    p = argparse.ArgumentParser(
        prog="quadsitl sim",
        description="The lockstep quadrotor simulator: waits for an autopilot on UDP, then steps the world with it.",
        epilog="Usually started by 'quadsitl up' together with the autopilot.",
    )
    p.add_argument("--version", action="version", version=version_text("quadsitl sim"))
    p.add_argument(
        "--world", type=Path, default=None, metavar="MISSION.yaml", help="mission file whose world: is simulated"
    )
    p.add_argument(
        "--vehicle",
        default=None,
        metavar="NAME",
        help="vehicle config name or YAML path (default: the mission's vehicle:, else x500)",
    )
    p.add_argument("--seed", type=int, default=0, help="seed of sensor noise and gusts")
    p.add_argument(
        "--speed",
        type=_speed,
        default=None,
        metavar="{max|FLOAT}",
        help="sim seconds per wall second: 1 is real time, max (default) as fast as the autopilot answers",
    )
    p.add_argument(
        "--instance",
        type=int,
        default=0,
        metavar="N",
        help="offset of the listen port (14560 + N; a fleet world's vehicle i listens on 14560 + N + i)",
    )
    p.add_argument(
        "--listen",
        default=None,
        metavar="udp:HOST:PORT",
        help=f"lockstep server address (udp: or udpin:; default {DEFAULT_LISTEN}, + --instance), used as typed",
    )
    p.add_argument(
        "--sim-loss",
        type=loss_fraction,
        default=0.0,
        metavar="FRACTION",
        help="drop this share of lockstep datagrams each way, seeded by --seed (to test loss; default 0)",
    )
    link = TrafficLinkConfig()
    for flag, field, kind, what in _TRAFFIC_LINK_FLAGS:
        help_ = f"{what} (default: the world's traffic_link: {field}, else {getattr(link, field):g}; docs/traffic.md)"
        p.add_argument(flag, dest=field, type=kind, default=None, metavar="X", help=help_)
    p.add_argument("--log-dir", type=Path, default=None, metavar="DIR", help="where sim_summary.json is written")
    p.add_argument("--duration-s", type=float, default=None, metavar="S", help="stop after this much sim time")
    p.add_argument(
        "--end-when-landed",
        action="store_true",
        help="end the run (COMPLETED) once every vehicle has been armed and is disarmed on the ground",
    )
    p.add_argument("--physics-hz", type=int, default=1000, metavar="HZ", help="physics rate (default 1000)")
    p.add_argument("--control-hz", type=int, default=250, metavar="HZ", help="lockstep/control rate (default 250)")
    p.add_argument(
        "--autopilot-timeout-s", type=float, default=3.0, help="wall s of silence before AUTOPILOT_LOST (default 3)"
    )
    p.add_argument(
        "--start-timeout-s", type=float, default=None, metavar="S", help="give up waiting for the first HEARTBEAT"
    )
    p.add_argument("--no-sensor-noise", action="store_true", help="noiseless sensors (truth + quantisation)")
    p.add_argument("--truth-log", type=Path, default=None, metavar="PATH.npz", help="truth state at control rate")
    add_spin_option(p, "the answer")
    p.add_argument(
        "--check", action="store_true", help="only check the world and vehicle files, then exit (0 fine, 2 refused)"
    )
    p.add_argument(
        "--recording",
        type=Path,
        default=None,
        metavar="PATH.rrd",
        help="a fleet world: write its traffic and per-pair separations to this Rerun recording (quadsitl up sets it)",
    )
    p.add_argument("--recording-id", default="", metavar="ID", help="the recording id of --recording")
    p.add_argument("-v", "--verbose", action="store_true", help="log lockstep events")
    return p


def check_inputs(args: argparse.Namespace) -> None:
    """Load the world and the vehicle as the server would, without opening a port (ValueError: refused)."""
    if args.world is not None:
        load_world(args.world)
        fleet = load_fleet(args.world)
        default = args.vehicle or mission_vehicle(args.world) or DEFAULT_VEHICLE
        for name in dict.fromkeys(v.vehicle or default for v in fleet.vehicles):
            load_vehicle(name)
    load_vehicle(args.vehicle or mission_vehicle(args.world) or DEFAULT_VEHICLE)


#: ``quadsitl sim`` flags of the traffic link: (flag, TrafficLinkConfig field, type, what it sets).
_TRAFFIC_LINK_FLAGS = (
    ("--traffic-range-m", "adsb_range_m", float, "ADS-B reception range, m (3D)"),
    ("--utm-latency-s", "utm_latency_s", float, "UTM relay latency of a vehicle's own report, s"),
    ("--utm-range-m", "utm_range_m", float, "UTM relay range about the reported position, m (3D)"),
    ("--adsb-nacp", "adsb_nacp", int, "ADS-B position accuracy category of the manned traffic (8..11)"),
    ("--adsb-nacv", "adsb_nacv", int, "ADS-B velocity accuracy category of the manned traffic (1..4)"),
    ("--adsb-latency-s", "adsb_latency_s", float, "ADS-B uncompensated latency, s"),
    ("--adsb-reception", "adsb_reception", float, "probability that a 1 Hz ADS-B report is received"),
    ("--adsb-error-tau-s", "adsb_error_tau_s", float, "correlation time of the ADS-B position error, s (0: white)"),
)


def config_from_args(args: argparse.Namespace) -> SimConfig:
    """Validate the parsed options into a ``SimConfig``; ``--instance`` offsets the default listen port only."""
    if args.instance < 0:
        raise SimSetupError(f"--instance: expected N >= 0, got {args.instance}")
    listen = resolve_url(args.listen, DEFAULT_LISTEN, args.instance)
    url = LinkUrl.parse(listen)
    if url.mode is not LinkMode.LISTEN:
        raise LinkUrlError(f"--listen: the simulator listens, use udp:HOST:PORT or udpin:HOST:PORT, got {args.listen}")
    return SimConfig(
        listen_url=str(url),
        world_path=args.world,
        vehicle=args.vehicle,
        seed=args.seed,
        speed=args.speed,
        duration_s=args.duration_s,
        end_when_landed=args.end_when_landed,
        physics_hz=args.physics_hz,
        control_hz=args.control_hz,
        autopilot_timeout_s=args.autopilot_timeout_s,
        start_timeout_s=args.start_timeout_s,
        sensor_noise=not args.no_sensor_noise,
        truth_log=args.truth_log,
        recording=args.recording,
        recording_id=args.recording_id,
        lockstep_spin_s=args.lockstep_spin_us * 1e-6,
        loss_fraction=args.sim_loss,
        traffic_link=tuple((f, getattr(args, f)) for _, f, _, _ in _TRAFFIC_LINK_FLAGS if getattr(args, f) is not None),
    )


def exit_code(end_reason: str) -> int:
    """Process exit status for an end reason (see module docstring)."""
    if end_reason in (EndReason.COMPLETED.name, EndReason.STOPPED.name):
        return EXIT_OK
    if end_reason == EndReason.AUTOPILOT_LOST.name:
        return EXIT_AUTOPILOT_LOST
    return EXIT_VEHICLE_ENDED


def main(argv: list[str] | None = None) -> int:
    """Run one simulator process; returns the exit status."""
    args = build_parser().parse_args(argv)
    logging.basicConfig(
        level=logging.INFO if args.verbose else logging.WARNING,
        format="sim %(levelname)s %(message)s",
        stream=sys.stderr,
    )
    if args.check:
        try:
            check_inputs(args)
        except (ValueError, OSError) as exc:
            print(f"quadsitl sim: {exc}", file=sys.stderr)
            return EXIT_USAGE
        return EXIT_OK
    try:
        config = config_from_args(args)
        fleet = load_fleet(args.world) if args.world is not None and args.world.is_file() else None
        problem = TrafficLinkConfig.with_overrides(config.traffic_link).problem()
        if problem is not None:
            raise SimSetupError(f"traffic link: {problem}")
        server = SimServer(config, fleet)
    except (ValueError, OSError) as exc:  # refused world/vehicle/options, or the port is taken
        print(f"quadsitl sim: {exc}", file=sys.stderr)
        return EXIT_USAGE

    def _stop(signum: int, _frame: FrameType | None) -> None:
        server.request_stop()

    pace = "as fast as possible" if args.speed is None else f"{args.speed:g}x real time"
    if not server.solo:
        ports = ", ".join(
            f"{v.name} (sys id {v.sys_id}) udp {host}:{port}"
            for v, (host, port) in zip(server.fleet.vehicles, server.local_addresses, strict=True)
        )
        count = len(server.servers)
        print(f"quadsitl sim: {count} vehicles wait for their autopilots: {ports} ({pace}); Ctrl-C stops", flush=True)
    else:
        host, port = server.local_address
        print(f"quadsitl sim: waiting for an autopilot on udp {host}:{port} ({pace}); Ctrl-C stops", flush=True)

    previous = {sig: signal.signal(sig, _stop) for sig in (signal.SIGINT, signal.SIGTERM)}
    try:
        summary = server.run()
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)
    if args.log_dir is not None:
        summary.write(args.log_dir)
    print(
        f"quadsitl sim: {summary.end_reason} after {summary.sim_time_s:.2f} s sim "
        f"({summary.real_time_factor:.1f}x real time)",
        file=sys.stderr,
    )
    return exit_code(summary.end_reason)
