"""``quadsitl up``: the simulator and the autopilot as two processes.

Checks every input file first (mission or world, ``--params``, ``--script``, the vehicle; one line
naming the file, the line and the fix), then starts ``python -m sim`` and ``python -m autopilot`` with
the options of both (``--instance N`` offsets every default port of both; an address given explicitly is
used as typed), checks that every port either will listen on is free (one line naming a taken port and the
fix), prints where they listen, forwards
SIGINT/SIGTERM to them, and when either one exits stops the other. Real time by default, like PX4
SITL (``--speed max``: as fast as the machine goes). Exit status: 0 when both ended cleanly (a signal,
``--duration-s``), else the simulator's non-zero status if it had one (3 autopilot lost, 4 vehicle
ended the run), else the autopilot's; 2 for bad options or input files.
"""

from __future__ import annotations

import argparse
import os
import signal
import subprocess
import sys
import time
from pathlib import Path
from types import FrameType

from autopilot.cli import add_autopilot_options, link_urls
from autopilot.preflight import InputFileError, check_autopilot_inputs
from mavlink_bridge.contract.about import version_text
from mavlink_bridge.lockstep import DEFAULT_LISTEN_URL
from mavlink_bridge.wire.link import LinkMode, LinkUrl, LinkUrlError, check_ports_free, resolve_url
from mavlink_bridge.wire.lossy import loss_fraction

EXIT_USAGE = 2
#: How long a child gets to exit after SIGTERM before it is killed (wall s).
STOP_TIMEOUT_S = 15.0


#: ``quadsitl up``'s default pace: real time, like PX4 SITL (a person flies it from a ground station).
DEFAULT_SPEED = "1"


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="quadsitl up",
        description="Start the simulator and the autopilot as two processes; Ctrl-C stops both.",
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


def preflight(args: argparse.Namespace, sim_cmd: list[str]) -> str | None:
    """Check every input file before anything starts; the one-line error, or None when all are fine."""
    try:
        check_autopilot_inputs(mission=args.world, params=args.params, script=args.script, vehicle=args.vehicle)
        if args.rerun_world and args.rerun_world != args.world:
            check_autopilot_inputs(mission=args.rerun_world)
    except InputFileError as exc:
        return str(exc)
    if args.world is None and args.vehicle is None:
        return None
    env = dict(os.environ, PYTHONUNBUFFERED="1")
    check = subprocess.run([*sim_cmd, "--check"], env=env, capture_output=True, text=True, check=False)
    if check.returncode != 0:
        lines = check.stderr.strip().splitlines()
        return (
            lines[-1].removeprefix("quadsitl sim: ")
            if lines
            else f"the simulator refused the inputs ({check.returncode})"
        )
    return None


def _port_text(url: str) -> str:
    if url == "off":
        return "off"
    link = LinkUrl.parse(url)
    return f"{link.host}:{link.port}"


def listen_urls(args: argparse.Namespace) -> list[str]:
    """Every address the pair will listen on: the sim's lockstep port, the autopilot's GCS and API links."""
    urls = link_urls(args)
    return [resolve_url(args.listen, DEFAULT_LISTEN_URL, args.instance), urls["gcs"], urls["api"]]


def banner(args: argparse.Namespace, vehicle: str) -> str:
    """What ``quadsitl up`` prints at start: speed, ports, world, where the logs go, how to stop."""
    listen = LinkUrl.parse(resolve_url(args.listen, DEFAULT_LISTEN_URL, args.instance))
    urls = link_urls(args)
    speed = "as fast as possible (--speed max)" if args.speed == "max" else f"{args.speed}x real time"
    gcs_in, gcs_out = _port_text(urls["gcs"]), _port_text(urls["gcs_target"])
    api_in, api_out = _port_text(urls["api"]), _port_text(urls["api_target"])
    gcs = "off" if gcs_in == "off" else f"listens on {gcs_in}, sends to {gcs_out} (QGroundControl, tools.gcs)"
    api = "off" if api_in == "off" else f"listens on {api_in}, sends to {api_out} (MAVSDK, scripts)"
    recording = "off (--rerun save:PATH.rrd to record)" if args.rerun == "off" else args.rerun
    lines = [
        f"{version_text('quadsitl up')}: simulator + autopilot, {speed}",
        f"  world      {args.world or 'empty (no --world)'}, vehicle {vehicle}",
        f"  simulator  lockstep on udp {listen.host}:{listen.port}",
        f"  GCS link   {gcs}",
        f"  API link   {api}",
        f"  summaries  {args.log_dir or 'not written (--log-dir DIR)'}",
        f"  recording  {recording}",
        "  Ctrl-C stops both processes.",
    ]
    return "\n".join(lines)


def _world_vehicle(world: str | None) -> str | None:
    """The ``vehicle:`` of a mission YAML (the default airframe of ``up``), if any."""
    if world is None or not world.endswith((".yaml", ".yml")):
        return None
    import yaml

    try:
        data = yaml.safe_load(Path(world).read_text())
    except (OSError, yaml.YAMLError):
        return None
    vehicle = data.get("vehicle") if isinstance(data, dict) else None
    return str(vehicle) if vehicle else None


def commands(args: argparse.Namespace) -> tuple[list[str], list[str]]:
    """The sim and autopilot command lines for parsed ``up`` options (LinkUrlError on a bad URL).

    Both children get ``--instance`` and only the link URLs given here, so each shifts its own defaults and
    uses typed addresses as typed; an explicit ``--listen`` without ``--sim`` makes the autopilot send there.
    """
    listen = LinkUrl.parse(resolve_url(args.listen, DEFAULT_LISTEN_URL, args.instance))
    if listen.mode is not LinkMode.LISTEN:
        raise LinkUrlError(f"--listen must be udp:HOST:PORT or udpin:HOST:PORT, got {args.listen!r}")
    link_urls(args)  # LinkUrlError for a malformed link URL before anything starts
    vehicle = args.vehicle or _world_vehicle(args.world) or "x500"
    py = [sys.executable, "-m"]
    sim = [*py, "sim", "--seed", str(args.seed), "--speed", args.speed, "--instance", str(args.instance)]
    sim += ["--vehicle", vehicle]
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
    ap = [*py, "autopilot", "--instance", str(args.instance), "--vehicle", vehicle]
    sim_url = args.sim or (f"udpout:{listen.host}:{listen.port}" if args.listen is not None else None)
    for option, url in (
        ("--sim", sim_url),
        ("--gcs", args.gcs),
        ("--gcs-target", args.gcs_target),
        ("--api", args.api),
        ("--api-target", args.api_target),
    ):
        if url is not None:
            ap += [option, url]
    ap += ["--rerun", args.rerun, "--estimator", args.estimator, "--speed", args.speed]
    rerun_world = args.rerun_world or (args.world if args.world and args.world.endswith((".yaml", ".yml")) else None)
    if rerun_world and args.rerun != "off":  # drawn in the recording only (the autopilot never plans with it)
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
    if args.world and args.world.endswith((".yaml", ".yml")):  # the world's failures: the autopilot injects them
        ap += ["--world-failures", args.world]
    if args.log_dir:
        sim += ["--log-dir", args.log_dir]
        ap += ["--log-dir", args.log_dir]
    return sim, ap


def stop_process(proc: subprocess.Popen[bytes], timeout_s: float = STOP_TIMEOUT_S, *, signalled: bool = False) -> int:
    """SIGTERM (a clean stop: summaries are written), wait up to ``timeout_s``, then SIGKILL; the exit status.

    ``signalled``: the process was already sent its stop signal; only wait (a second SIGTERM could hit it
    after it restored the default handler during its own shutdown and kill it mid-summary).
    """
    if proc.poll() is None:
        if not signalled:
            proc.send_signal(signal.SIGTERM)
        try:
            proc.wait(timeout=timeout_s)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
    return int(proc.returncode)


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        sim_cmd, ap_cmd = commands(args)
    except LinkUrlError as exc:
        print(f"quadsitl up: {exc}", file=sys.stderr)
        return EXIT_USAGE
    problem = preflight(args, sim_cmd)  # the files first: a typo is the user's to fix whatever the ports
    if problem is not None:
        print(f"quadsitl up: {problem}", file=sys.stderr)
        return EXIT_USAGE
    try:
        check_ports_free(listen_urls(args))
    except (LinkUrlError, OSError) as exc:  # OSError: PortInUseError naming the port and --instance
        print(f"quadsitl up: {exc}", file=sys.stderr)
        return EXIT_USAGE
    print(banner(args, sim_cmd[sim_cmd.index("--vehicle") + 1]), flush=True)
    if args.log_dir:
        Path(args.log_dir).mkdir(parents=True, exist_ok=True)
    stop = {"signal": 0}

    def _on_signal(signum: int, _frame: FrameType | None) -> None:
        stop["signal"] = signum

    previous = {sig: signal.signal(sig, _on_signal) for sig in (signal.SIGINT, signal.SIGTERM)}
    env = dict(os.environ, PYTHONUNBUFFERED="1")
    sim = subprocess.Popen(sim_cmd, env=env)
    autopilot = subprocess.Popen(ap_cmd, env=env)
    ended_first: subprocess.Popen[bytes] | None = None
    try:
        while stop["signal"] == 0 and sim.poll() is None and autopilot.poll() is None:
            time.sleep(0.05)
        ended_first = next((proc for proc in (sim, autopilot) if proc.poll() is not None), None)
        signalled = stop["signal"] != 0
        if signalled:
            for proc in (autopilot, sim):
                if proc.poll() is None:
                    proc.send_signal(stop["signal"])
        # whoever is still running follows the one that ended (the autopilot first: the sim then sums up)
        stop_process(autopilot, signalled=signalled)
        stop_process(sim, signalled=signalled)
    finally:
        for proc in (autopilot, sim):
            if proc.poll() is None:
                proc.kill()
                proc.wait()
        for sig, handler in previous.items():
            signal.signal(sig, handler)
    sim_rc, ap_rc = sim.returncode, autopilot.returncode
    print(f"quadsitl up: sim exited {sim_rc}, autopilot exited {ap_rc}", file=sys.stderr)
    if ended_first is not None and ended_first.returncode != 0:
        rc = ended_first.returncode  # the failure that ended the run, not the stop we sent the other one
    else:
        rc = sim_rc if sim_rc != 0 else ap_rc
    return 128 - rc if rc < 0 else rc  # killed by signal N -> 128 + N, as a shell reports it
