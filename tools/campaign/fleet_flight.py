"""A fleet case of an encounter campaign (``encounter:``, docs/traffic.md): fly the case's generated fleet world
with ``tools.run`` (one simulator, one autopilot per vehicle, the fleet ground station) in its own process
group, and fold its summaries into the flight record a results row is built from.

The row's usual columns become fleet-wide: ``items_*`` summed over the vehicles, ``landed``/``disarmed`` true
only when every vehicle is, ``collisions`` the simulator's, ``end_reason`` ``COMPLETED`` unless a vehicle ended
otherwise than stopped (a crash), the truth hash the SHA-256 of the vehicles' hashes. The traffic columns:

- ``traffic_contacts``: pairs of vehicles that touched (the simulator's truth);
- ``traffic_min_sep_m``: the closest approach of two airborne vehicles in the default UAV separation volume's
  measure, ``max(horizontal, 2 * vertical)`` between centres (``sim.fleet``): below 10 m they were inside the
  volume (10 m horizontally and 5 m vertically at once); NaN when no two vehicles were airborne together;
- ``traffic_volume_entries``: vehicles that came inside that volume of another (target 0);
- ``traffic_min_dist_m``: the closest 3D approach of two vehicles, surface to surface, airborne or not (0 is a
  contact; pads are >= 14 m apart);
- ``traffic_nmac``: vehicles that came inside a manned aircraft's NMAC volume (500 ft / 100 ft at once);
- ``traffic_min_manned_m``: the closest 3D approach to a manned aircraft (NaN: none flew);
- ``traffic_completion``: the fraction of vehicles whose mission the ground station saw done, landed, disarmed;
- ``traffic_vehicles``: how many flew.

Unlike the single-vehicle modes the ground station arms and starts the vehicles on wall-clock timing, so a fleet
case re-flies the same world and inputs, not the same bits (docs/traffic.md says so).
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import random
import subprocess
import sys
from pathlib import Path
from typing import Any

from mavlink_bridge.contract.status_texts import failsafe_in
from sim.fleet import UAV_VOLUME_HOR_M

#: The ``base`` a case of an encounter campaign records (its world is generated, not read from a file).
ENCOUNTER_BASE = "encounter"
TRAFFIC_COLUMNS = (
    "traffic_contacts",
    "traffic_min_sep_m",
    "traffic_volume_entries",
    "traffic_min_dist_m",
    "traffic_nmac",
    "traffic_min_manned_m",
    "traffic_completion",
    "traffic_vehicles",
)
_RUN_ENDS = ("STOPPED", "COMPLETED")


def fly(case_dir: Path, deadline_s: float, stagger_s: float, kill_group: Any) -> dict[str, Any]:
    """Fly ``case_dir/world.yaml`` with its ``params.yaml``; the flight record (``error``/``timed_out`` when the
    flight could not be judged)."""
    repo = Path(__file__).resolve().parent.parent.parent
    out = case_dir / "fleet"
    cmd = [
        sys.executable, "-m", "tools.run", "--world", str(case_dir / "world.yaml"), "--out-dir", str(out),
        "--stagger-s", f"{stagger_s:g}", "--params", str(case_dir / "params.yaml"), "--rerun", "off",
        "--timeout-s", f"{max(deadline_s - 30.0, 10.0):g}", "--block-from", str(random.randrange(100, 4000)),
    ]  # fmt: skip
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(filter(None, [str(repo), os.environ.get("PYTHONPATH")])))
    with open(case_dir / "supervisor.log", "wb") as log:
        proc = subprocess.Popen(cmd, cwd=repo, env=env, stdout=log, stderr=log, start_new_session=True)
    try:
        proc.wait(timeout=deadline_s)
    except subprocess.TimeoutExpired:
        kill_group(proc)
        return {"error": "", "timed_out": True, "sim": {}, "autopilot": {}, "texts": [], "pgid": proc.pid}
    finally:
        if proc.poll() is None:
            kill_group(proc)
    try:
        summary = json.loads((out / "summary.json").read_text())
    except (OSError, ValueError):
        tail = (case_dir / "supervisor.log").read_text(errors="replace").strip().splitlines()[-3:]
        return {"error": f"tools.run exited {proc.returncode}: {' | '.join(tail)}", "sim": {}, "autopilot": {}}
    return record(summary)


def record(summary: dict[str, Any]) -> dict[str, Any]:
    """The flight record of a ``tools.run`` summary (see the module docstring)."""
    sim = summary.get("sim") or {}
    rows = summary.get("vehicles") or []
    truth = sim.get("vehicles") or []
    if not sim or not truth:
        return {"error": "; ".join(summary.get("errors") or ["the simulator wrote no summary"]), "sim": {}}
    crashed = [v["end_reason"] for v in truth if v.get("end_reason") not in _RUN_ENDS]
    hashes = "".join(str(v.get("truth_sha256", "")) for v in truth)
    texts = []
    for row in rows:
        reason = str(row.get("reason") or "")
        if failsafe_in(reason):
            texts.append(failsafe_in(reason))
    manned = [float(v["min_manned_distance_m"]) for v in truth if v.get("min_manned_distance_m") is not None]
    separations = [float(v["min_separation_m"]) for v in truth if v.get("min_separation_m") is not None]
    volume_seps = [float(v["min_volume_sep_m"]) for v in truth if v.get("min_volume_sep_m") is not None]
    n = len(truth)
    return {
        "sim": {
            **sim,
            "end_reason": crashed[0] if crashed else "COMPLETED",
            "truth_sha256": hashlib.sha256(hashes.encode()).hexdigest(),
        },
        "autopilot": {
            "items_total": sum(int(r.get("items_total", 0)) for r in rows),
            "items_reached": sum(int(r.get("items_reached", 0)) for r in rows),
            "items_bypassed": sum(int(r.get("items_bypassed", 0)) for r in rows),
            "landed": bool(rows) and all(r.get("landed") for r in rows),
            "disarmed": bool(rows) and all(r.get("disarmed") for r in rows),
        },
        "texts": texts,
        "traffic": {
            "traffic_contacts": int(sim.get("vehicle_contacts", 0)),
            "traffic_min_sep_m": min(volume_seps) if volume_seps else math.nan,
            "traffic_volume_entries": sum(sep < UAV_VOLUME_HOR_M for sep in volume_seps),
            "traffic_min_dist_m": min(separations) if separations else math.nan,
            "traffic_nmac": int(sim.get("manned_nmacs", 0)),
            "traffic_min_manned_m": min(manned) if manned else math.nan,
            "traffic_completion": sum(bool(r.get("ok")) for r in rows) / n if n else 0.0,
            "traffic_vehicles": n,
        },
    }


def traffic_columns(flight: dict[str, Any]) -> dict[str, Any]:
    """The traffic columns of a fleet row, as floats (NaN when the flight could not be judged: every row of an
    encounter campaign has them, in one type)."""
    got = flight.get("traffic") or {}
    return {column: float(got.get(column, math.nan)) for column in TRAFFIC_COLUMNS}
