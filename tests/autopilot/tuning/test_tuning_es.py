"""Extremum seeking as pure code: convergence on known quadratics, projection, batching (SPEC §6.3)."""

from __future__ import annotations

import numpy as np
import pytest

from autopilot.tuning import (
    CentralEsConfig,
    EsError,
    GainSpace,
    GainSpaceError,
    PerturbationEsConfig,
    central_es,
    dither_frequencies,
    perturbation_es,
)

D = 6
K_STAR = np.array([8.0, 0.1, 5.0, 2.0, 0.5, 3.0])  # paper-like magnitudes: k_p, k_i, k_d, ...


def _space(log_scale: bool = True) -> GainSpace:
    return GainSpace.from_bounds([f"g{j}" for j in range(D)], [0.01] * D, [100.0] * D, log_scale=log_scale)


def _hessian(seed: int) -> np.ndarray:
    a = np.random.default_rng(seed).normal(size=(D, D))
    return a @ a.T / D + 0.3 * np.eye(D)  # SPD, condition number ~ 10-30


def _quadratic(space: GainSpace, h: np.ndarray, j_min: float):
    z_star = space.to_unit(K_STAR)

    def cost(gains: np.ndarray) -> np.ndarray:
        dz = space.to_unit(gains) - z_star
        return j_min + np.einsum("mi,ij,mj->m", dz, h, dz)

    return cost, z_star


def test_gain_space_round_trip_and_projection() -> None:
    for log_scale in (True, False):
        space = _space(log_scale)
        z = np.random.default_rng(0).uniform(0, 1, size=(50, D))
        np.testing.assert_allclose(space.to_unit(space.to_gains(z)), z, atol=1e-12)
        wild = np.array([[-5.0, 0.0, 1e9, np.float64(50.0), 0.001, 200.0]])
        k = space.to_gains(space.to_unit(wild))
        assert np.all(k >= space.lower) and np.all(k <= space.upper)
        np.testing.assert_allclose(space.project(wild)[0], [0.01, 0.01, 100.0, 50.0, 0.01, 100.0])


def test_gain_space_rejects_bad_bounds() -> None:
    with pytest.raises(GainSpaceError, match="g1"):
        GainSpace.from_bounds(["g0", "g1"], [0.1, 2.0], [1.0, 1.0])
    with pytest.raises(GainSpaceError, match="positive lower bound"):
        GainSpace.from_bounds(["g0"], [0.0], [1.0], log_scale=True)
    with pytest.raises(GainSpaceError):
        GainSpace.from_bounds(["g0", "g1"], [0.1], [1.0])


@pytest.mark.parametrize("seed", [0, 1, 2])
@pytest.mark.parametrize("j_min", [1.0, 0.0])
def test_central_es_converges_on_quadratic_from_random_starts(seed: int, j_min: float) -> None:
    space = _space()
    cost, z_star = _quadratic(space, _hessian(seed), j_min)
    res = central_es(cost, space, CentralEsConfig(iterations=40, restarts=5, seed=seed))
    assert np.max(np.abs(space.to_unit(res.k_best) - z_star)) < 0.01
    assert res.j_best - j_min < 1e-3
    # every restart started at a random point and every restart improved substantially on its own
    start_err = np.abs(space.to_unit(res.k_history[0]) - z_star).max(axis=1)
    end_err = np.abs(space.to_unit(res.k_history[-1]) - z_star).max(axis=1)
    assert np.all(start_err > 0.05)
    assert np.all(end_err < 0.5 * start_err)
    # the accepted cost of every restart never increases (backtracking)
    assert np.all(np.diff(res.j_history, axis=0) <= 0.0)


def test_central_es_runs_one_batch_per_iteration_with_all_rollouts() -> None:
    space = _space()
    cost, _ = _quadratic(space, _hessian(0), 0.0)
    calls: list[int] = []

    def counting_cost(gains: np.ndarray) -> np.ndarray:
        calls.append(gains.shape[0])
        return cost(gains)

    cfg = CentralEsConfig(iterations=5, restarts=3, step_min=1e-9, seed=0)
    res = central_es(counting_cost, space, cfg)
    assert calls == [cfg.batch_size(D)] * 6 == [3 * (2 * D + 1)] * 6
    assert res.n_batches == 6 and res.n_evaluations == sum(calls)
    assert res.j_history.shape == (6, 3) and res.k_history.shape == (6, 3, D)


def test_central_es_gradient_matches_central_difference() -> None:
    """One step from a known point follows -grad J / |grad J| of a linear cost (no factor-2 error)."""
    space = GainSpace.from_bounds(["a", "b"], [0.0, 0.0], [1.0, 1.0], log_scale=False)
    slope = np.array([3.0, -4.0])

    def linear(gains: np.ndarray) -> np.ndarray:
        return 10.0 + gains @ slope

    cfg = CentralEsConfig(iterations=1, restarts=1, step_initial=0.1, probe_width=0.01, seed=0)
    res = central_es(linear, space, cfg, initial_gains=np.array([0.5, 0.5]))
    np.testing.assert_allclose(res.k_history[1, 0], [0.5 - 0.06, 0.5 + 0.08], atol=1e-12)
    plain = central_es(
        linear, space, CentralEsConfig(**{**_cfg_dict(cfg), "normalize_gradient": False, "step_initial": 0.01})
    )
    z0 = plain.k_history[0, 0]
    np.testing.assert_allclose(plain.k_history[1, 0], np.clip(z0 - 0.01 * slope, 0, 1), atol=1e-12)


def _cfg_dict(cfg: CentralEsConfig) -> dict[str, object]:
    return {name: getattr(cfg, name) for name in cfg.__dataclass_fields__}


def test_projection_keeps_gains_positive_and_bounded() -> None:
    """Minimum outside the box (k_p wants to go below zero, k_i above its bound): ES ends on the bounds."""
    space = GainSpace.from_bounds(["kp", "ki", "kd"], [0.05, 0.01, 0.1], [20.0, 2.0, 10.0])
    z_target = np.array([-0.5, 1.5, 0.4])  # k_p -> 0.05 * 400**-0.5 = 0.0025 (outside), k_i -> 2 * 200**0.5
    seen: list[np.ndarray] = []

    def cost(gains: np.ndarray) -> np.ndarray:
        seen.append(gains.copy())
        z = np.log(gains / space.lower) / np.log(space.upper / space.lower)  # unclipped, independent of GainSpace
        return np.sum((z - z_target) ** 2, axis=1)

    for method in ("central", "perturbation"):
        seen.clear()
        if method == "central":
            res = central_es(cost, space, CentralEsConfig(iterations=30, restarts=4, seed=3))
        else:
            res = perturbation_es(cost, space, PerturbationEsConfig(iterations=150, restarts=4, seed=3))
        allk = np.concatenate(seen)
        assert np.all(allk > 0.0)
        assert np.all(allk >= space.lower) and np.all(allk <= space.upper)
        tol = 0.01 if method == "central" else 0.2  # the dithered method sits about a dither amplitude off
        assert res.k_best[0] == pytest.approx(0.05, rel=tol)
        assert res.k_best[1] == pytest.approx(2.0, rel=tol)
        assert res.k_best[2] == pytest.approx(0.1 * 100.0**0.4, rel=tol)


def test_diverged_rollouts_never_win() -> None:
    space = _space()
    cost, z_star = _quadratic(space, _hessian(4), 0.0)

    def unstable(gains: np.ndarray) -> np.ndarray:
        j = cost(gains)
        j[gains[:, 0] > 30.0] = np.nan  # "diverged" region
        return j

    res = central_es(unstable, space, CentralEsConfig(iterations=30, restarts=4, seed=5))
    assert np.isfinite(res.j_best) and res.k_best[0] <= 30.0
    assert np.max(np.abs(space.to_unit(res.k_best) - z_star)) < 0.02


def test_all_diverged_raises() -> None:
    space = _space()
    with pytest.raises(EsError, match="diverged"):
        central_es(lambda k: np.full(k.shape[0], np.inf), space, CentralEsConfig(iterations=2, restarts=2))
    with pytest.raises(EsError, match="shape"):
        central_es(lambda k: np.zeros(3), space, CentralEsConfig(iterations=2, restarts=2))


def test_dither_frequencies_avoid_second_order_aliasing() -> None:
    for d in (2, 3, 6, 9):
        w = dither_frequencies(d)
        assert np.all((w > 0) & (w < np.pi)) and len(np.unique(w)) == d
        pairs = [w[i] + s * w[j] for i in range(d) for j in range(d) for s in (1, -1) if i != j or s == 1]
        folded = np.abs(np.angle(np.exp(1j * np.asarray(pairs))))  # alias into [0, pi]
        assert np.min(np.abs(folded[:, None] - w[None, :])) > 0.05


@pytest.mark.parametrize("seed", [0, 1, 2])
@pytest.mark.parametrize("j_min", [1.0, 0.01])
def test_perturbation_es_finds_minimum_of_static_map(seed: int, j_min: float) -> None:
    space = _space()
    cost, z_star = _quadratic(space, _hessian(seed), j_min)
    cfg = PerturbationEsConfig(iterations=250, restarts=5, seed=seed)
    res = perturbation_es(cost, space, cfg)
    start_err = np.abs(space.to_unit(res.k_history[0]) - z_star).max(axis=1)
    end_err = np.abs(space.to_unit(res.k_history[-1]) - z_star).max(axis=1)
    assert np.median(start_err) > 0.2
    assert np.median(end_err) < 0.06  # about one dither amplitude (0.05) from the minimiser
    assert np.all(end_err < 0.15)  # and every loop within three
    assert res.j_best < j_min + 0.01
    assert res.n_batches == 251 and res.j_history.shape == (251, 5)
