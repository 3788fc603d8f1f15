"""k(s) of SPEC §6.1: limits, continuity, monotonicity, and the paper-literal variant's jump at δ2."""

from __future__ import annotations

import numpy as np
import pytest

from autopilot.control.gain_schedule import GainVariant, variable_gain

D1, D2 = 0.01, 0.838


@pytest.mark.parametrize(("k1", "k2"), [(2.0, 6.0), (6.0, 2.0), (0.1, 0.1)])
def test_limits_k1_below_delta1_and_k2_above_delta2(k1: float, k2: float) -> None:
    s = np.array([0.0, 0.5 * D1, -0.5 * D1, D2 + 1e-6, 5.0, -50.0])
    k = variable_gain(s, k1, k2, D1, D2)
    np.testing.assert_allclose(k, [k1, k1, k1, k2, k2, k2])
    mid = variable_gain(0.5 * (D1 + D2), k1, k2, D1, D2)
    assert mid == pytest.approx(0.5 * (k1 + k2))


@pytest.mark.parametrize(("k1", "k2"), [(2.0, 6.0), (6.0, 2.0)])
def test_raised_cosine_is_continuous_and_monotone(k1: float, k2: float) -> None:
    s = np.linspace(0.0, 1.5, 150_001)
    k = variable_gain(s, k1, k2, D1, D2)
    step = np.diff(k)
    # continuity: the largest jump between neighbours is bounded by the maximum slope × ds
    max_slope = abs(k2 - k1) / 2 * np.pi / (D2 - D1)
    assert np.max(np.abs(step)) <= max_slope * (s[1] - s[0]) * 1.0001
    # monotone from k1 to k2
    assert np.all(np.sign(k2 - k1) * step >= -1e-12)
    for edge in (D1, D2):
        left, right = variable_gain(np.array([edge - 1e-9, edge + 1e-9]), k1, k2, D1, D2)
        assert left == pytest.approx(right, abs=1e-6)


def test_gain_is_even_in_s_and_broadcasts() -> None:
    s = np.linspace(-2, 2, 41).reshape(41, 1)
    k1 = np.array([1.0, 2.0, 3.0])
    k = variable_gain(s, k1, 2 * k1, D1, D2)
    assert k.shape == (41, 3)
    np.testing.assert_allclose(k, k[::-1])


def test_paper_literal_returns_near_k1_at_delta2_then_jumps_to_k2() -> None:
    k1, k2 = 2.0, 6.0
    amp = 0.5 * (k2 - k1)
    at_d2 = variable_gain(D2, k1, k2, D1, D2, "paper_literal")
    past_d2 = variable_gain(D2 + 1e-9, k1, k2, D1, D2, "paper_literal")
    assert abs(at_d2 - k1) < 0.01 * amp  # the printed cosine completes a full period: back to ≈ k1
    assert past_d2 - at_d2 > 1.9 * amp  # … then a jump of ≈ 2A
    # the default variant is continuous at the same place
    rc = variable_gain(np.array([D2, D2 + 1e-9]), k1, k2, D1, D2, GainVariant.RAISED_COSINE)
    assert rc[1] - rc[0] < 1e-6
    # and the literal one is not monotone inside [δ1, δ2]
    s = np.linspace(D1, D2, 1001)
    assert np.any(np.diff(variable_gain(s, k1, k2, D1, D2, "paper_literal")) < 0.0)


def test_bad_deltas_and_variant_are_refused() -> None:
    with pytest.raises(ValueError, match="delta"):
        variable_gain(0.1, 1.0, 2.0, 0.5, 0.5)
    with pytest.raises(ValueError, match="variant"):
        variable_gain(0.1, 1.0, 2.0, variant="cubic")
