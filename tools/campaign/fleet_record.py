"""The flight record of a fleet case (a world with ``vehicles:``, e.g. an encounter campaign's, docs/traffic.md):
the fleet run's summaries (the fleet run command's ``summary.json`` in ``sitl`` mode, ``inproc_flight``'s in
``inproc``) folded into the record a results row is built from, and the row's traffic columns.

The row's usual columns become fleet-wide: ``items_*`` summed over the vehicles, ``landed``/``disarmed`` true
only when every vehicle is, ``collisions`` the simulator's, ``fence_breaches`` the vehicles that left their fence
(a geofence failsafe text, or, flown in process, the simulator's truth sampled every second while armed, on the
ground too: the autopilot reports breaches only in the air), the truth hash the SHA-256 of the vehicles' hashes.
``end_reason`` tells how the flight ended: a vehicle's simulator end when one ended otherwise than stopped (a
crash: ``COLLISION``, ``GROUND_IMPACT``...), else ``STUCK`` when a vehicle was given up as stuck (its reason
``stuck: ...``: no mission progress for too long), else ``UNFINISHED`` when a vehicle was still flying when the
flight stopped (the sim-time or wall-clock limit), else ``COMPLETED``. The traffic columns (simulator truth;
losses of separation as pair-events, ``sim.separation_events``, as DEGAS counts them):

- ``traffic_contacts``: pairs of vehicles that touched;
- ``traffic_volume_entries``: pairs of airborne vehicles that came inside the default UAV separation volume
  (10 m horizontally and 5 m vertically at once), each pair once (target 0); ``traffic_volume_vehicles``: the
  vehicles in those pairs;
- ``traffic_nmac``: (vehicle, manned aircraft) pairs inside the NMAC volume (500 ft / 100 ft at once) with the
  vehicle in flight, each pair once (target 0); ``traffic_nmac_vehicles``: the vehicles in them;
- ``traffic_ground_excluded``: pairs inside either volume only while a vehicle stood on the ground (on its pad:
  parked, not in flight), not counted above and written here so nothing is excluded silently;
- ``traffic_min_sep_m``: the closest approach of two airborne vehicles in the volume's measure,
  ``max(horizontal, 2 * vertical)`` between centres (``sim.fleet``; below 10 m: inside); NaN when no two vehicles
  were airborne together;
- ``traffic_min_dist_m``: the closest 3D approach of two vehicles, surface to surface, airborne or not (0 is a
  contact; pads are >= 20 m apart);
- ``traffic_min_manned_m``: the closest 3D approach to a manned aircraft (NaN: none flew);
- ``traffic_completion``: the fraction of vehicles whose mission was done, landed, disarmed, no failsafe;
- ``traffic_vehicles``: how many flew.

In ``sitl`` mode the fleet ground station arms and starts the vehicles on wall-clock timing, so a fleet case
re-flies the same world and inputs, not the same bits; ``inproc`` scripts the starts on sim time and replays bit
for bit (docs/traffic.md says so).
"""

from __future__ import annotations

import hashlib
import math
from typing import Any

from mavlink_bridge.contract.status_texts import failsafe_in, is_geofence_breach
from tools.gcs.summary import is_stuck

TRAFFIC_COLUMNS = (
    "traffic_contacts",
    "traffic_min_sep_m",
    "traffic_volume_entries",
    "traffic_volume_vehicles",
    "traffic_min_dist_m",
    "traffic_nmac",
    "traffic_nmac_vehicles",
    "traffic_ground_excluded",
    "traffic_min_manned_m",
    "traffic_completion",
    "traffic_vehicles",
)
_RUN_ENDS = ("STOPPED", "COMPLETED")


def end_reason(truth: list[dict[str, Any]], rows: list[dict[str, Any]]) -> str:
    """How a fleet flight ended (see the module docstring): a crash, ``STUCK``, ``UNFINISHED`` or ``COMPLETED``."""
    crashed = [str(v["end_reason"]) for v in truth if v.get("end_reason") not in _RUN_ENDS]
    if crashed:
        return crashed[0]
    if any(r.get("stuck") or is_stuck(str(r.get("reason") or "")) for r in rows):
        return "STUCK"
    if len(rows) < len(truth) or not all(r.get("landed") and r.get("disarmed") for r in rows):
        return "UNFINISHED"
    return "COMPLETED"


def record(summary: dict[str, Any]) -> dict[str, Any]:
    """The flight record of a fleet run's summary (see the module docstring)."""
    sim = summary.get("sim") or {}
    rows = summary.get("vehicles") or []
    truth = sim.get("vehicles") or []
    if not sim or not truth:
        return {"error": "; ".join(summary.get("errors") or ["the simulator wrote no summary"]), "sim": {}}
    hashes = "".join(str(v.get("truth_sha256", "")) for v in truth)
    texts, breaches = [], 0
    for row in rows:
        reason = str(row.get("reason") or "")
        if failsafe_in(reason):
            texts.append(failsafe_in(reason))
        breaches += is_geofence_breach(failsafe_in(reason)) or int(row.get("fence_exits") or 0) > 0
    manned = [float(v["min_manned_distance_m"]) for v in truth if v.get("min_manned_distance_m") is not None]
    separations = [float(v["min_separation_m"]) for v in truth if v.get("min_separation_m") is not None]
    volume_seps = [float(v["min_volume_sep_m"]) for v in truth if v.get("min_volume_sep_m") is not None]
    n = len(truth)
    volume = sim.get("volume_events") or []
    nmac = sim.get("nmac_events") or []
    ground = len(sim.get("volume_ground_excluded") or []) + len(sim.get("nmac_ground_excluded") or [])
    return {
        "sim": {
            **sim,
            "end_reason": end_reason(truth, rows),
            "truth_sha256": hashlib.sha256(hashes.encode()).hexdigest(),
        },
        "autopilot": {
            "items_total": sum(int(r.get("items_total", 0)) for r in rows),
            "items_reached": sum(int(r.get("items_reached", 0)) for r in rows),
            "items_bypassed": sum(int(r.get("items_bypassed", 0)) for r in rows),
            "landed": bool(rows) and all(r.get("landed") for r in rows),
            "disarmed": bool(rows) and all(r.get("disarmed") for r in rows),
            "fence_breaches": breaches,
        },
        "texts": texts,
        "traffic": {
            "traffic_contacts": int(sim.get("vehicle_contacts", 0)),
            "traffic_min_sep_m": min(volume_seps) if volume_seps else math.nan,
            "traffic_volume_entries": len(volume),
            "traffic_volume_vehicles": len({e["a"] for e in volume} | {e["b"] for e in volume}),
            "traffic_min_dist_m": min(separations) if separations else math.nan,
            "traffic_nmac": len(nmac),
            "traffic_nmac_vehicles": len({e["a"] for e in nmac}),
            "traffic_ground_excluded": ground,
            "traffic_min_manned_m": min(manned) if manned else math.nan,
            "traffic_completion": sum(bool(r.get("ok")) for r in rows) / n if n else 0.0,
            "traffic_vehicles": n,
        },
    }


def traffic_columns(flight: dict[str, Any]) -> dict[str, Any]:
    """The traffic columns of a fleet case's row, as floats (NaN when the flight could not be judged: every row of
    a fleet case has them, in one type)."""
    got = flight.get("traffic") or {}
    return {column: float(got.get(column, math.nan)) for column in TRAFFIC_COLUMNS}
