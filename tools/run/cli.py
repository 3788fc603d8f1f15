"""``python -m tools.run``: fly a mission or a fleet world end to end through simulator, autopilot(s) and ground
station (``make run``: missions/delivery.yaml; ``make run-fleet``: missions/depot_fleet.yaml).

Checks every input first, starts ``quadsitl up --world W`` (``--speed max``) on a free ``--instance`` block, runs
the ground station's ``fly`` on the same file (one vehicle, or every vehicle of a fleet world, ``--stagger-s`` sim
seconds apart), stops every process and prints one summary. Everything lands in ``runs/<timestamp>/`` (a fleet
world: ``runs/fleet-<timestamp>/``; or ``--out-dir``): ``sim_summary.json``, the autopilot's
``autopilot_summary.json`` (a fleet: ``<name>/autopilot_summary.json``), ``gcs_summary.json``, ``summary.json``,
the processes' log ``up.log`` and the Rerun recording (``--rerun``, default ``save:<out-dir>/flight.rrd``; a fleet
writes it in several files, ``flight_<name>.rrd`` per autopilot and ``flight_world.rrd``, one recording id: open
them together with ``rerun <out-dir>/*.rrd``; docs/traffic.md).

Exit status: 0 every vehicle flew its mission and landed with no collision or contact, 1 a flight failed, 2 bad
arguments, 3 the SITL processes died or the wall-clock limit was hit.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from datetime import datetime
from pathlib import Path

from autopilot.estimation import DEFAULT_ESTIMATOR, ESTIMATORS
from autopilot.mission.files import MissionFileError, load_fleet_missions
from tools.run.processes import check_inputs, fly, free_block, read_json
from tools.run.report import error, fleet_min_separation_m, print_fleet, print_mission, problems, vehicle_rows

EXIT_OK = 0
EXIT_FLIGHT_FAILED = 1
EXIT_USAGE = 2
EXIT_SITL_DIED = 3
#: Wall seconds on top of the flight limit for start-up (JIT warm-up) and shutdown.
_STARTUP_MARGIN_S = 120.0
_TIMEOUT_S = {False: 600.0, True: 900.0}  # default wall-clock limit of the flight: one vehicle, a fleet


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="python -m tools.run",
        description="Fly a mission or a fleet world end to end (make run, make run-fleet): simulator, autopilots, "
        "ground station; summary + recording.",
    )
    parser.add_argument(
        "--world",
        "--mission",
        dest="world",
        default="missions/delivery.yaml",
        help="mission file (YAML, .waypoints, .plan) or fleet world (vehicles:)",
    )
    parser.add_argument("--speed", default="max", help="'max' or a real-time factor such as 1 or 10")
    parser.add_argument("--vehicle", default=None, help="vehicle config name (default: the mission's)")
    parser.add_argument("--seed", type=int, default=1, help="seed of sensor noise and gusts (default 1)")
    parser.add_argument(
        "--estimator", default=DEFAULT_ESTIMATOR, choices=sorted(ESTIMATORS), help="state estimator (default: ekf)"
    )
    parser.add_argument("--out-dir", default=None, help="default runs/<timestamp> (a fleet: runs/fleet-<timestamp>)")
    parser.add_argument(
        "--timeout-s", type=float, default=None, help="wall-clock limit for the flight (default 600 s, a fleet 900 s)"
    )
    parser.add_argument("--rerun", default=None, help="override --rerun (default save:<out-dir>/flight.rrd)")
    parser.add_argument("--params", default=None, help="every autopilot's --params FILE (NAME: value pairs or gains)")
    parser.add_argument("--stagger-s", type=float, default=4.0, help="fleet: sim seconds between take-offs (default 4)")
    parser.add_argument(
        "--stall-s", type=float, default=None, help="sim s without progress that fail a vehicle (default: the GCS's)"
    )
    parser.add_argument("--block-from", type=int, default=0, help="search a free --instance block from here")
    return parser


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    world = Path(args.world)
    problem = check_inputs(world, args.vehicle)
    try:
        fleet = [p.name for p in load_fleet_missions(world)] if problem is None else []
    except MissionFileError as exc:
        problem = str(exc)
    if problem is not None:  # before any folder or process: one line naming the file, the line and the fix
        error(problem)
        return EXIT_USAGE
    timeout_s = args.timeout_s if args.timeout_s is not None else _TIMEOUT_S[bool(fleet)]
    stamp = datetime.now().strftime("fleet-%Y%m%d-%H%M%S" if fleet else "%Y%m%d-%H%M%S")
    out_dir = Path(args.out_dir or Path("runs") / stamp)
    rerun = args.rerun or f"save:{out_dir / 'flight.rrd'}"
    try:
        block = free_block(max(len(fleet), 1), api=not fleet, start=args.block_from)
    except RuntimeError as exc:
        error(str(exc))
        return EXIT_SITL_DIED
    out_dir.mkdir(parents=True, exist_ok=True)  # only now: a refused start leaves no empty run folder

    up_cmd = [
        sys.executable, "-m", "quadsitl_cli", "up",
        "--world", str(world), "--seed", str(args.seed), "--speed", args.speed,
        "--instance", str(block), "--log-dir", str(out_dir), "--rerun", rerun, "--estimator", args.estimator,
    ]  # fmt: skip
    up_cmd += ["--api", "off"] if fleet else []  # nobody talks to a fleet's API ports during a run
    up_cmd += ["--vehicle", args.vehicle] if args.vehicle else []
    up_cmd += ["--params", args.params] if args.params else []
    gcs_cmd = [
        sys.executable, "-m", "tools.gcs", "--instance", str(block), "fly", str(world),
        "--summary", str(out_dir / "gcs_summary.json"), "--timeout-s", str(timeout_s),
        "--stagger-s", str(args.stagger_s),
    ]  # fmt: skip
    gcs_cmd += ["--stall-s", str(args.stall_s)] if args.stall_s is not None else []

    what = f"{len(fleet)} vehicles" if fleet else "mission"
    print(f"[run] {world}: {what} -> {out_dir} (instance {block}, speed {args.speed})", flush=True)
    t0 = time.monotonic()
    outcome = fly(up_cmd, gcs_cmd, out_dir, timeout_s + _STARTUP_MARGIN_S, out_dir / "gcs_summary.json")
    wall_s = round(time.monotonic() - t0, 2)

    sim, gcs = read_json(out_dir / "sim_summary.json"), read_json(out_dir / "gcs_summary.json")
    found = problems(outcome, gcs, sim, out_dir)
    recordings = _recordings(rerun, fleet)
    if rerun.startswith("save:") and not recordings:
        found.append(f"no recording written at {rerun[len('save:') :]} (see {out_dir / 'up.log'})")
    summary: dict[str, object] = {"ok": not found, "world" if fleet else "mission": str(world)}
    if fleet:
        summary |= {
            "wall_time_s": wall_s,
            "min_separation_m": fleet_min_separation_m(sim),
            "vehicles": vehicle_rows(gcs, sim),
            "gcs": gcs,
            "sim": sim,
            "autopilots": {name: read_json(out_dir / name / "autopilot_summary.json") for name in fleet},
            "recording": [str(p) for p in recordings],
        }
    else:
        summary |= {
            "out_dir": str(out_dir),
            "wall_time_s": wall_s,
            "gcs": gcs,
            "sim": sim,
            "autopilot": read_json(out_dir / "autopilot_summary.json"),
            "recording": str(recordings[0]) if recordings else None,
        }
    summary |= {"exit_codes": {"gcs": outcome.gcs_rc, "up": outcome.up_rc}, "errors": found}
    (out_dir / "summary.json").write_text(json.dumps(summary, indent=2) + "\n")
    (print_fleet if fleet else print_mission)(summary, found, out_dir)
    if not found:
        return EXIT_OK
    return EXIT_SITL_DIED if outcome.up_died_first or outcome.timed_out or outcome.interrupted else EXIT_FLIGHT_FAILED


def _recordings(rerun: str, fleet: list[str]) -> list[Path]:
    """The recording files written (not empty) for ``--rerun save:PATH``: PATH itself, or a fleet's PATH-stem_*
    files (one per autopilot and the world); [] for any other sink."""
    if not rerun.startswith("save:"):
        return []
    path = Path(rerun[len("save:") :])
    files = sorted(path.parent.glob(f"{path.stem}*{path.suffix}")) if fleet else [path]
    return [p for p in files if p.is_file() and p.stat().st_size > 0]
