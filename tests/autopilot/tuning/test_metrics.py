"""Metrics of SPEC §6.4 against closed forms: IAE/ITAE/ITSE with t_peak, ES cost, overshoot, settling."""

from __future__ import annotations

import math

import numpy as np
import pytest

from autopilot.tuning import metrics as m

TP = m.T_PEAK_POSITION_S


def _grid(dt: float = 1e-5, end: float = 1.0) -> np.ndarray:
    return np.arange(0.0, end + dt / 2, dt)


def test_constant_error_closed_forms_on_an_unaligned_grid() -> None:
    t = np.arange(0.0, 1.0, 0.004)  # 0.37 s is not a sample time: the cut must be exact anyway
    e = np.full_like(t, 0.5)
    assert m.iae(e, t, TP) == pytest.approx(0.5)
    assert m.itae(e, t, TP) == pytest.approx(0.5 * TP / 2)
    assert m.itse(e, t, TP) == pytest.approx(0.25 * TP / 2)


def test_ramp_closed_forms() -> None:
    t = _grid()
    a = 3.0
    e = -a * t  # sign must not matter for IAE/ITAE/ITSE
    assert m.iae(e, t, TP) == pytest.approx(a * TP / 2, rel=1e-8)
    assert m.itae(e, t, TP) == pytest.approx(a * TP**2 / 3, rel=1e-8)
    assert m.itse(e, t, TP) == pytest.approx(a * a * TP**3 / 4, rel=1e-6)


def test_exponential_closed_forms_and_batch_shape() -> None:
    t = _grid()
    tau = np.array([0.05, 0.2])
    e = np.exp(-t[None, :] / tau[:, None])
    tp = m.T_PEAK_ATTITUDE_S
    iae = tau * (1 - np.exp(-tp / tau)) / tp
    itae = (tau**2 - tau * (tp + tau) * np.exp(-tp / tau)) / tp
    sig = tau / 2
    itse = (sig**2 - sig * (tp + sig) * np.exp(-tp / sig)) / tp
    np.testing.assert_allclose(m.iae(e, t, tp), iae, rtol=1e-7)
    np.testing.assert_allclose(m.itae(e, t, tp), itae, rtol=1e-7)
    np.testing.assert_allclose(m.itse(e, t, tp), itse, rtol=1e-6)


def test_time_is_measured_from_the_first_sample() -> None:
    t = _grid() + 12.0
    e = t - 12.0
    assert m.itae(e, t, TP) == pytest.approx(TP**2 / 3, rel=1e-8)


def test_es_cost_of_a_sine_over_whole_periods_is_half() -> None:
    t = _grid(1e-4, 2.0)
    assert m.es_cost(np.sin(2 * np.pi * t), t) == pytest.approx(0.5, rel=1e-8)
    assert m.es_cost(np.ones_like(t) * 2, t, 0.5, 1.5) == pytest.approx(4.0)


def test_rms_and_max() -> None:
    e = np.array([[3.0, -4.0], [1.0, 1.0]])
    np.testing.assert_allclose(m.rms(e), [math.sqrt(12.5), 1.0])
    np.testing.assert_allclose(m.max_abs(e), [4.0, 1.0])


def test_second_order_overshoot_and_first_order_settling() -> None:
    t = _grid(1e-4, 10.0)
    zeta, wn = 0.3, 4.0
    wd = wn * math.sqrt(1 - zeta**2)
    y2 = 1 - np.exp(-zeta * wn * t) * (np.cos(wd * t) + zeta / math.sqrt(1 - zeta**2) * np.sin(wd * t))
    assert m.overshoot(y2, 0.0, 1.0) == pytest.approx(math.exp(-math.pi * zeta / math.sqrt(1 - zeta**2)), rel=1e-6)
    tau = 0.5
    y1 = 2.0 - 2.0 * np.exp(-t / tau)  # first-order step response from 0 to 2
    assert m.overshoot(y1, 0.0, 2.0) == 0.0
    assert m.settling_time(y1, t, 0.0, 2.0, band=0.05) == pytest.approx(tau * math.log(20), abs=2e-4)
    assert m.rise_time(y1, t, 0.0, 2.0) == pytest.approx(tau * math.log(9), abs=2e-4)
    assert m.settling_time(np.zeros_like(t), t, 0.0, 2.0) == math.inf


def test_bad_time_axis_is_refused() -> None:
    with pytest.raises(ValueError):
        m.iae(np.ones(5), np.array([0, 1, 1, 2, 3.0]), 0.15)
    with pytest.raises(ValueError):
        m.iae(np.ones(5), np.arange(5.0) * 0.01, 0.15)  # record shorter than t_peak
