"""ES tuner end to end: config parsing, gain-vector mapping, tiny closed-loop tune, output files (SPEC §6.3)."""

from __future__ import annotations

import csv
import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from conftest import REPO_ROOT

from autopilot.control.gains import CascadeGains
from tools.research.experiments.gain_vector import GainParametrisation, Structure
from tools.research.experiments.tune_config import TuneConfigError, load_tune_config, tune_config_from_dict
from tools.research.experiments.tuner import tune, write_outputs

CONFIG_DIR = REPO_ROOT / "tools" / "research" / "experiments"
BOUNDS = {"kp": (0.5, 60.0), "ki": (0.001, 5.0), "kd": (0.3, 30.0)}


def test_gain_vector_maps_nlvg_and_pid_layouts() -> None:
    base = CascadeGains.fixed_pid()
    nlvg = GainParametrisation(base, (("roll", "pitch"),), Structure.NLVG, BOUNDS)
    assert nlvg.names == tuple(f"roll+pitch.{lvl}.{t}" for lvl in ("k1", "k2") for t in ("kp", "ki", "kd"))
    k = np.array([[1.0, 0.1, 2.0, 3.0, 0.3, 4.0], [5.0, 0.5, 6.0, 7.0, 0.7, 8.0]])
    g = nlvg.gains(k)
    assert g.n == 2
    np.testing.assert_allclose(g.roll.k1[0], [1.0, 5.0])
    np.testing.assert_allclose(g.pitch.k2[2], [4.0, 8.0])
    np.testing.assert_allclose(g.x.k1[0], [5.0, 5.0])  # untuned channel keeps the base gains
    np.testing.assert_allclose(nlvg.vector(nlvg.single(k[1])), k[1])
    pid = GainParametrisation(base, (("x",), ("y",)), Structure.PID, BOUNDS)
    gp = pid.gains(np.array([[1.0, 0.1, 2.0, 3.0, 0.3, 4.0]]))
    assert gp.x.k1 == gp.x.k2 and gp.y.k1 == gp.y.k2
    np.testing.assert_allclose(np.ravel(gp.y.k1), [3.0, 0.3, 4.0])
    space = pid.space()
    assert space.dim == 6 and space.log_scale and np.all(space.lower > 0)


def test_config_errors_name_the_key() -> None:
    good = {
        "vehicle": "x500",
        "groups": [["roll"]],
        "experiments": [{"kind": "step", "channel": "roll", "amplitude": 0.5, "duration_s": 0.5}],
        "bounds": {k: list(v) for k, v in BOUNDS.items()},
    }
    assert tune_config_from_dict(good).structure is Structure.NLVG
    with pytest.raises(TuneConfigError, match="unknown channel"):
        tune_config_from_dict({**good, "groups": [["rol"]]})
    with pytest.raises(TuneConfigError, match="bounds"):
        tune_config_from_dict({**good, "bounds": {"kp": [1, 2]}})
    with pytest.raises(TuneConfigError, match="unknown keys"):
        tune_config_from_dict({**good, "es": {"iterationz": 3}})
    with pytest.raises(TuneConfigError, match="method"):
        tune_config_from_dict({**good, "method": "bayes"})


def test_shipped_configs_load() -> None:
    names = sorted(p.name for p in CONFIG_DIR.glob("*.yaml"))
    assert {"attitude_nlvg.yaml", "attitude_pid.yaml", "position_nlvg.yaml", "position_pid.yaml"} <= set(names)
    for name in names:
        load_tune_config(CONFIG_DIR / name)


@pytest.mark.parametrize("method", ["central", "perturbation"])
def test_tiny_closed_loop_tune_lowers_cost_and_round_trips(tmp_path: Path, method: str) -> None:
    """Start from deliberately soft attitude gains: a few ES iterations on a short roll step must lower J."""
    base = CascadeGains.fixed_pid(attitude=(2.0, 0.05, 1.5))
    es = {"iterations": 3, "restarts": 2, "seed": 1} if method == "central" else {"iterations": 12, "restarts": 3}
    cfg = tune_config_from_dict(
        {
            "name": f"tiny_{method}",
            "vehicle": "x500",
            "structure": "nlvg",
            "method": method,
            "groups": [["roll"]],
            "experiments": [{"kind": "step", "channel": "roll", "amplitude": 0.3, "duration_s": 0.4}],
            "bounds": {k: list(v) for k, v in BOUNDS.items()},
            "es": es,
        }
    )
    cfg = replace(cfg, base_gains=base)
    out = tune(cfg)
    res = out.result
    j_base = float(res.j_history[0, 0])  # restart 0 starts at the base gains
    assert res.j_best < 0.9 * j_base
    paths = write_outputs(out, tmp_path)
    loaded = CascadeGains.from_yaml(paths["gains"])
    param = cfg.parametrisation()
    np.testing.assert_allclose(param.vector(loaded), res.k_best, rtol=1e-12)
    assert loaded.pitch == base.pitch  # untuned channel unchanged
    with paths["csv"].open() as f:
        rows = list(csv.reader(f))
    assert len(rows) == res.j_history.shape[0] + 1
    summary = json.loads(paths["summary"].read_text())
    assert summary["j_best"] == pytest.approx(res.j_best) and summary["rollouts"] == res.n_evaluations
    assert paths["plot"].stat().st_size > 1000
