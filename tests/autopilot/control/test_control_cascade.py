"""Cascade unit tests without a simulator: equilibrium, signs, limits, NaN guard, batch == single, gain files."""

from __future__ import annotations

import math

import numpy as np
import pytest

from autopilot.control import CascadeController, CascadeGains, CascadeLimits, NlvgGains, load_airframe
from mavlink_bridge.contract.frames import quat_from_euler

G = 9.80665
AF = load_airframe("x500")
LEVEL = np.array([1.0, 0.0, 0.0, 0.0])
Z3 = np.zeros(3)


def _ctrl(n: int = 1, gains: CascadeGains | None = None) -> CascadeController:
    return CascadeController(AF, gains or CascadeGains.paper_default(k1_scale=0.8, k2_scale=1.5), n=n)


def _step(c: CascadeController, pos=Z3, vel=Z3, q=LEVEL, rate=Z3, sp=Z3, vsp=Z3, aff=Z3, yaw=0.0) -> np.ndarray:
    return c.update_position(pos, vel, q, rate, sp, vsp, aff, yaw)


def test_hover_equilibrium_gives_equal_hover_commands() -> None:
    c = _ctrl()
    u = _step(c)
    hover_u = math.sqrt(AF.mass_kg * G / 4 / AF.k_f) / AF.omega_max_rad_s
    np.testing.assert_allclose(u, hover_u, rtol=1e-12)
    assert c.diagnostics.thrust_n[0] == pytest.approx(AF.mass_kg * G)
    np.testing.assert_allclose(c.diagnostics.torque_frd_nm, 0.0, atol=1e-12)


def test_position_errors_tilt_and_push_the_right_way() -> None:
    c = _ctrl()
    _step(c, sp=np.array([1.0, 0.0, 0.0]))
    assert c.diagnostics.att_sp_rad[0, 1] < 0.0  # north: nose down
    c.reset()
    _step(c, sp=np.array([0.0, 1.0, 0.0]))
    assert c.diagnostics.att_sp_rad[0, 0] > 0.0  # east: right side down
    c.reset()
    _step(c, sp=np.array([0.0, 0.0, -1.0]))
    assert c.diagnostics.thrust_n[0] > AF.mass_kg * G  # up: more thrust


def test_tilt_and_acceleration_limits_hold_for_huge_errors() -> None:
    lim = CascadeLimits(tilt_max_rad=math.radians(20.0))
    c = CascadeController(AF, CascadeGains.paper_default(), limits=lim)
    _step(c, sp=np.array([500.0, -300.0, 400.0]))  # far away and far below
    roll, pitch, _ = c.diagnostics.att_sp_rad[0]
    tilt = math.acos(math.cos(roll) * math.cos(pitch))
    assert tilt <= math.radians(20.0) + 1e-9
    assert c.diagnostics.acc_sp_ned[0, 2] <= lim.acc_down_max_m_s2 + 1e-9


def test_yaw_error_is_wrapped() -> None:
    c = _ctrl()
    q = quat_from_euler(0.0, 0.0, -math.pi + 0.1)
    _step(c, q=q, yaw=math.pi - 0.1)
    assert c.diagnostics.att_err_rad[0, 2] == pytest.approx(-0.2)


def test_live_gains_follow_error_size() -> None:
    g = CascadeGains.paper_default(k1_scale=0.5, k2_scale=2.0)
    c = _ctrl(gains=g)
    _step(c, sp=np.array([0.001, 5.0, 0.0]))
    kp = c.diagnostics.kp[0]
    assert kp[0] == pytest.approx(2.5) and kp[1] == pytest.approx(10.0)  # x: |e| < δ1 → k1; y: |e| > δ2 → k2


def test_nan_inputs_never_reach_the_motors() -> None:
    n = 9
    c = _ctrl(n)
    pos = np.zeros((n, 3))
    q = np.tile(LEVEL, (n, 1))
    sp = np.tile([0.3, -0.2, -0.5], (n, 1))
    u_good = c.update_position(pos, pos, q, pos, sp, pos, pos, np.zeros(n)).copy()
    bad_pos, bad_vel, bad_q, bad_rate = pos.copy(), pos.copy(), q.copy(), pos.copy()
    bad_sp, bad_vsp, bad_aff, bad_yaw = sp.copy(), pos.copy(), pos.copy(), np.zeros(n)
    bad_pos[0, 0] = math.nan
    bad_vel[1, 2] = math.inf
    bad_q[2] = math.nan
    bad_q[3] = 0.0  # not a rotation
    bad_rate[4, 1] = -math.inf
    bad_sp[5, 1] = math.nan
    bad_yaw[6] = math.nan
    bad_vsp[7, 0] = math.nan  # feed-forwards: NaN means "not controlled" → treated as zero
    bad_aff[8, 2] = math.nan
    u = c.update_position(bad_pos, bad_vel, bad_q, bad_rate, bad_sp, bad_vsp, bad_aff, bad_yaw)
    assert np.all(np.isfinite(u)) and np.all((u >= 0) & (u <= 1))
    np.testing.assert_array_equal(u[:7], u_good[:7])  # held
    np.testing.assert_array_equal(c.diagnostics.valid, [0, 0, 0, 0, 0, 0, 0, 1, 1])
    # rows 7, 8 ran with zero feed-forward: same as a fresh controller given zeros
    ref = _ctrl(n)
    ref.update_position(pos, pos, q, pos, sp, pos, pos, np.zeros(n))
    u_ref = ref.update_position(pos, pos, q, pos, sp, pos, pos, np.zeros(n))
    np.testing.assert_allclose(u[7:], u_ref[7:])


def test_random_and_extreme_inputs_give_commands_in_range() -> None:
    rng = np.random.default_rng(7)
    n = 2000
    c = _ctrl(n)
    for _ in range(5):
        scale = rng.choice([1e-3, 1.0, 1e3, 1e12], (n, 1))
        q = rng.normal(size=(n, 4))
        u = c.update_position(
            rng.normal(size=(n, 3)) * scale,
            rng.normal(size=(n, 3)) * scale,
            q,
            rng.normal(size=(n, 3)) * scale,
            rng.normal(size=(n, 3)) * scale,
            rng.normal(size=(n, 3)) * scale,
            rng.normal(size=(n, 3)) * scale,
            rng.normal(size=n) * scale[:, 0],
        )
        assert np.all(np.isfinite(u)) and np.all((u >= 0) & (u <= 1))
        att = c.update_attitude(q, rng.normal(size=(n, 3)) * scale, rng.normal(size=(n, 3)), rng.uniform(-5, 60, n))
        assert np.all(np.isfinite(att)) and np.all((att >= 0) & (att <= 1))


def test_batch_equals_independent_single_controllers() -> None:
    sets = [CascadeGains.paper_default(k1_scale=a, k2_scale=b) for a, b in ((0.5, 1.0), (1.0, 1.0), (0.7, 2.0))]
    batch = _ctrl(3, CascadeGains.stacked(sets))
    singles = [_ctrl(1, g) for g in sets]
    rng = np.random.default_rng(2)
    for _ in range(50):
        pos, vel, rate = rng.normal(size=(3, 3)) * 0.5, rng.normal(size=(3, 3)), rng.normal(size=(3, 3)) * 0.3
        q = quat_from_euler(*rng.normal(size=(3, 3)).T * 0.2)
        sp, yaw = rng.normal(size=(3, 3)), rng.normal(size=3)
        ub = batch.update_position(pos, vel, q, rate, sp, Z3, Z3, yaw)
        for i, s in enumerate(singles):
            us = s.update_position(pos[i], vel[i], q[i], rate[i], sp[i], Z3, Z3, yaw[i])
            np.testing.assert_allclose(ub[i], us[0], rtol=1e-12, atol=1e-15)


def test_set_mass_scales_thrust_and_set_gains_is_live() -> None:
    c = _ctrl()
    _step(c)
    c.set_mass_kg(AF.mass_kg * 0.7)
    _step(c)
    assert c.diagnostics.thrust_n[0] == pytest.approx(0.7 * AF.mass_kg * G)
    c.set_gains(CascadeGains.fixed_pid(position=(1.0, 0.0, 1.0)))
    _step(c, sp=np.array([2.0, 0.0, 0.0]))
    assert c.diagnostics.kp[0, 0] == 1.0
    with pytest.raises(ValueError):
        c.set_mass_kg(-1.0)


def test_reset_mask_clears_only_selected_vehicles() -> None:
    c = _ctrl(2)
    sp = np.array([[1.0, 0.0, 0.0], [1.0, 0.0, 0.0]])
    for _ in range(50):
        u = c.update_position(
            np.zeros((2, 3)), np.zeros((2, 3)), np.tile(LEVEL, (2, 1)), np.zeros((2, 3)), sp, Z3, Z3, 0
        )
    c.reset(np.array([True, False]))
    np.testing.assert_array_equal(c.diagnostics.motor_cmd[0], 0.0)
    np.testing.assert_array_equal(c.diagnostics.motor_cmd[1], u[1])


def test_gain_file_round_trip_stacking_and_validation(tmp_path) -> None:
    g = CascadeGains.paper_default(k1_scale=0.6, k2_scale=1.7, variant="paper_literal")
    path = tmp_path / "gains.yaml"
    g.to_yaml(path)
    back = CascadeGains.from_yaml(path)
    for a, b in zip(g.channels(), back.channels(), strict=True):
        assert a.to_dict() == b.to_dict()
    batch = CascadeGains.stacked([g, CascadeGains.fixed_pid(variant="paper_literal")])
    with pytest.raises(ValueError, match="differ"):
        CascadeGains.stacked([g, CascadeGains.fixed_pid()])
    assert batch.n == 2 and batch.table(2).shape[:2] == (2, 6)
    assert batch.select(1).roll.k1 == (8.0, 0.1, 5.0)
    with pytest.raises(ValueError):
        batch.to_yaml(path)
    with pytest.raises(ValueError, match="delta"):
        NlvgGains(k1=(1, 1, 1), k2=(1, 1, 1), delta1=1.0, delta2=0.5)
    with pytest.raises(ValueError, match="kp"):
        NlvgGains(k1=(-1, 1, 1), k2=(1, 1, 1))
    path.write_text("format: something-else\n")
    with pytest.raises(ValueError, match="format"):
        CascadeGains.from_yaml(path)


def test_per_term_schedule_in_the_cascade_uses_velocity_error_for_kd() -> None:
    g = CascadeGains.paper_default(k1_scale=0.5, k2_scale=2.0, schedule="per_term")
    c = _ctrl(gains=g)
    _step(c, vel=np.array([0.0, -3.0, 0.0]), sp=np.array([0.001, 0.001, 0.0]))
    kd = c.diagnostics.kd[0]
    kp = c.diagnostics.kp[0]
    assert kd[0] == pytest.approx(2.5) and kd[1] == pytest.approx(10.0)  # |ė_y| = 3 m/s > δ2 → k2
    assert kp[1] == pytest.approx(2.5)  # |e_y| = 1 mm < δ1 → k1
