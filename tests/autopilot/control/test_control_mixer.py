"""Quad-X mixer: hover, torque signs per motor (PX4 order), saturation priority, NaN, range."""

from __future__ import annotations

import math

import numpy as np
import pytest

from autopilot.control.airframe import load_airframe
from autopilot.control.mixer import QuadXMixer

G = 9.80665


@pytest.fixture(scope="module")
def mixer() -> QuadXMixer:
    return QuadXMixer(load_airframe("x500"))


def test_hover_spins_all_motors_equally(mixer: QuadXMixer) -> None:
    af = mixer.airframe
    u = mixer.mix(af.mass_kg * G, np.zeros(3))[0]
    expected = math.sqrt(af.mass_kg * G / 4 / af.k_f) / af.omega_max_rad_s
    np.testing.assert_allclose(u, expected)
    np.testing.assert_allclose(mixer.wrench(u[None])[0], [af.mass_kg * G, 0, 0, 0], atol=1e-9)


@pytest.mark.parametrize(
    ("torque", "up"),
    [
        ((0.5, 0.0, 0.0), (1, 2)),  # +roll (right side down): left motors 1 rear-left, 2 front-left
        ((0.0, 0.5, 0.0), (0, 2)),  # +pitch (nose up): front motors 0 front-right, 2 front-left
        ((0.0, 0.0, 0.1), (0, 1)),  # +yaw: CCW motors 0, 1 (their reaction torque is +yaw)
    ],
)
def test_torque_signs_per_motor(mixer: QuadXMixer, torque: tuple, up: tuple) -> None:
    hover = mixer.mix(20.0, np.zeros(3))[0]
    u = mixer.mix(20.0, np.array(torque))[0]
    for i in range(4):
        assert (u[i] > hover[i]) == (i in up), f"motor {i}"


def test_unsaturated_request_is_met_exactly(mixer: QuadXMixer) -> None:
    w = np.array([22.0, 0.4, -0.3, 0.05])
    u = mixer.mix(w[0], w[1:])
    np.testing.assert_allclose(mixer.wrench(u)[0], w, atol=1e-9)


@pytest.mark.parametrize("collective_frac", [0.01, 0.5, 0.99])
def test_saturation_keeps_roll_pitch_authority(mixer: QuadXMixer, collective_frac: float) -> None:
    f_max = mixer.f_max_n
    thrust = collective_frac * 4 * f_max
    torque = np.array([0.6, -0.4, 0.0])  # needs ~±1.5 N per rotor differential
    got = mixer.wrench(mixer.mix(thrust, torque))[0]
    np.testing.assert_allclose(got[1:3], torque[:2], rtol=1e-9, atol=1e-9)  # roll/pitch kept in full
    if collective_frac != 0.5:
        assert abs(got[0] - thrust) > 0.1  # … by moving the collective, which gives way


def test_yaw_gives_way_last(mixer: QuadXMixer) -> None:
    f_max = mixer.f_max_n
    thrust = 0.9 * 4 * f_max
    torque = np.array([0.5, 0.0, 2.0])  # yaw far beyond what is left at 90 % collective
    got = mixer.wrench(mixer.mix(thrust, torque))[0]
    assert got[1] == pytest.approx(0.5, rel=1e-9)
    assert got[0] == pytest.approx(thrust, rel=1e-9)
    assert 0.0 < got[3] < 2.0


def test_impossible_roll_pitch_is_scaled_keeping_direction(mixer: QuadXMixer) -> None:
    torque = np.array([30.0, 10.0, 0.0])
    got = mixer.wrench(mixer.mix(20.0, torque))[0]
    assert got[1] / got[2] == pytest.approx(3.0, rel=1e-6)
    assert got[1] < 30.0


def test_commands_in_range_for_random_and_extreme_inputs(mixer: QuadXMixer) -> None:
    rng = np.random.default_rng(3)
    thrust = rng.uniform(-50, 200, 5000)
    torque = rng.normal(0, 5, (5000, 3)) * rng.choice([0.01, 1.0, 100.0], (5000, 1))
    u = mixer.mix(thrust, torque)
    assert np.all(np.isfinite(u)) and np.all((u >= 0.0) & (u <= 1.0))


def test_non_finite_input_keeps_previous_command(mixer: QuadXMixer) -> None:
    prev = np.full((3, 4), 0.4)
    thrust = np.array([20.0, math.nan, 20.0])
    torque = np.array([[0.0, 0.0, 0.0], [0.0, 0.0, 0.0], [math.inf, 0.0, 0.0]])
    u = mixer.mix(thrust, torque, u_prev=prev)
    np.testing.assert_array_equal(u[1:], prev[1:])
    assert not np.allclose(u[0], 0.4)
