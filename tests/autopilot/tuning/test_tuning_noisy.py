"""The noisy, effort-aware tuning of issue 14: feedback noise, the cost's terms, learned δ, the PID warm start,
the gains file as ``--params`` and the shipped defaults (SPEC §6.3)."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import yaml
from autopilot_loop import SimLoop

from autopilot.control.gains import CascadeGains
from autopilot.control.param_decls import DEFAULT_GAINS_PATH, gain_param_name, gains_from_params, shipped_gains
from autopilot.param_schema import make_param_store
from autopilot.parameters.store import ParamError
from tools.research.experiments.feedback_noise import DEFAULT_FEEDBACK_NOISE, NoiseStream, rotate_body
from tools.research.experiments.gain_vector import GainParametrisation, Structure
from tools.research.experiments.noisy_pipeline import pid_twin
from tools.research.experiments.rollout import run_step
from tools.research.experiments.tune_config import TuneConfigError, tune_config_from_dict
from tools.research.experiments.tuner import cost_terms, tune, write_outputs

BOUNDS = {"kp": (0.5, 60.0), "ki": (0.001, 5.0), "kd": (0.3, 30.0)}
DELTAS = {"delta1": (0.002, 0.08), "delta2": (0.1, 1.5)}


def _tiny_config(**overrides: object) -> dict:
    cfg = {
        "name": "tiny",
        "vehicle": "x500",
        "structure": "nlvg",
        "groups": [["roll", "pitch"]],
        "experiments": [{"kind": "step", "channel": "roll", "amplitude": 0.3, "duration_s": 0.3, "weight": 11.0}],
        "bounds": {k: list(v) for k, v in BOUNDS.items()},
        "delta_bounds": {k: list(v) for k, v in DELTAS.items()},
        "es": {"iterations": 1, "restarts": 2, "seed": 0},
        "noise_scale": 1.0,
        "seeds": [1, 2],
        "eval_seeds": [7],
        "effort_weight": 0.05,
        "overshoot_weight": 0.5,
    }
    cfg.update(overrides)
    return cfg


def test_noise_stream_shares_draws_within_a_seed_block_and_differs_between_seeds() -> None:
    a = NoiseStream(DEFAULT_FEEDBACK_NOISE, (1, 2), m=3, n_steps=2000, dt_s=0.004)
    b = NoiseStream(DEFAULT_FEEDBACK_NOISE, (1,), m=1, n_steps=2000, dt_s=0.004)
    dp = a.at(10)[0]
    assert dp.shape == (6, 3)
    np.testing.assert_array_equal(dp[0], dp[2])  # same seed block: same draws for every gain set
    assert not np.allclose(dp[0], dp[3])  # another seed: other draws
    np.testing.assert_array_equal(b.at(10)[0][0], dp[0])  # a seed always gives the same sequence
    pos = np.array([a.at(k)[0][0] for k in range(2000)])
    # white 0.03 m on a drift of 0.4 m (τ 5 s over 8 s): the step-to-step change is the white part (× √2)
    assert 0.03 < np.std(np.diff(pos[:, 0])) < 0.06
    q = rotate_body(np.array([[1.0, 0.0, 0.0, 0.0]]), np.array([[0.2, 0.0, 0.0]]))
    np.testing.assert_allclose(q[0], [np.cos(0.1), np.sin(0.1), 0.0, 0.0], atol=1e-12)


def test_noisy_step_costs_use_the_true_error_and_the_same_noise_for_every_gain_set() -> None:
    stiff = CascadeGains.fixed_pid(attitude=(12.0, 0.1, 6.0))
    g = CascadeGains.stacked([CascadeGains.fixed_pid(), CascadeGains.fixed_pid(), stiff])
    clean = run_step("x500", g, "roll", 0.02, 0.4, m=3)
    noisy = run_step("x500", g, "roll", 0.02, 0.4, m=3, noise=DEFAULT_FEEDBACK_NOISE, seeds=(1, 2))
    assert noisy.error.shape == (6, clean.error.shape[1]) and noisy.n_seeds == 2
    np.testing.assert_array_equal(noisy.error[0], noisy.error[1])  # identical gains, identical noise
    assert not np.allclose(noisy.error[0], noisy.error[3])  # other seed
    assert not np.allclose(noisy.error[0], clean.error[0])  # the noise acts
    assert np.all(noisy.chatter > clean.chatter[0])  # noise makes the motors chatter
    assert np.all(np.isfinite(noisy.chatter)) and np.all(noisy.overshoot >= 0.0)


def test_config_checks_the_new_keys() -> None:
    with pytest.raises(TuneConfigError, match="unknown keys"):
        tune_config_from_dict(_tiny_config(effort=1.0))
    with pytest.raises(TuneConfigError, match="held out"):
        tune_config_from_dict(_tiny_config(eval_seeds=[2]))
    with pytest.raises(TuneConfigError, match="delta"):
        tune_config_from_dict(_tiny_config(delta_bounds={"delta1": [0.01, 0.5], "delta2": [0.2, 1.0]}))
    with pytest.raises(TuneConfigError, match="nlvg"):
        tune_config_from_dict(_tiny_config(structure="pid"))


def test_deltas_are_learned_parameters() -> None:
    p = GainParametrisation(CascadeGains.fixed_pid(), (("roll", "pitch"),), Structure.NLVG, BOUNDS, DELTAS)
    assert p.names[-2:] == ("roll+pitch.delta1", "roll+pitch.delta2") and p.space().dim == 8
    k = np.array([[8.0, 0.1, 5.0, 4.0, 0.1, 3.0, 0.02, 0.5], [8.0, 0.1, 5.0, 4.0, 0.1, 3.0, 0.05, 1.0]])
    g = p.gains(k)
    np.testing.assert_allclose(g.roll.delta1, [0.02, 0.05])
    np.testing.assert_allclose(g.select(1).pitch.delta2, 1.0)
    np.testing.assert_allclose(p.vector(p.single(k[1])), k[1])
    # a PID's paper δ (0.01, 0.838) lies inside the box: the warm start keeps them
    np.testing.assert_allclose(p.vector(CascadeGains.fixed_pid())[-2:], [0.01, 0.838])


def test_nlvg_warm_started_at_the_tuned_pid_never_ends_worse_on_its_cost(tmp_path: Path) -> None:
    cfg = tune_config_from_dict(_tiny_config())
    pid = tune(pid_twin(cfg))
    nlvg = tune(replace(cfg, warm_start=pid.gains))
    assert nlvg.result.j_history[0, 0] == pytest.approx(pid.result.j_best, rel=1e-12)
    assert nlvg.result.j_best <= pid.result.j_best
    terms = cost_terms(cfg, CascadeGains.stacked([pid.gains, nlvg.gains]), 2, cfg.seeds)
    assert terms.total[1] == pytest.approx(nlvg.result.j_best, rel=1e-9)
    assert np.all(terms.chatter_sq > 0.0)


def test_tuned_gains_file_flies_through_params(tmp_path: Path) -> None:
    """Tune a tiny problem, write the gains file, load it with ``--params`` as it is and fly a hover with it."""
    cfg = tune_config_from_dict(_tiny_config(es={"iterations": 1, "restarts": 1, "seed": 0}))
    outcome = tune(cfg)
    paths = write_outputs(outcome, tmp_path, command="test")
    assert yaml.safe_load(paths["gains"].read_text())["provenance"]["command"] == "test"
    store = make_param_store(paths["gains"])
    tuned = outcome.gains.roll
    assert store.get(gain_param_name("roll", "P", 1)) == pytest.approx(float(tuned.k1[0]))
    assert store.get(gain_param_name("roll", "D", 2)) == pytest.approx(float(tuned.k2[2]))
    assert store.get("NV_ROLL_DLT2") == pytest.approx(float(tuned.delta2))
    loop = SimLoop("x500", params=store)
    loop.take_off(alt_m=5.0, settle_s=2.0)
    assert abs(loop.alt_m - 5.0) < 0.5
    assert float(loop.ap.control.gains.roll.k1[0]) == pytest.approx(float(tuned.k1[0]))


def test_params_refuses_a_bad_gains_file_in_one_line(tmp_path: Path) -> None:
    bad = tmp_path / "gains.yaml"
    data = CascadeGains.fixed_pid().to_dict()
    data["channels"]["roll"]["k1"] = [1.0, -2.0, 3.0]
    bad.write_text(yaml.safe_dump(data))
    with pytest.raises(ParamError) as err:
        make_param_store(bad)
    assert "\n" not in str(err.value) and "roll" in str(err.value)
    bad.write_text("format: something/2\nX: 1\n")
    with pytest.raises(ParamError, match="unknown file format"):
        make_param_store(bad)


def test_shipped_defaults_are_an_es_tuned_nlvg() -> None:
    data = yaml.safe_load(DEFAULT_GAINS_PATH.read_text())
    assert "tune_es --ship" in data["provenance"]["command"]  # as run: tools.tune_es before tools.research
    shipped = shipped_gains()
    defaults = gains_from_params({})
    assert defaults == shipped
    assert any(
        not np.allclose(getattr(shipped, ch).k1, getattr(shipped, ch).k2) for ch in ("x", "y", "z", "roll", "pitch")
    )
