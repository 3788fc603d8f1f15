"""Issue 28's SITL must-show: two fleet worlds flown as real processes (``quadsitl up`` + the ground station, by
``python -m tools.run``, each on a free ``--instance`` block), judged by the simulator's truth (its
``sim_summary.json`` folded by ``tools.campaign.fleet_record``, the campaign's own record of a fleet flight).

- ``missions/ring_swap6.yaml``: six vehicles swap pads across a 40 m circle at one altitude, all at once
  (``--stagger-s 0``);
- ``missions/depot_helicopter.yaml``: five vehicles leave a depot 4 s apart, fly to drop points and back while a
  helicopter crosses 60 m from the depot at 25 m, there and back (over it at 20 and 60 s of sim time; the ground
  station starts the vehicles about 16 s in: they wait for it on their pads or meet it in the air).

Keys per world (``sitl_<world>_...``): ``volume_entries`` (pairs of airborne vehicles inside the 10 m / 5 m UAV
volume, target 0), ``nmac`` ((vehicle, aircraft) pairs inside the NMAC volume in flight, target 0), ``contacts``,
``completion`` (share of vehicles whose mission the ground station saw done, target 1), ``min_sep_m`` (closest
airborne pair in the volume's measure) and ``ground_excluded``; the end reason in the note. ``--quick`` flies the
ring swap only. A flight takes one to three minutes of wall time on the 2-core VM (7 processes for the ring swap).
Each run's folder (summaries, ``up.log``, the run's log) is kept under ``runs/bench-sitl-traffic-<time>/``.
"""

from __future__ import annotations

import json
import math
import random
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

from tools.benchmarks import BenchResult

REPO_ROOT = Path(__file__).resolve().parent.parent.parent
#: (key stem, world, sim seconds between take-offs).
WORLDS = (
    ("ring_swap6", REPO_ROOT / "missions" / "ring_swap6.yaml", 0.0),
    ("depot_helicopter", REPO_ROOT / "missions" / "depot_helicopter.yaml", 4.0),
)
FLIGHT_TIMEOUT_S = 600.0


def fly(world: Path, stagger_s: float, out_dir: Path) -> dict[str, Any]:
    """Fly ``world`` with ``tools.run`` (real processes) into ``out_dir``; the fleet flight record of its summary
    (``error`` set when the run wrote none)."""
    from tools.campaign.fleet_record import record

    cmd = [
        sys.executable, "-m", "tools.run", "--world", str(world), "--out-dir", str(out_dir), "--rerun", "off",
        "--stagger-s", f"{stagger_s:g}", "--timeout-s", f"{FLIGHT_TIMEOUT_S:g}",
        "--block-from", str(random.randrange(100, 4000)),
    ]  # fmt: skip
    with open(out_dir.parent / f"{out_dir.name}.log", "wb") as log:
        subprocess.run(cmd, cwd=REPO_ROOT, stdout=log, stderr=log, timeout=FLIGHT_TIMEOUT_S + 300.0, check=False)
    try:
        summary = json.loads((out_dir / "summary.json").read_text())
    except (OSError, ValueError):
        return {"error": f"tools.run wrote no summary (see {out_dir.parent / f'{out_dir.name}.log'})", "sim": {}}
    flight = record(summary)
    flight["vehicle_rows"] = summary.get("vehicles") or []
    return flight


def world_results(stem: str, flight: dict[str, Any]) -> list[BenchResult]:
    """The keys of one world's flight record."""
    traffic = flight.get("traffic") or {}
    why = flight.get("error") or f"end {flight.get('sim', {}).get('end_reason', '?')}"
    rows = flight.get("vehicle_rows") or []
    failed = [f"{r['name']}: {r.get('reason') or 'not complete'}" for r in rows if not r.get("ok")]
    why += f"; {'; '.join(failed)[:200]}" if failed else ""

    def value(column: str) -> float:
        got = traffic.get(column)
        return float(got) if isinstance(got, int | float) else math.nan

    entries, nmac, completion = value("traffic_volume_entries"), value("traffic_nmac"), value("traffic_completion")
    return [
        BenchResult(f"sitl_{stem}_volume_entries", entries, target="== 0", met=entries == 0, note=why),
        BenchResult(f"sitl_{stem}_nmac", nmac, target="== 0", met=nmac == 0),
        BenchResult(
            f"sitl_{stem}_contacts", value("traffic_contacts"), target="== 0", met=value("traffic_contacts") == 0
        ),
        BenchResult(f"sitl_{stem}_completion", completion, target="== 1", met=completion == 1.0),
        BenchResult(f"sitl_{stem}_min_sep_m", value("traffic_min_sep_m"), note="closest airborne pair (< 10: inside)"),
        BenchResult(f"sitl_{stem}_ground_excluded", value("traffic_ground_excluded"), note="on-ground pairs"),
    ]


def run(quick: bool) -> list[BenchResult]:
    out: list[BenchResult] = []
    runs = REPO_ROOT / "runs" / time.strftime("bench-sitl-traffic-%Y%m%d-%H%M%S")
    runs.mkdir(parents=True, exist_ok=True)
    for stem, world, stagger_s in WORLDS[:1] if quick else WORLDS:
        out += world_results(stem, fly(world, stagger_s, runs / stem))
    return out
