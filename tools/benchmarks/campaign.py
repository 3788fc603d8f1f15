"""Campaign throughput on the engine (SPEC §11, §14; issue 21): flights per minute with 1 and 2 workers, same run.

The campaign is the shipped delivery sweep (``missions/campaigns/delivery_wind_payload.yaml``: real lockstep
flights, simulator + autopilot processes, 150 s of sim time each), cut to its first N cases (a case depends only
on its id, so these are the 1000-case campaign's first N). The same N cases are flown on a LocalCluster of 1
worker, then of 2; throughput is cases per wall minute of the whole ``run_campaign`` call (cluster start, the
cases, merge and report). Beside it, a plain ``make run`` flight (``tools.run``, the delivery mission,
sim + autopilot + ground station, no Dask) gives the engine's overhead per flight:
``campaign_flight_wall_s_1w`` / ``campaign_plain_flight_wall_s``. Target: 2 workers >= 1.7x 1 worker.
"""

from __future__ import annotations

import dataclasses
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from tools.benchmarks import BenchResult

REPO_ROOT = Path(__file__).resolve().parent.parent.parent
CAMPAIGN = REPO_ROOT / "missions" / "campaigns" / "delivery_wind_payload.yaml"
SPEEDUP_TARGET = 1.7
FULL_CASES = 12
QUICK_CASES = 4


def _campaign_wall_s(cases: int, workers: int, out_dir: Path) -> tuple[float, list[dict]]:
    from tools.campaign.results import read_rows
    from tools.campaign.runner import run_campaign
    from tools.campaign.spec import load_campaign

    spec = dataclasses.replace(load_campaign(CAMPAIGN), cases=cases)
    t0 = time.perf_counter()
    run_campaign(spec, out_dir, workers=workers, progress=False)
    return time.perf_counter() - t0, read_rows(out_dir)


def _plain_flight_wall_s(out_dir: Path) -> float:
    """One ``make run`` flight (``python -m tools.run --rerun off``), whole command wall time."""
    t0 = time.perf_counter()
    cmd = [sys.executable, "-m", "tools.run", "--out-dir", str(out_dir), "--rerun", "off"]
    done = subprocess.run(cmd, cwd=REPO_ROOT, capture_output=True, timeout=900, check=False)
    if done.returncode != 0:
        raise RuntimeError(f"plain flight failed ({done.returncode}): {done.stderr.decode()[-2000:]}")
    return time.perf_counter() - t0


def run(quick: bool) -> list[BenchResult]:
    n = QUICK_CASES if quick else FULL_CASES
    with tempfile.TemporaryDirectory(prefix="bench-campaign-") as tmp:
        root = Path(tmp)
        plain_s = _plain_flight_wall_s(root / "plain")
        wall_1w, rows_1w = _campaign_wall_s(n, 1, root / "w1")
        wall_2w, rows_2w = _campaign_wall_s(n, 2, root / "w2")
        plain_s = min(plain_s, _plain_flight_wall_s(root / "plain2"))
    same = [r["truth_hash"] for r in rows_1w] == [r["truth_hash"] for r in rows_2w]
    per_min_1w, per_min_2w = 60.0 * n / wall_1w, 60.0 * n / wall_2w
    speedup = per_min_2w / per_min_1w
    flight_1w = wall_1w / n
    ok_1w = sum(r["status"] in ("ok", "fail") for r in rows_1w)
    note = f"{n} cases of {CAMPAIGN.name} (sitl, 150 s sim each), {ok_1w} flown to the end"
    return [
        BenchResult("campaign_flights_per_min_1w", per_min_1w, note=note),
        BenchResult("campaign_flights_per_min_2w", per_min_2w, note="same cases, same run, 2 LocalCluster workers"),
        BenchResult(
            "campaign_speedup_2w_over_1w",
            speedup,
            target=f">= {SPEEDUP_TARGET:g}",
            met=None if quick else speedup >= SPEEDUP_TARGET,
            note="2 cores shared with other work: each flight is 3 processes, 2 of them spinning in lockstep",
        ),
        BenchResult("campaign_flight_wall_s_1w", flight_1w, note="wall per flight in the engine, 1 worker"),
        BenchResult("campaign_plain_flight_wall_s", plain_s, note="one make run flight (tools.run), best of 2"),
        BenchResult(
            "campaign_flight_overhead_ratio",
            flight_1w / plain_s,
            note="engine flight / plain flight (the campaign flies 150 s sim, make run stops ~5 s after landing)",
        ),
        BenchResult("campaign_same_hashes_1w_2w", float(same), target="== 1", met=same, note="truth hashes per case"),
    ]
