"""The Monte Carlos of ``make bench`` and the ES tuner's rollouts run on the campaign engine: the same numbers with
1 worker as with 2 (results in input order, every case seeded by its own inputs)."""

from __future__ import annotations

import dataclasses

import numpy as np

from autopilot.planner.param_decls import PlannerParams
from tools.benchmarks import estimator_mc, routing


def _outcome(flight: routing.MissionFlight) -> dict:
    """A routing flight without its CPU timings (those are measured, not computed)."""
    d = dataclasses.asdict(flight)
    d["local_plans"] = len(d.pop("local_plan_s"))
    d["known_plans"] = len(d.pop("known_plan_s"))
    return d


def test_routing_monte_carlo_gives_the_same_flights_on_one_and_two_workers() -> None:
    params = PlannerParams()
    one = routing.monte_carlo(2, params, workers=1)  # two worlds: one per worker of the two-worker run
    two = routing.monte_carlo(2, params, workers=2)
    assert len(one) == 2
    assert [_outcome(f) for f in one] == [_outcome(f) for f in two]
    # and the same as flying them in this process, in order (world i with sensor seed i)
    here = [routing.fly_mission(rw, params, seed=i) for i, rw in enumerate(routing.benchmark_worlds(2, params))]
    assert [_outcome(f) for f in here] == [_outcome(f) for f in one]


def test_estimator_monte_carlo_gives_the_same_numbers_on_one_and_two_workers() -> None:
    one = estimator_mc.monte_carlo(2, workers=1, timeout_s=12.0)  # one flight per worker of the two-worker run
    two = estimator_mc.monte_carlo(2, workers=2, timeout_s=12.0)
    assert [(r.key, r.value) for r in one] == [(r.key, r.value) for r in two]
    values = {r.key: r.value for r in one}
    assert values["ekf_mc_flights"] == 2.0
    assert np.isfinite(values["ekf_mc_pos_horiz_rms_m"])  # the flights were airborne and compared with the truth


def test_es_tune_is_the_same_in_process_and_on_one_or_two_engine_workers() -> None:
    from dataclasses import replace

    from tools.campaign.engine import TaskEngine
    from tools.research.experiments.noisy_pipeline import noisy_config
    from tools.research.experiments.tuner import engine_rollouts, tune

    cfg = noisy_config("attitude", "x500")  # noisy feedback on two seeds, three step experiments
    cfg = replace(cfg, experiments=tuple(replace(e, duration_s=0.2) for e in cfg.experiments))
    cfg = cfg.with_budget(iterations=1, restarts=1)
    here = tune(cfg)
    for workers in (1, 2):
        with TaskEngine(workers=workers) as engine:
            there = tune(cfg, rollouts=engine_rollouts(engine))
        assert np.array_equal(there.result.j_history, here.result.j_history)
        assert np.array_equal(there.result.k_best, here.result.k_best)
        assert there.result.n_evaluations == here.result.n_evaluations
