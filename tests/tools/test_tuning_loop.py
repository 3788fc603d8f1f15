"""Gains tuned where they fly (issue 22 item 1): the in-process closed-loop rollout (sensors -> EKF -> the
autopilot), its ES cost normalised by the paper's PID, the delivery campaign's pipeline and the per-airframe
default gains. Small versions only: the numbers come from ``tools.research.tune_es --ship`` and ``make bench``."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from autopilot.control.gains import CascadeGains
from autopilot.control.param_decls import (
    DEFAULT_GAINS_PATH,
    airframe_gains_path,
    default_gains_path,
    gains_from_params,
    params_from_gains,
    shipped_gains,
)
from autopilot.param_schema import make_param_store
from autopilot.runner import Autopilot, AutopilotConfig
from tools.benchmarks import gains_campaign
from tools.research.experiments.gain_vector import Structure
from tools.research.experiments.loop_rollout import LoopRollout, fly_route
from tools.research.experiments.loop_tuner import LoopTuneConfig, in_process, loop_cost, reference, tune_loop
from tools.research.experiments.loop_tuner import paper_position_on as paper_position


def test_rollout_flies_the_product_loop_and_measures_the_true_error() -> None:
    paper = CascadeGains.fixed_pid()
    a = fly_route(LoopRollout.of("x500", paper, "steps", 1))
    assert a.completed and not a.diverged and a.samples > 100
    assert 0.0 < a.pos_err_rms_m < 3.0 and a.pos_err_max_m >= a.pos_err_rms_m
    assert a.chatter_rms_per_s > 0.0
    assert fly_route(LoopRollout.of("x500", paper, "steps", 1)) == a  # seeded: the same flight
    b = fly_route(LoopRollout.of("x500", paper, "steps", 2))
    assert b.pos_err_rms_m != a.pos_err_rms_m  # another seed, other sensor noise
    soft = paper_position(paper)
    soft = CascadeGains(**{**{c: getattr(soft, c) for c in ("y", "z", "roll", "pitch", "yaw")}, "x": paper.x})
    assert soft == paper  # paper_position_on only replaces the position channels
    with pytest.raises(ValueError, match="unknown route"):
        fly_route(LoopRollout.of("x500", paper, "nowhere", 1))


def test_the_cost_is_normalised_by_the_paper_pid_and_es_runs_on_it() -> None:
    cfg = LoopTuneConfig("x500", Structure.PID, CascadeGains.fixed_pid(), routes=(("steps", 1.0),), seeds=(1,))
    ref = reference(cfg, in_process)
    param = cfg.parametrisation()
    cost = loop_cost(cfg, ref, in_process)
    j = cost(param.vector(CascadeGains.fixed_pid())[None, :])
    assert j[0] == pytest.approx(1.0 + cfg.effort_weight)  # the paper PID's J by construction
    from autopilot.tuning import CentralEsConfig

    quick = LoopTuneConfig(
        "x500", Structure.PID, CascadeGains.fixed_pid(), routes=(("steps", 1.0),), seeds=(1,),
        es=CentralEsConfig(iterations=0, restarts=1),
    )  # fmt: skip
    out = tune_loop(quick, ref, in_process)
    assert out.result.j_best <= 1.0 + cfg.effort_weight + 1e-12  # best kept: never above its start
    assert np.isfinite(out.result.j_best) and out.result.n_evaluations == 2 * param.space().dim + 1


def test_per_airframe_defaults_fly_that_airframe(tmp_path: Path) -> None:
    for name in ("x500", "delivery650"):
        path = default_gains_path(name)
        assert path == airframe_gains_path(name) and path.is_file()
        assert "tune_es --ship" in path.read_text()  # the command as run (tools.tune_es before tools.research)
        ap = Autopilot(AutopilotConfig(vehicle=name))
        assert gains_from_params(ap.params.values()) == shipped_gains(name)
        store = make_param_store(payload_nominal_kg=ap.airframe.payload_nominal_kg, airframe=name)
        assert store.values() == ap.params.values()
    assert default_gains_path("quad250") == DEFAULT_GAINS_PATH  # no own file: the generic set
    assert gains_from_params(make_param_store(airframe="quad250").values()) == shipped_gains()
    # a --params file still wins over the airframe's defaults
    paper = CascadeGains.fixed_pid()
    f = tmp_path / "paper.yaml"
    paper.to_yaml(f)
    assert gains_from_params(make_param_store(f, airframe="x500").values()) == paper
    assert params_from_gains(paper)["NV_X_P_K1"] == pytest.approx(paper.x.k1[0])


def test_delivery_campaign_pipeline_few_flights(tmp_path: Path) -> None:
    cache = tmp_path / "flights.jsonl"
    one = ("x500",)  # one airframe: the pipeline is the same for each (the bench flies both)
    fly = {"n_seeds": 1, "workers": 1, "cache": cache, "vehicles": one, "route": "leg"}  # the bench: the delivery
    table, n_flights = gains_campaign.campaign(**fly)  # type: ignore[arg-type]
    assert n_flights == len(cache.read_text().splitlines()) <= 4  # a set equal to another is flown once
    again = gains_campaign.campaign(**fly)  # type: ignore[arg-type]
    assert again == (table, n_flights)  # read back, nothing flown again
    assert len(cache.read_text().splitlines()) == n_flights
    assert set(table) == set(one)
    for sets in table.values():
        assert set(sets) == set(gains_campaign.SETS)
        for d in sets.values():
            assert d["flights"] == 1 and d["completed"] == 1
            assert all(math.isfinite(x) and x > 0 for x in d["pos_err_rms_m"])
    summary = gains_campaign.summarise(table)
    keys = {r.key: r for r in gains_campaign._keys(summary, n_flights)}
    assert {"gains_vs_paper_pid_pos_rms_ratio", "gains_vs_paper_pid_chatter_ratio"} <= set(keys)
    assert keys["gains_campaign_flights"].met is False  # a few flights are a pipeline check, not the campaign
