"""One NLVG-PID term: fixed-PID equivalence, time scale, windup bound, no derivative kick, NaN guard."""

from __future__ import annotations

import math

import numpy as np
import pytest

from autopilot.control.pid import NlvgPidBatch, Schedule, gain_row

DT = 0.004


def _pid(k1=(2.0, 0.5, 0.3), k2=None, u_max=100.0, i_max=50.0, n=1, time_scale_s=1.0, **kw) -> NlvgPidBatch:
    pid = NlvgPidBatch(n, DT, u_max, i_max, time_scale_s)
    pid.set_gains(gain_row(k1, k2 or k1, **kw))
    return pid


def test_fixed_gains_match_a_hand_written_pid() -> None:
    pid = _pid()
    rng = np.random.default_rng(1)
    integral = 0.0
    for _ in range(200):
        e, de = rng.normal(), rng.normal()
        integral += 0.5 * e * DT
        u = pid.update(e, de)[0]
        assert u == pytest.approx(2.0 * e + 0.3 * de + integral, rel=1e-12, abs=1e-12)


def test_time_scale_normalises_gains() -> None:
    t = 0.15
    pid = _pid(time_scale_s=t)
    u = pid.update(0.1, -0.2)[0]
    w = 1.0 / t
    assert u == pytest.approx(w * w * 2.0 * 0.1 + w * 0.3 * -0.2 + w**3 * 0.5 * 0.1 * DT)


def test_live_gains_follow_the_schedule() -> None:
    pid = _pid(k1=(1.0, 0.1, 0.2), k2=(3.0, 0.3, 0.6), delta1=0.01, delta2=0.838)
    pid.update(0.005, 0.0)
    np.testing.assert_allclose(pid.k_live[0], [1.0, 0.1, 0.2])
    pid.update(-2.0, 0.0)
    np.testing.assert_allclose(pid.k_live[0], [3.0, 0.3, 0.6])


def test_per_term_schedule_uses_each_terms_signal() -> None:
    pid = _pid(k1=(1.0, 0.1, 0.2), k2=(3.0, 0.3, 0.6), schedule=int(Schedule.PER_TERM))
    pid.update(2.0, 0.0)  # large e, zero ė, tiny ∫e
    kp, ki, kd = pid.k_live[0]
    assert (kp, ki, kd) == pytest.approx((3.0, 0.1, 0.2))


def test_integrator_windup_is_bounded_and_recovers_fast() -> None:
    pid = _pid(k1=(1.0, 5.0, 0.0), u_max=2.0, i_max=1.5)
    for _ in range(5000):  # 20 s of a large persistent error
        u = pid.update(10.0, 0.0)[0]
        assert u <= 2.0
    # P alone saturates: conditional integration keeps I from growing at all
    assert pid.integral[0] == 0.0
    pid.reset()
    for _ in range(5000):  # moderate error: I grows but never beyond i_max
        pid.update(0.5, 0.0)
        assert abs(pid.integral[0]) <= 1.5 + 1e-12
    # the error reverses: the output leaves the positive limit within one step (no wound-up I to unwind)
    u = pid.update(-2.0, 0.0)[0]
    assert u < 0.0


def test_no_derivative_kick_on_setpoint_step() -> None:
    pid = _pid(k1=(2.0, 0.0, 5.0))
    meas_rate = 0.0  # the measurement is at rest: derivative on measurement sees no change
    before = pid.update(0.0, -meas_rate)[0]
    after = pid.update(1.0, -meas_rate)[0]  # setpoint steps by 1
    assert after - before == pytest.approx(2.0)  # only the P term moves; a D on error would add kd/dt = 1250


def test_nan_input_holds_last_output_and_state() -> None:
    pid = _pid()
    u_ok = pid.update(0.3, 0.1)[0]
    state = pid.state.copy()
    for bad in (math.nan, math.inf, -math.inf):
        assert pid.update(bad, 0.0)[0] == u_ok
        assert pid.update(0.2, bad)[0] == u_ok
    np.testing.assert_array_equal(pid.state, state)
    assert np.isfinite(pid.update(0.2, 0.0)[0])


def test_nan_before_any_valid_input_gives_zero() -> None:
    assert _pid().update(math.nan, 0.0)[0] == 0.0


def test_batch_terms_are_independent() -> None:
    pid = NlvgPidBatch(3, DT, 100.0, 50.0)
    pid.set_gains(np.stack([gain_row((k, 0.0, 0.0), (k, 0.0, 0.0)) for k in (1.0, 2.0, 3.0)]))
    np.testing.assert_allclose(pid.update(np.array([1.0, 1.0, math.nan]), 0.0), [1.0, 2.0, 0.0])
