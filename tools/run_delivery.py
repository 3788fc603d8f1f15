"""``make run``: fly the default delivery mission end to end through sim + autopilot + ground station.

Starts ``quadsitl up`` (simulator and autopilot as two processes, ``--speed max``) on a free
``--instance``, runs the ground-station script's ``fly`` on the mission, stops both processes,
and prints one summary. Everything lands in ``runs/<timestamp>/`` (or ``--out-dir``):
``flight.rrd`` (Rerun recording), ``sim_summary.json``, ``autopilot_summary.json``,
``gcs_summary.json``, ``summary.json`` and the processes' log ``up.log``.

Never hangs: when ``quadsitl up`` exits before the ground station is done (a process died, the
lockstep was lost) the ground station is stopped too, and a wall-clock limit ends everything.
Exit status: 0 the mission flew and landed with no collision, 1 the flight failed, 2 bad
arguments, 3 the SITL processes died or the wall-clock limit was hit.

Usage: ``python -m tools.run_delivery [--mission missions/delivery.yaml] [--speed max|N]
[--vehicle NAME] [--seed N] [--out-dir DIR] [--timeout-s S] [--rerun off|save:PATH|connect:URL]``.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import socket
import subprocess
import sys
import time
from dataclasses import dataclass
from datetime import datetime
from pathlib import Path

from autopilot.estimation import DEFAULT_ESTIMATOR, ESTIMATORS
from autopilot.launch_processes import stop_process
from autopilot.mission.files import MissionFileError, load_mission_file
from autopilot.preflight import InputFileError, check_autopilot_inputs
from sim.vehicle_config import VehicleConfigError, load_vehicle
from sim.world import WorldConfigError, load_world

EXIT_OK = 0
EXIT_FLIGHT_FAILED = 1
EXIT_USAGE = 2
EXIT_SITL_DIED = 3
# Default ports of SPEC §3; --instance N offsets every one of them by N.
_BASE_PORTS = (14560, 18570, 14550, 14580, 14540)
#: Wall seconds the ground station gets to notice a finished flight after ``quadsitl up`` exits.
_GCS_GRACE_S = 5.0
#: Wall seconds on top of the flight limit for start-up (JIT warm-up) and shutdown.
_STARTUP_MARGIN_S = 120.0
_POLL_S = 0.2


def _ports_free(instance: int) -> bool:
    for port in _BASE_PORTS:
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
            try:
                s.bind(("127.0.0.1", port + instance))
            except OSError:
                return False
    return True


def free_instance(start: int = 0, limit: int = 200) -> int:
    """The smallest instance number >= start whose ports are all free on 127.0.0.1."""
    for instance in range(start, start + limit):
        if _ports_free(instance):
            return instance
    raise RuntimeError(f"no free quadsitl instance in {start}..{start + limit - 1}")


def check_inputs(mission: Path, vehicle: str | None) -> str | None:
    """Every input of the flight checked as the simulator and the autopilot will (None: all fine)."""
    try:
        check_autopilot_inputs(mission=mission, vehicle=vehicle)
        if mission.suffix.lower() in (".yaml", ".yml"):
            load_world(mission)
        load_vehicle(vehicle or load_mission_file(mission).vehicle)
    except (InputFileError, WorldConfigError, VehicleConfigError, MissionFileError) as exc:
        return str(exc)
    return None


def _read_json(path: Path) -> dict[str, object]:
    try:
        data = json.loads(path.read_text())
    except (OSError, ValueError):
        return {}
    return data if isinstance(data, dict) else {}


def _tail(path: Path, lines: int = 6) -> list[str]:
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


def fly(up_cmd: list[str], gcs_cmd: list[str], out_dir: Path, wall_limit_s: float) -> FlightOutcome:
    """Run ``quadsitl up`` and the ground station side by side until the ground station is done.

    The ground station ending stops ``up`` (SIGTERM: both summaries are written); ``up`` ending
    first gives the ground station ``_GCS_GRACE_S`` and then stops it; ``wall_limit_s`` or
    Ctrl-C stops both. No child outlives this call.
    """
    env = dict(os.environ, PYTHONUNBUFFERED="1")
    deadline = time.monotonic() + wall_limit_s
    up_died_first = timed_out = interrupted = False
    with open(out_dir / "up.log", "wb") as up_log:
        up = subprocess.Popen(up_cmd, stdout=up_log, stderr=subprocess.STDOUT, env=env)
        gcs = subprocess.Popen(gcs_cmd, env=env)  # its progress bar and result line go to the terminal
        try:
            while gcs.poll() is None:
                if time.monotonic() > deadline:
                    timed_out = True
                    break
                if up.poll() is not None:
                    up_died_first = True
                    with contextlib.suppress(subprocess.TimeoutExpired):
                        gcs.wait(timeout=_GCS_GRACE_S)
                    break
                time.sleep(_POLL_S)
        except KeyboardInterrupt:
            interrupted = True
        finally:
            gcs_rc = gcs.returncode if gcs.poll() is not None else None
            stop_process(gcs, 10.0)
            up_rc = stop_process(up)
    return FlightOutcome(gcs_rc, up_rc, up_died_first, timed_out, interrupted)


def _problems(outcome: FlightOutcome, gcs: dict[str, object], sim: dict[str, object], out_dir: Path) -> list[str]:
    """One line per thing that went wrong (empty: a good flight)."""
    lines: list[str] = []
    if outcome.interrupted:
        lines.append("interrupted (Ctrl-C): both processes stopped")
    if outcome.timed_out:
        lines.append("wall-clock limit reached before the ground station finished: both processes stopped")
    if outcome.up_died_first:
        lines.append(
            f"quadsitl up exited with status {outcome.up_rc} before the mission was done"
            f" (sim end reason: {sim.get('end_reason', 'unknown')}); last lines of {out_dir / 'up.log'}:"
        )
        lines += [f"    {line}" for line in _tail(out_dir / "up.log")]
    elif outcome.up_rc not in (0, None):
        lines.append(f"quadsitl up exited with status {outcome.up_rc} when stopped (see {out_dir / 'up.log'})")
    if outcome.gcs_rc not in (0, None) or (outcome.gcs_rc == 0 and not gcs.get("ok")):
        reason = gcs.get("reason") or "no summary written (see its output above)"
        lines.append(f"ground station: mission failed: {reason}")
    collisions = sim.get("collisions")
    if isinstance(collisions, int) and collisions != 0:
        lines.append(f"simulator: collisions = {collisions}")
    elif not sim and not lines:  # nothing else explains it: the flight cannot be called good without the sim's word
        lines.append(f"the simulator wrote no summary (see {out_dir / 'up.log'})")
    return lines


def _print_summary(summary: dict[str, object], problems: list[str], recording: Path | None, out_dir: Path) -> None:
    gcs, sim, ap = summary["gcs"], summary["sim"], summary["autopilot"]
    assert isinstance(gcs, dict) and isinstance(sim, dict) and isinstance(ap, dict)
    progress = gcs or ap  # the autopilot's own count when the ground station was stopped before its summary
    rows: list[tuple[str, str | None]] = [("result", "OK" if summary["ok"] else "FAILED")]
    if "items_reached" in progress and "items_total" in progress:
        rows.append(("items reached", f"{progress['items_reached']}/{progress['items_total']}"))
    if "landed" in progress and "disarmed" in progress:
        rows.append(("landed / disarmed", f"{progress['landed']} / {progress['disarmed']}"))
    if sim:  # the simulator's numbers, only when it wrote them (no row of "?" after a failed start)
        clearance = _num(sim.get("min_clearance_m"), 2, " m", "no obstacles")
        rows += [
            ("sim time", _num(sim.get("sim_time_s"), 1, " s")),
            ("wall time (flight / total)", f"{_num(sim.get('wall_time_s'), 1, ' s')} / {summary['wall_time_s']} s"),
            ("real-time factor", _num(sim.get("real_time_factor"), 2, "x")),
            ("payload released at", _num(sim.get("payload_released_at_s"), 3, " s sim time", "not released")),
            ("collisions", str(sim.get("collisions"))),
            ("min clearance to obstacles", clearance),
            ("max tilt", _num(sim.get("max_tilt_deg"), 1, " deg")),
            ("sim end reason", str(sim.get("end_reason"))),
        ]
    else:
        rows.append(("wall time", f"{summary['wall_time_s']} s"))
    print()
    for name, value in rows:
        print(f"{name:<28} {value}")
    sys.stdout.flush()  # the table first, then the error lines, in a terminal too
    for line in problems:
        print(f"run_delivery: error: {line}" if not line.startswith("    ") else line, file=sys.stderr)
    print(f"\nsummary:   {out_dir / 'summary.json'}")
    if recording is not None:
        print(f"recording: {recording}\n           open it with: .venv/bin/rerun {recording}")


def _num(value: object, digits: int, unit: str, missing: str = "n/a") -> str:
    if isinstance(value, int | float) and not isinstance(value, bool):
        return f"{value:.{digits}f}{unit}"
    return missing


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m tools.run_delivery",
        description="Fly a mission end to end (make run): simulator, autopilot, ground station; summary + recording.",
    )
    parser.add_argument("--mission", default="missions/delivery.yaml", help="mission file (YAML, .waypoints, .plan)")
    parser.add_argument("--speed", default="max", help="'max' or a real-time factor such as 1 or 10")
    parser.add_argument("--vehicle", default=None, help="vehicle config name (default: the mission's)")
    parser.add_argument("--seed", type=int, default=1, help="seed of sensor noise and gusts (default 1)")
    parser.add_argument(
        "--estimator", default=DEFAULT_ESTIMATOR, choices=sorted(ESTIMATORS), help="state estimator (default: ekf)"
    )
    parser.add_argument("--out-dir", default=None, help="default runs/<timestamp>")
    parser.add_argument("--timeout-s", type=float, default=600.0, help="wall-clock limit for the flight")
    parser.add_argument("--rerun", default=None, help="override --rerun (default save:<out-dir>/flight.rrd)")
    parser.add_argument("--params", default=None, help="autopilot --params FILE (NAME: value pairs or a gains file)")
    args = parser.parse_args(argv)

    mission = Path(args.mission)
    problem = check_inputs(mission, args.vehicle)
    if problem is not None:  # before any folder or process: one line naming the file, the line and the fix
        print(f"run_delivery: error: {problem}", file=sys.stderr)
        return EXIT_USAGE
    out_dir = Path(args.out_dir or Path("runs") / datetime.now().strftime("%Y%m%d-%H%M%S"))
    rerun = args.rerun or f"save:{out_dir / 'flight.rrd'}"
    recording = Path(rerun[len("save:") :]) if rerun.startswith("save:") else None
    try:
        instance = free_instance()
    except RuntimeError as exc:
        print(f"run_delivery: error: {exc}", file=sys.stderr)
        return EXIT_SITL_DIED
    out_dir.mkdir(parents=True, exist_ok=True)  # only now: a refused start leaves no empty run folder

    up_cmd = [
        sys.executable, "-m", "quadsitl_cli", "up",
        "--world", str(mission), "--seed", str(args.seed), "--speed", args.speed,
        "--instance", str(instance), "--log-dir", str(out_dir), "--rerun", rerun, "--estimator", args.estimator,
    ]  # fmt: skip
    if args.vehicle:
        up_cmd += ["--vehicle", args.vehicle]
    if args.params:
        up_cmd += ["--params", args.params]
    gcs_cmd = [
        sys.executable, "-m", "tools.gcs", "--instance", str(instance), "fly", str(mission),
        "--summary", str(out_dir / "gcs_summary.json"), "--timeout-s", str(args.timeout_s),
    ]  # fmt: skip

    print(f"[run] mission {mission} -> {out_dir} (instance {instance}, speed {args.speed})", flush=True)
    t0 = time.monotonic()
    outcome = fly(up_cmd, gcs_cmd, out_dir, args.timeout_s + _STARTUP_MARGIN_S)
    wall_s = time.monotonic() - t0

    sim = _read_json(out_dir / "sim_summary.json")
    ap = _read_json(out_dir / "autopilot_summary.json")
    gcs = _read_json(out_dir / "gcs_summary.json")
    problems = _problems(outcome, gcs, sim, out_dir)
    if recording is not None and not (recording.is_file() and recording.stat().st_size > 0):
        problems.append(f"no recording written at {recording} (see {out_dir / 'up.log'})")
        recording = None
    ok = not problems
    summary = {
        "ok": ok,
        "mission": str(mission),
        "out_dir": str(out_dir),
        "wall_time_s": round(wall_s, 2),
        "gcs": gcs,
        "sim": sim,
        "autopilot": ap,
        "recording": str(recording) if recording is not None else None,
        "exit_codes": {"gcs": outcome.gcs_rc, "up": outcome.up_rc},
        "errors": problems,
    }
    (out_dir / "summary.json").write_text(json.dumps(summary, indent=2) + "\n")
    _print_summary(summary, problems, recording, out_dir)
    if ok:
        return EXIT_OK
    sitl_failed = outcome.up_died_first or outcome.timed_out or outcome.interrupted
    return EXIT_SITL_DIED if sitl_failed else EXIT_FLIGHT_FAILED


if __name__ == "__main__":
    sys.exit(main())
