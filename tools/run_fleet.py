"""``make run-fleet``: fly a fleet world end to end: one simulator, one autopilot per vehicle, one ground station.

Starts ``quadsitl up --world W`` (``--speed max``) on a free ``--instance`` block, runs the ground station's
``fly`` on the same world (it uploads each vehicle's fence and mission to its system id over the one GCS port, arms
and starts them ``--stagger-s`` sim seconds apart and waits until every one has landed), stops every process and
prints one row per vehicle. Everything lands in ``runs/fleet-<timestamp>/`` (or ``--out-dir``): ``sim_summary.json``
(the simulator's truth: contacts, closest approaches), ``<name>/autopilot_summary.json``, ``gcs_summary.json``,
``summary.json``, ``up.log`` and one Rerun recording in several files (``--rerun``, default
``save:<out-dir>/flight.rrd``: each autopilot writes ``flight_<name>.rrd`` under its vehicle's name, the simulator
``flight_world.rrd`` (traffic, separation per pair), all with one recording id and about the world's home; open them
together with ``rerun <out-dir>/*.rrd``; docs/traffic.md).

Exit status: 0 every vehicle flew its mission and landed with no contact, 1 a flight failed, 2 bad arguments,
3 the SITL processes died or the wall-clock limit was hit.
"""

from __future__ import annotations

import argparse
import json
import socket
import sys
import time
from datetime import datetime
from pathlib import Path

from autopilot.launch_plan import API_LOCAL_PORT, GCS_LOCAL_PORT, GCS_PORT, SIM_PORT
from autopilot.mission.files import MissionFileError, load_fleet_missions
from tools.run_delivery import (
    _STARTUP_MARGIN_S,
    EXIT_FLIGHT_FAILED,
    EXIT_OK,
    EXIT_SITL_DIED,
    EXIT_USAGE,
    FlightOutcome,
    _read_json,
    _tail,
    check_inputs,
    fly,
)


def _block_free(block: int, count: int) -> bool:
    ports = [GCS_PORT + block] + [
        base + block + i for base in (SIM_PORT, GCS_LOCAL_PORT, API_LOCAL_PORT) for i in range(count)
    ]
    for port in ports:
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
            try:
                s.bind(("127.0.0.1", port))
            except OSError:
                return False
    return True


def free_block(count: int, start: int = 0, limit: int = 400) -> int:
    """The smallest ``--instance`` block >= ``start`` whose ports for ``count`` vehicles are all free."""
    for block in range(start, start + limit, max(count, 1)):
        if _block_free(block, count):
            return block
    raise RuntimeError(f"no free block of {count} quadsitl instances in {start}..{start + limit - 1}")


def problems_of(outcome: FlightOutcome, gcs: dict[str, object], sim: dict[str, object], out_dir: Path) -> list[str]:
    """One line per thing that went wrong (empty: every vehicle flew and nothing touched)."""
    lines: list[str] = []
    if outcome.interrupted:
        lines.append("interrupted (Ctrl-C): every process stopped")
    if outcome.timed_out:
        lines.append("wall-clock limit reached before the ground station finished: every process stopped")
    if outcome.up_died_first:
        lines.append(f"quadsitl up exited with status {outcome.up_rc} before the fleet was done; last lines of up.log:")
        lines += [f"    {line}" for line in _tail(out_dir / "up.log")]
    rows = gcs.get("vehicles")
    for row in rows if isinstance(rows, list) else []:
        if isinstance(row, dict) and not row.get("ok"):
            lines.append(f"{row.get('name')}: mission failed: {row.get('reason') or 'not complete'}")
    if outcome.gcs_rc not in (0, None) and not isinstance(rows, list):
        lines.append("ground station failed before writing its summary (see its output above)")
    if not sim:
        lines.append(f"the simulator wrote no summary (see {out_dir / 'up.log'})")
    for key in ("collisions", "vehicle_contacts"):
        value = sim.get(key)
        if isinstance(value, int) and value:
            lines.append(f"simulator: {key} = {value}")
    return lines


def vehicle_rows(gcs: dict[str, object], sim: dict[str, object]) -> list[dict[str, object]]:
    """Per vehicle: the ground station's result joined with the simulator's truth (contacts, closest approach)."""
    truth = {str(v.get("name")): v for v in sim.get("vehicles", []) if isinstance(v, dict)}  # type: ignore[union-attr]
    rows = []
    for row in gcs.get("vehicles", []):  # type: ignore[union-attr]
        if isinstance(row, dict):
            t = truth.get(str(row.get("name")), {})
            rows.append({**row, "contacts": t.get("contacts"), "min_separation_m": t.get("min_separation_m")})
    return rows


def fleet_min_separation_m(sim: dict[str, object]) -> float | None:
    """The fleet's closest approach of two vehicles (surface to surface, the simulator's truth)."""
    values = [v.get("min_separation_m") for v in sim.get("vehicles", []) if isinstance(v, dict)]  # type: ignore[union-attr]
    numbers = [float(v) for v in values if isinstance(v, int | float)]
    return min(numbers) if numbers else None


def _print(rows: list[dict[str, object]], summary: dict[str, object], problems: list[str], out_dir: Path) -> None:
    print(f"\n{'vehicle':<10} {'result':<7} {'items':>7} {'bypassed':>8} {'closest':>9} {'contacts':<10}")
    for r in rows:
        sep = r.get("min_separation_m")
        sep_text = f"{sep:.1f} m" if isinstance(sep, int | float) else "n/a"
        items = f"{r.get('items_reached')}/{r.get('items_total')}"
        contacts = ", ".join(r.get("contacts") or []) or "none"  # type: ignore[arg-type]
        print(f"{r.get('name')!s:<10} {'OK' if r.get('ok') else 'FAILED':<7} {items:>7} {r.get('items_bypassed')!s:>8} "
              f"{sep_text:>9} {contacts:<10}")  # fmt: skip
    sep = summary["min_separation_m"]
    print(f"\nresult                 {'OK' if summary['ok'] else 'FAILED'}")
    print(f"fleet min separation   {f'{sep:.2f} m (surface to surface, sim truth)' if sep is not None else 'n/a'}")
    sim = summary["sim"]
    if isinstance(sim, dict) and sim:
        rtf = sim.get("real_time_factor")
        rtf_text = f"{rtf:.2f}x" if isinstance(rtf, int | float) else "n/a"
        print(f"sim time / RTF         {sim.get('sim_time_s')} s / {rtf_text}")
    sys.stdout.flush()
    for line in problems:
        print(f"run_fleet: error: {line}" if not line.startswith("    ") else line, file=sys.stderr)
    print(f"\nsummary:   {out_dir / 'summary.json'}")
    if summary.get("recording"):
        print(f"recording: one recording in {len(summary['recording'])} files (one per autopilot + the world)")  # type: ignore[arg-type]
        print(f"           open it with: .venv/bin/rerun {out_dir}/*.rrd")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m tools.run_fleet",
        description="Fly a fleet world end to end (make run-fleet): simulator, one autopilot per vehicle, one GCS.",
    )
    parser.add_argument("--world", default="missions/depot_fleet.yaml", help="fleet world file (vehicles:)")
    parser.add_argument("--speed", default="max", help="'max' or a real-time factor such as 1 or 10")
    parser.add_argument("--seed", type=int, default=1, help="seed of sensor noise and gusts (default 1)")
    parser.add_argument("--stagger-s", type=float, default=4.0, help="sim seconds between take-offs (default 4)")
    parser.add_argument("--out-dir", default=None, help="default runs/fleet-<timestamp>")
    parser.add_argument("--timeout-s", type=float, default=900.0, help="wall-clock limit for the flight")
    parser.add_argument("--rerun", default=None, help="override --rerun (default save:<out-dir>/flight.rrd)")
    parser.add_argument("--stall-s", type=float, default=120.0, help="sim s without progress that fail a vehicle")
    parser.add_argument("--block-from", type=int, default=0, help="search a free --instance block from here")
    parser.add_argument("--params", default=None, help="every autopilot's --params FILE (e.g. NAV_TRAFF_AVOID: 1)")
    args = parser.parse_args(argv)

    world = Path(args.world)
    problem = check_inputs(world, None)
    try:
        plans = load_fleet_missions(world) if problem is None else []
    except MissionFileError as exc:
        problem = str(exc)
    if problem is None and not plans:
        problem = f"{world}: not a fleet world (no vehicles:); fix: fly it with make run, or add vehicles:"
    if problem is not None:
        print(f"run_fleet: error: {problem}", file=sys.stderr)
        return EXIT_USAGE
    out_dir = Path(args.out_dir or Path("runs") / datetime.now().strftime("fleet-%Y%m%d-%H%M%S"))
    rerun = args.rerun or f"save:{out_dir / 'flight.rrd'}"
    try:
        block = free_block(len(plans), start=args.block_from)
    except RuntimeError as exc:
        print(f"run_fleet: error: {exc}", file=sys.stderr)
        return EXIT_SITL_DIED
    out_dir.mkdir(parents=True, exist_ok=True)
    up_cmd = [
        sys.executable, "-m", "quadsitl_cli", "up", "--world", str(world), "--seed", str(args.seed),
        "--speed", args.speed, "--instance", str(block), "--log-dir", str(out_dir), "--rerun", rerun, "--api", "off",
    ]  # fmt: skip
    if args.params:
        up_cmd += ["--params", args.params]
    gcs_cmd = [
        sys.executable, "-m", "tools.gcs", "--instance", str(block), "fly", str(world), "--stagger-s",
        str(args.stagger_s), "--stall-s", str(args.stall_s), "--summary", str(out_dir / "gcs_summary.json"),
        "--timeout-s", str(args.timeout_s),
    ]  # fmt: skip
    print(f"[run-fleet] {world}: {len(plans)} vehicles -> {out_dir} (instance block {block})", flush=True)
    t0 = time.monotonic()
    outcome = fly(up_cmd, gcs_cmd, out_dir, args.timeout_s + _STARTUP_MARGIN_S)
    sim, gcs = _read_json(out_dir / "sim_summary.json"), _read_json(out_dir / "gcs_summary.json")
    problems = problems_of(outcome, gcs, sim, out_dir)
    recording = sorted(out_dir.glob("flight*.rrd")) if rerun.startswith("save:") else []
    summary: dict[str, object] = {
        "ok": not problems,
        "world": str(world),
        "wall_time_s": round(time.monotonic() - t0, 2),
        "min_separation_m": fleet_min_separation_m(sim),
        "vehicles": vehicle_rows(gcs, sim),
        "gcs": gcs,
        "sim": sim,
        "autopilots": {p.name: _read_json(out_dir / p.name / "autopilot_summary.json") for p in plans},
        "recording": [str(p) for p in recording],
        "exit_codes": {"gcs": outcome.gcs_rc, "up": outcome.up_rc},
        "errors": problems,
    }
    (out_dir / "summary.json").write_text(json.dumps(summary, indent=2) + "\n")
    _print(summary["vehicles"], summary, problems, out_dir)  # type: ignore[arg-type]
    if not problems:
        return EXIT_OK
    return EXIT_SITL_DIED if outcome.up_died_first or outcome.timed_out or outcome.interrupted else EXIT_FLIGHT_FAILED


if __name__ == "__main__":
    sys.exit(main())
