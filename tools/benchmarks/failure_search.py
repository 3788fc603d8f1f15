"""Failure search and rare-event estimation against plain Monte Carlo (issue 29, docs/campaigns.md), real flights.

The configuration is ``missions/campaigns/hop_tracking_rare.yaml``: the x500's first 4 s of a 15 m hop
(in-process, the true state), a steady wind north U[-10, 4] m/s, east U[-7, 7] m/s, payload U[0, 0.8] kg, no gusts
(a flight is a function of its inputs); a failure is a position tracking error above 0.74 m (a headwind near 10 m/s,
a crosswind from either side, a nearly full payload: P about 1.5e-4, docs/performance.md). All flights run on one
engine session (a LocalCluster, ``--workers``), every one an ordinary case:

- ``search_flights_to_failure``: CMA-ES (the file's ``search:``, popsize 8) from 10 root seeds, each stopped after
  the generation holding its first failing flight; the flights up to and including that one, median over the seeds
  (a seed that found none within ``SEARCH_CAP`` counts as the cap);
- ``is_estimate``: the failure probability by cross-entropy importance sampling (the file's ``estimate:``), with
  ``is_ci95_low``/``_high``, ``is_ess`` (Kish), ``is_mean_weight`` and ``is_flights`` (levels and final batch);
- ``mc_estimate``: plain Monte Carlo of ``MC_FACTOR`` x ``is_flights`` cases of the campaign (root seed + 1: its
  own noise), failures / flights, with its exact interval; ``mc_inside_is_ci95`` (target 1);
- ``mc_flights_to_failure``: the same flights read as 10 plain Monte Carlo campaigns starting at 10 evenly spaced
  cases of that pool (wrapping round; the streams overlap, they are not independent): flights up to and including
  the first failure, median over the 10 (the pool's size when it holds no failure: a lower bound);
- ``search_speedup_over_mc``: their ratio (target >= 10); ``failure_search_flight_wall_s``: wall per flight.

``--quick``: 3 search seeds, a smaller estimate and a Monte Carlo of 1 x its budget (no targets judged).
"""

from __future__ import annotations

import dataclasses
import math
import statistics
import tempfile
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from tools.benchmarks import BenchResult

REPO_ROOT = Path(__file__).resolve().parent.parent.parent
CAMPAIGN = REPO_ROOT / "missions" / "campaigns" / "hop_tracking_rare.yaml"
SEEDS, QUICK_SEEDS = 10, 3
SEARCH_CAP, QUICK_SEARCH_CAP = 320, 96
MC_FACTOR, QUICK_MC_FACTOR = 20, 1
SPEEDUP_TARGET = 10.0
MC_NEEDS = 2000


class _FoundError(Exception):
    """Raised by the search's evaluator at the first failing flight (the bench's early stop)."""

    def __init__(self, flights: int) -> None:
        super().__init__(flights)
        self.flights = flights


def _search_until_failure(spec: Any, engine: Any, out_dir: Path, cap: int) -> tuple[int, bool]:
    from tools.campaign.runner import prepare_dir
    from tools.campaign.search import cmaes
    from tools.campaign.search_run import FlightEvaluator
    from tools.campaign.search_space import space_of

    assert spec.search is not None
    space = space_of(spec, spec.search.inputs)
    prepare_dir(spec, out_dir, False)
    evaluator = FlightEvaluator(spec, space, spec.search.objective, out_dir, engine, progress=False)

    def evaluate(first_case: int, points: Sequence[Any]) -> list[float]:
        margins = evaluator(first_case, points)
        failing = [j for j, m in enumerate(margins) if m < 0.0]
        if failing:
            raise _FoundError(first_case + failing[0] + 1)
        return margins

    try:
        popsize = spec.search.popsize or 8
        cmaes(space, evaluate, budget=cap, popsize=popsize, seed=spec.seed, sigma0=spec.search.sigma0)
    except _FoundError as found:
        return found.flights, True
    return cap, False


def _estimate(spec: Any, engine: Any, out_dir: Path) -> Any:
    from tools.campaign.estimate import ce_is
    from tools.campaign.runner import prepare_dir
    from tools.campaign.search_config import EstimateConfig
    from tools.campaign.search_run import FlightEvaluator
    from tools.campaign.search_space import space_of

    assert spec.search is not None
    cfg = spec.estimate or EstimateConfig()
    prepare_dir(spec, out_dir, False)
    evaluator = FlightEvaluator(spec, space_of(spec, spec.search.inputs), spec.search.objective, out_dir, engine, False)
    return ce_is(evaluator.space, evaluator, seed=spec.seed, **dataclasses.asdict(cfg))


def _plain_margins(spec: Any, cases: int, engine: Any, out_dir: Path) -> list[float]:
    from tools.campaign.cases import draw, materialise
    from tools.campaign.runner import payload_for
    from tools.campaign.task import run_case

    assert spec.search is not None
    margins = [math.nan] * cases
    payloads = [payload_for(spec, c, materialise(spec, c), out_dir) for c in (draw(spec, k) for k in range(cases))]

    def keep(i: int, value: Any) -> None:
        margins[i] = spec.search.objective.margin(value) if isinstance(value, dict) else math.nan

    engine.run(run_case, payloads, key="bench-mc", on_result=keep, on_error="return")
    return margins


def mc_flights_to_failure(failed: Sequence[bool], starts: int) -> list[int]:
    """Flights up to and including the first failure of the pool read from ``starts`` evenly spaced cases,
    wrapping round (the pool's size when it holds none)."""
    n = len(failed)
    where = [i for i, f in enumerate(failed) if f]
    if not where:
        return [n] * starts
    out = []
    for s in range(starts):
        o = s * n // starts
        out.append(min((f - o) % n for f in where) + 1)
    return out


def run(quick: bool, workers: int | None = None, scheduler: str | None = None) -> list[BenchResult]:
    from tools.campaign.engine import TaskEngine
    from tools.campaign.estimate import mc_interval
    from tools.campaign.inproc_flight import warm
    from tools.campaign.search_config import EstimateConfig
    from tools.campaign.spec import load_campaign

    spec = load_campaign(CAMPAIGN)
    seeds, cap, factor = (QUICK_SEEDS, QUICK_SEARCH_CAP, QUICK_MC_FACTOR) if quick else (SEEDS, SEARCH_CAP, MC_FACTOR)
    if quick:
        spec = dataclasses.replace(spec, estimate=EstimateConfig(rho=0.1, level_batch=30, final=60, max_levels=4))
    t0 = time.perf_counter()
    with (
        tempfile.TemporaryDirectory(prefix="bench-search-") as tmp,
        TaskEngine(workers=workers, scheduler=scheduler, worker_setup=warm) as engine,
    ):
        root = Path(tmp)
        engine.run(warm_flight, [0] * engine.n_workers, key="bench-warm")  # every worker's kernels loaded
        t_search = time.perf_counter()
        found = [_search_until_failure(dataclasses.replace(spec, seed=s), engine, root / f"search-{s}", cap)
                 for s in range(seeds)]  # fmt: skip
        search_flights = sum(-(-f // 8) * 8 for f, _ in found)
        t_is = time.perf_counter()
        res = _estimate(spec, engine, root / "is")
        is_flights = sum(len(lv.margins) for lv in res.levels) + len(res.final_margins)
        t_mc = time.perf_counter()
        mc_cases = factor * is_flights
        margins = _plain_margins(dataclasses.replace(spec, seed=spec.seed + 1), mc_cases, engine, root / "mc")
        t_end = time.perf_counter()
    known = [m for m in margins if math.isfinite(m)]
    failed = [m < 0.0 for m in known]
    fails = sum(failed)
    mc_p = fails / len(known)
    mc_low, mc_high = mc_interval(fails, len(known))
    search_median = statistics.median(f for f, _ in found)
    mc_ftf = statistics.median(mc_flights_to_failure(failed, 10))
    est = res.estimate
    inside = est.ci95[0] <= mc_p <= est.ci95[1]
    flights = search_flights + is_flights + mc_cases
    wall_per_flight = (t_end - t_search) / flights
    return [
        BenchResult("search_flights_to_failure", float(search_median), target=f"<= mc/{SPEEDUP_TARGET:g}",
                    met=None if quick else search_median * SPEEDUP_TARGET <= mc_ftf,
                    note=f"CMA-ES, median over {seeds} seeds: {sorted(f for f, _ in found)}; "
                         f"{sum(not ok for _, ok in found)} found none within {cap}"),
        BenchResult("mc_flights_to_failure", float(mc_ftf), target=f">= {MC_NEEDS}",
                    met=None if quick else mc_ftf >= MC_NEEDS,
                    note=f"median over 10 starts in the {len(known)}-flight pool ({fails} failures; overlapping)"),
        BenchResult("search_speedup_over_mc", mc_ftf / search_median, target=f">= {SPEEDUP_TARGET:g}",
                    met=None if quick else mc_ftf / search_median >= SPEEDUP_TARGET, note="mc / search"),
        BenchResult("is_estimate", est.p, note=f"CE-IS: {len(res.levels)} levels, reached {res.reached}, "
                    f"final {est.n} flights with {est.failures} failures"),
        BenchResult("is_ci95_low", est.ci95[0], note="normal 95 % interval of the IS estimate"),
        BenchResult("is_ci95_high", est.ci95[1]),
        BenchResult("is_ess", est.ess, note="Kish effective sample size of the final batch"),
        BenchResult("is_mean_weight", est.mean_weight, note="about 1 when the mixture covers the nominal"),
        BenchResult("is_flights", float(is_flights), note=f"{(t_mc - t_is):.0f} s wall"),
        BenchResult("mc_estimate", mc_p, note=f"{fails}/{len(known)} plain flights ({factor}x is_flights), exact "
                    f"95 % [{mc_low:.3g}, {mc_high:.3g}], {(t_end - t_mc):.0f} s wall"),
        BenchResult("mc_inside_is_ci95", float(inside), target="== 1", met=None if quick else inside,
                    note=f"exact intervals overlap: {mc_low <= est.ci95[1] and est.ci95[0] <= mc_high}"),
        BenchResult("failure_search_flight_wall_s", wall_per_flight,
                    note=f"{flights} flights in {(t_end - t_search):.0f} s, {engine_workers(workers)} workers, "
                         f"total {(t_end - t0):.0f} s"),
    ]  # fmt: skip


def engine_workers(workers: int | None) -> int:
    from tools.campaign.engine import default_workers

    return workers or default_workers()


def warm_flight(_: int) -> float:
    """One short flight of the hop in a worker (its first flight pays the kernels' loading), untimed."""
    from tools.campaign.cases import draw, materialise
    from tools.campaign.runner import payload_for
    from tools.campaign.spec import load_campaign
    from tools.campaign.task import run_case

    spec = load_campaign(CAMPAIGN)
    case = draw(spec, 0)
    with tempfile.TemporaryDirectory(prefix="bench-warm-") as tmp:
        return float(run_case(payload_for(spec, case, materialise(spec, case), Path(tmp)))["wall_time_s"])
