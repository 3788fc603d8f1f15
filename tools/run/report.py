"""What a run found: one line per problem, the ``summary.json`` of a single-vehicle mission or of a fleet world, and
the table printed at the end (one vehicle: the flight's figures; a fleet: one row per vehicle).
"""

from __future__ import annotations

import sys
from pathlib import Path

from tools.run.processes import FlightOutcome, tail


def error(line: str) -> None:
    """One error line on stderr (a line of a log's tail, indented, as it is)."""
    print(f"run: error: {line}" if not line.startswith("    ") else line, file=sys.stderr)


def gcs_rows(gcs: dict[str, object]) -> list[dict[str, object]]:
    """The ground station's summary per vehicle: a fleet's ``vehicles`` entries, else the one vehicle's summary."""
    rows = gcs.get("vehicles") if "vehicles" in gcs else ([gcs] if gcs else [])
    return [r for r in rows if isinstance(r, dict)] if isinstance(rows, list) else []


def problems(outcome: FlightOutcome, gcs: dict[str, object], sim: dict[str, object], out_dir: Path) -> list[str]:
    """One line per thing that went wrong (empty: every vehicle flew its mission and landed, nothing touched)."""
    lines: list[str] = []
    if outcome.interrupted:
        lines.append("interrupted (Ctrl-C): every process stopped")
    if outcome.timed_out:
        lines.append("wall-clock limit reached before the ground station finished: every process stopped")
    if outcome.up_died_first:
        lines.append(
            f"quadsitl up exited with status {outcome.up_rc} before the mission was done"
            f" (sim end reason: {sim.get('end_reason', 'unknown')}); last lines of {out_dir / 'up.log'}:"
        )
        lines += [f"    {line}" for line in tail(out_dir / "up.log")]
    elif outcome.up_rc not in (0, None):
        lines.append(f"quadsitl up exited with status {outcome.up_rc} when stopped (see {out_dir / 'up.log'})")
    rows = gcs_rows(gcs)
    for row in rows:
        if not row.get("ok"):
            lines.append(f"{row.get('name', 'ground station')}: mission failed: {row.get('reason') or 'not complete'}")
    if outcome.gcs_rc not in (0, None) and not rows:
        lines.append("ground station failed before writing its summary (see its output above)")
    for key in ("collisions", "vehicle_contacts"):
        value = sim.get(key)
        if isinstance(value, int) and value:
            lines.append(f"simulator: {key} = {value}")
    if not sim and not lines:  # nothing else explains it: the flight cannot be called good without the sim's word
        lines.append(f"the simulator wrote no summary (see {out_dir / 'up.log'})")
    return lines


def vehicle_rows(gcs: dict[str, object], sim: dict[str, object]) -> list[dict[str, object]]:
    """Per vehicle of a fleet: the ground station's result joined with the simulator's truth (contacts, closest
    approach)."""
    truth = {str(v.get("name")): v for v in _sim_vehicles(sim)}
    rows = []
    for row in gcs_rows(gcs):
        t = truth.get(str(row.get("name")), {})
        rows.append({**row, "contacts": t.get("contacts"), "min_separation_m": t.get("min_separation_m")})
    return rows


def fleet_min_separation_m(sim: dict[str, object]) -> float | None:
    """The fleet's closest approach of two vehicles (surface to surface, the simulator's truth)."""
    numbers = [float(v) for t in _sim_vehicles(sim) if isinstance(v := t.get("min_separation_m"), int | float)]
    return min(numbers) if numbers else None


def _sim_vehicles(sim: dict[str, object]) -> list[dict[str, object]]:
    vehicles = sim.get("vehicles")
    return [v for v in vehicles if isinstance(v, dict)] if isinstance(vehicles, list) else []


def print_mission(summary: dict[str, object], problems: list[str], out_dir: Path) -> None:
    """A single-vehicle run's table: result, items, landing, the simulator's figures; errors; where things are."""
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
    _print_end(problems, out_dir)
    recording = summary["recording"]
    if recording is not None:
        print(f"recording: {recording}\n           open it with: .venv/bin/rerun {recording}")


def print_fleet(summary: dict[str, object], problems: list[str], out_dir: Path) -> None:
    """A fleet run's table: one row per vehicle, the fleet's result and closest approach; errors; where things are."""
    rows = summary["vehicles"]
    assert isinstance(rows, list)
    print(f"\n{'vehicle':<10} {'result':<7} {'items':>7} {'bypassed':>8} {'closest':>9} {'contacts':<10}")
    for r in rows:
        sep = r.get("min_separation_m")
        sep_text = f"{sep:.1f} m" if isinstance(sep, int | float) else "n/a"
        items = f"{r.get('items_reached')}/{r.get('items_total')}"
        contacts = ", ".join(r.get("contacts") or []) or "none"
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
        print(f"losses of separation   {_pairs(sim, 'volume_events')} in the UAV volume, {_pairs(sim, 'nmac_events')} "
              f"NMAC (pairs; with a vehicle on the ground, not counted: {_pairs(sim, 'volume_ground_excluded')}, "
              f"{_pairs(sim, 'nmac_ground_excluded')})")  # fmt: skip
    _print_end(problems, out_dir)
    recording = summary["recording"]
    if isinstance(recording, list) and recording:
        print(f"recording: one recording in {len(recording)} files (one per autopilot + the world)")
        print(f"           open it with: .venv/bin/rerun {out_dir}/*.rrd")


def _pairs(sim: dict[str, object], key: str) -> str:
    """How many pair-events the simulator's summary lists under ``key`` ('n/a' when it has none)."""
    events = sim.get(key)
    return str(len(events)) if isinstance(events, list) else "n/a"


def _print_end(problems: list[str], out_dir: Path) -> None:
    sys.stdout.flush()  # the table first, then the error lines, in a terminal too
    for line in problems:
        error(line)
    print(f"\nsummary:   {out_dir / 'summary.json'}")


def _num(value: object, digits: int, unit: str, missing: str = "n/a") -> str:
    if isinstance(value, int | float) and not isinstance(value, bool):
        return f"{value:.{digits}f}{unit}"
    return missing
