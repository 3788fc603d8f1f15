"""Campaign throughput on the engine (SPEC §11, §14; issue 29), all in one run on one machine.

The campaign is the shipped delivery sweep (``missions/campaigns/delivery_wind_payload.yaml``: wind up to 6 m/s,
gusts, payload 0-0.8 kg, x500 or delivery650; a case ends landed and disarmed, ~103 s of sim). A case depends only
on its id, so the first N cases are the 1000-case campaign's first N.

- ``campaign_1000_wall_s``: the whole ``run_campaign`` call (cluster start, cases, merge, report) in the default
  mode (``inproc``) on 2 LocalCluster workers. The full run flies all 1000 cases; ``--quick`` flies the first
  ``QUICK_CASES`` and scales the time of its cases to 1000 (the note says so). Target <= 15 min.
- Lockstep scaling: the first cases as real lockstep flights (``mode: sitl``: simulator, autopilot and supervisor
  processes) on an engine of 1 worker, then of 2, each engine started and its workers set up before the clock
  starts: ``campaign_lockstep_flights_per_min_1w`` / ``_2w`` and ``campaign_lockstep_scaling_2w`` (target >= 1.8).
  ``campaign_same_hashes_inproc_sitl``: those flights' truth hashes equal the in-process flights' of the 1000-case
  run (both modes fly the same cases bit for bit).
- Engine overhead: the first cases through an engine of 1 set-up worker (``run_case`` on Dask: submission, case
  files, the flight, the row, the result's trip back), against each flight's own wall (``inproc_flight.fly_world``
  from loading the world to the summary, measured inside the same task, so a shared machine's load weighs on both
  alike): ``campaign_engine_flight_s`` and ``campaign_bare_flight_s`` per flight, and their difference
  ``campaign_engine_overhead_per_flight_s``.
"""

from __future__ import annotations

import dataclasses
import tempfile
import time
from pathlib import Path
from typing import Any

from tools.benchmarks import BenchResult
from tools.campaign.cases import draw, materialise
from tools.campaign.engine import TaskEngine
from tools.campaign.inproc_flight import warm
from tools.campaign.results import read_rows
from tools.campaign.runner import payload_for, run_campaign
from tools.campaign.spec import CampaignSpec, load_campaign
from tools.campaign.task import CasePayload, run_case

REPO_ROOT = Path(__file__).resolve().parent.parent.parent
CAMPAIGN = REPO_ROOT / "missions" / "campaigns" / "delivery_wind_payload.yaml"
FULL_CASES = 1000
QUICK_CASES = 40
WALL_TARGET_S = 15 * 60.0
SCALING_TARGET = 1.8
LOCKSTEP_CASES = (8, 4)  # full, quick
OVERHEAD_CASES = (12, 6)


def _payloads(spec: CampaignSpec, n: int, out_dir: Path) -> list[CasePayload]:
    return [payload_for(spec, case, materialise(spec, case), out_dir) for case in (draw(spec, k) for k in range(n))]


def _engine_wall_s(payloads: list[CasePayload], workers: int, setup: Any = None) -> tuple[float, list[dict]]:
    """Wall seconds of ``run_case`` over ``payloads`` on an engine of ``workers`` already started and set up."""
    with TaskEngine(workers=workers, worker_setup=setup) as engine:
        engine.run(time.sleep, [0.0] * workers, key="setup")  # every worker up (and set up) before the clock
        t0 = time.perf_counter()
        rows = engine.run(run_case, payloads, key="flight")
        return time.perf_counter() - t0, rows


def run(quick: bool) -> list[BenchResult]:
    spec = load_campaign(CAMPAIGN)
    n_campaign = QUICK_CASES if quick else FULL_CASES
    n_lockstep = LOCKSTEP_CASES[quick]
    n_overhead = OVERHEAD_CASES[quick]
    with tempfile.TemporaryDirectory(prefix="bench-campaign-") as tmp:
        root = Path(tmp)
        t0 = time.perf_counter()
        run_campaign(dataclasses.replace(spec, cases=n_campaign), root / "campaign", workers=2, progress=False)
        campaign_s = time.perf_counter() - t0
        rows = read_rows(root / "campaign")
        sitl = dataclasses.replace(spec, mode="sitl")
        lockstep_1w, sitl_rows = _engine_wall_s(_payloads(sitl, n_lockstep, root / "sitl1"), 1)
        lockstep_2w, _ = _engine_wall_s(_payloads(sitl, n_lockstep, root / "sitl2"), 2)
        engine_s, engine_rows = _engine_wall_s(_payloads(spec, n_overhead, root / "engine"), 1, warm)
    by_id = {r["case_id"]: r["truth_hash"] for r in rows}
    same = all(r["truth_hash"] and by_id.get(r["case_id"]) == r["truth_hash"] for r in sitl_rows)
    passed = sum(bool(r["passed"]) for r in rows)
    scale = FULL_CASES / n_campaign
    wall_1000 = campaign_s * scale
    per_min_1w, per_min_2w = 60.0 * n_lockstep / lockstep_1w, 60.0 * n_lockstep / lockstep_2w
    scaling = per_min_2w / per_min_1w
    bare, engine = sum(r["flight_wall_s"] for r in engine_rows) / n_overhead, engine_s / n_overhead
    sim_mean = sum(r["sim_time_s"] for r in rows) / len(rows)
    how = "all 1000 cases" if not quick else f"the first {n_campaign} cases' wall x {scale:g}"
    return [
        BenchResult(
            "campaign_1000_wall_s",
            wall_1000,
            target=f"<= {WALL_TARGET_S:g}",
            met=None if quick else wall_1000 <= WALL_TARGET_S,
            note=f"{CAMPAIGN.name}, default mode ({spec.mode}), 2 workers, whole run_campaign: {how}; {passed}/"
            f"{len(rows)} passed, mean {sim_mean:.1f} s of sim per case",
        ),
        BenchResult("campaign_lockstep_flights_per_min_1w", per_min_1w, note=f"{n_lockstep} cases, mode sitl"),
        BenchResult("campaign_lockstep_flights_per_min_2w", per_min_2w, note="the same cases on 2 workers"),
        BenchResult(
            "campaign_lockstep_scaling_2w",
            scaling,
            target=f">= {SCALING_TARGET:g}",
            met=None if quick else scaling >= SCALING_TARGET,
            note="2 workers / 1 worker, flights per minute (engines started and set up first)",
        ),
        BenchResult(
            "campaign_same_hashes_inproc_sitl",
            float(same),
            target="== 1",
            met=same,
            note=f"the {n_lockstep} lockstep flights' truth hashes = the in-process flights'",
        ),
        BenchResult("campaign_bare_flight_s", bare, note=f"fly_world's own wall in the task, {n_overhead} cases"),
        BenchResult("campaign_engine_flight_s", engine, note="the same cases through the engine, 1 worker"),
        BenchResult(
            "campaign_engine_overhead_per_flight_s",
            engine - bare,
            note=f"engine - bare per flight ({100.0 * (engine - bare) / bare:.1f} % of a flight)",
        ),
    ]
