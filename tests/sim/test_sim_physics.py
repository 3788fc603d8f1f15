"""Physics of the simulator (issue 2): hover, free fall, torque signs, angular momentum, RK4 order,
ground contact, payload, wind, batch/single equivalence, end reasons."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from mavlink_bridge.contract.frames import GRAVITY_M_S2, dcm_from_quat, euler_from_quat
from sim.batch import BatchSim
from sim.end_reason import EndReason
from sim.vehicle import VehicleSim
from sim.vehicle_config import load_vehicle, vehicle_names
from sim.world import Sphere, WindConfig, World, empty_world

X500 = load_vehicle("x500")
NO_DRAG = dataclasses.replace(X500, drag_body_n_per_m2_s2=(0.0, 0.0, 0.0), rotor_drag_n_s_per_m=0.0)


def _hover_cmd(sim: BatchSim | VehicleSim, scale: float = 1.0) -> np.ndarray:
    return np.full(4, scale * float(np.atleast_1d(sim.hover_omega_rad_s())[0]) / sim.vehicle.omega_max_rad_s)


def _airborne_at_hover(vehicle, alt_m: float = 10.0, **kw) -> VehicleSim:
    sim = VehicleSim(vehicle, **kw)
    sim.reset(pos_ned=[0.0, 0.0, -alt_m])
    sim.omega_rad_s[:] = sim.hover_omega_rad_s()
    return sim


@pytest.mark.parametrize("name", vehicle_names())
def test_sim_hover_omega_formula_holds_altitude(name: str) -> None:
    vehicle = load_vehicle(name)
    sim = _airborne_at_hover(vehicle)
    expected = np.sqrt(vehicle.mass_kg * GRAVITY_M_S2 / (4 * vehicle.k_f_n_per_rad2_s2))
    assert sim.hover_omega_rad_s() == pytest.approx(expected, rel=1e-12)
    cmd = _hover_cmd(sim)
    for _ in range(250 * 10):
        sim.step(cmd)
    assert abs(sim.pos_ned[2] + 10.0) < 1e-6
    assert np.max(np.abs(sim.vel_ned)) < 1e-6
    assert np.allclose(sim.specific_force_frd, [0.0, 0.0, -GRAVITY_M_S2], atol=1e-9)
    # 1 % more speed than hover must climb: the test above can fail
    sim2 = _airborne_at_hover(vehicle)
    for _ in range(250):
        sim2.step(_hover_cmd(sim2, 1.01))
    assert sim2.pos_ned[2] < -10.05


def test_sim_free_fall_at_g() -> None:
    sim = VehicleSim(NO_DRAG)
    sim.reset(pos_ned=[0.0, 0.0, -100.0])
    for _ in range(500):  # 2 s, motors off
        sim.step(np.zeros(4))
    t = 2.0
    assert sim.pos_ned[2] == pytest.approx(-100.0 + 0.5 * GRAVITY_M_S2 * t * t, abs=1e-9)
    assert sim.vel_ned[2] == pytest.approx(GRAVITY_M_S2 * t, abs=1e-9)
    assert np.allclose(sim.specific_force_frd, 0.0, atol=1e-12)  # free fall: accelerometer reads zero


# motor index -> expected signs of (roll, pitch, yaw) angular acceleration for a speed increase
_TORQUE_SIGNS = {0: (-1, +1, +1), 1: (+1, -1, +1), 2: (+1, +1, -1), 3: (-1, -1, -1)}


@pytest.mark.parametrize("motor", range(4))
def test_sim_each_motor_torque_sign(motor: int) -> None:
    sim = _airborne_at_hover(NO_DRAG)
    h = sim.hover_omega_rad_s()
    sim.omega_rad_s[motor] = 1.1 * h
    cmd = sim.omega_rad_s / NO_DRAG.omega_max_rad_s
    sim.step(cmd)
    signs = np.sign(sim.rate_frd)
    assert tuple(signs.astype(int)) == _TORQUE_SIGNS[motor]
    assert np.min(np.abs(sim.rate_frd)) > 1e-4


def test_sim_torque_free_spin_conserves_angular_momentum() -> None:
    vehicle = dataclasses.replace(NO_DRAG, inertia_kg_m2=(0.02, 0.03, 0.05))
    sim = VehicleSim(vehicle)
    sim.reset(pos_ned=[0.0, 0.0, -1000.0])
    sim.rate_frd[:] = [1.0, 2.0, 3.0]
    j = np.diag(vehicle.inertia_kg_m2)

    def momentum_ned() -> np.ndarray:
        return dcm_from_quat(sim.q_ned_frd) @ (j @ sim.rate_frd)

    h0 = momentum_ned()
    e0 = 0.5 * sim.rate_frd @ j @ sim.rate_frd
    rates = []
    for _ in range(250 * 5):
        sim.step(np.zeros(4))
        rates.append(sim.rate_frd.copy())
    assert np.allclose(momentum_ned(), h0, atol=1e-9)
    assert 0.5 * sim.rate_frd @ j @ sim.rate_frd == pytest.approx(e0, rel=1e-9)
    assert np.ptp(np.array(rates)[:, 0]) > 0.1  # the body rates really do precess


def _rk4_run(physics_hz: int) -> np.ndarray:
    vehicle = dataclasses.replace(NO_DRAG, inertia_kg_m2=(0.02, 0.03, 0.05))
    sim = BatchSim(vehicle, 1, physics_hz=physics_hz, control_hz=250)
    sim.reset(pos_ned=[0.0, 0.0, -100.0])
    sim.rate_frd[:] = [2.0, -1.0, 3.0]
    sim.omega_rad_s[:] = 600.0
    cmd = np.array([[0.80, 0.70, 0.75, 0.72]])
    for _ in range(250):  # 1 s
        sim.step(cmd)
    return sim.state[0].copy()


def test_sim_rk4_error_shrinks_16x_when_dt_halves() -> None:
    ref = _rk4_run(32000)
    e1 = np.max(np.abs(_rk4_run(500) - ref))
    e2 = np.max(np.abs(_rk4_run(1000) - ref))
    e3 = np.max(np.abs(_rk4_run(2000) - ref))
    assert 12.0 < e1 / e2 < 20.0
    assert 12.0 < e2 / e3 < 20.0


def test_sim_rests_on_ground_for_60_s() -> None:
    sim = VehicleSim(X500)
    sim.reset()
    idle = np.full(4, 0.3)  # spinning, thrust below weight
    for k in range(250 * 60):
        sim.step(np.zeros(4) if k < 250 * 30 else idle)
        assert sim.pos_ned[2] == 0.0
    assert np.all(sim.vel_ned == 0.0)
    assert np.all(sim.rate_frd == 0.0)
    assert sim.on_ground
    assert sim.end_reason == EndReason.RUNNING
    assert np.allclose(sim.specific_force_frd, [0.0, 0.0, -GRAVITY_M_S2], atol=1e-9)


def test_sim_takes_off_cleanly_without_spike() -> None:
    sim = VehicleSim(X500)
    sim.reset()
    cmd = _hover_cmd(sim, 1.2)
    z, accel_up = [], []
    for _ in range(250 * 2):
        sim.step(cmd)
        z.append(sim.pos_ned[2])
        accel_up.append(-(sim.specific_force_frd[2] + GRAVITY_M_S2))
    assert z[-1] < -1.0
    assert np.all(np.diff(z) <= 0.0)  # monotonic climb, no bounce
    max_accel = X500.k_f_n_per_rad2_s2 * 4 * (1.2 * sim.hover_omega_rad_s()) ** 2 / X500.mass_kg - GRAVITY_M_S2
    assert max(accel_up) <= max_accel + 1e-9  # never more than thrust allows: no launch spike


def test_sim_soft_landing_rests_and_hard_landing_is_ground_impact() -> None:
    soft = VehicleSim(X500)
    soft.reset(pos_ned=[0.0, 0.0, -0.5])
    soft.vel_ned[2] = 1.0
    soft.omega_rad_s[:] = soft.hover_omega_rad_s()
    for _ in range(250):
        soft.step(_hover_cmd(soft, 0.9))
    assert soft.end_reason == EndReason.RUNNING
    assert soft.pos_ned[2] == 0.0 and soft.vel_ned[2] == 0.0 and soft.on_ground

    hard = VehicleSim(X500)
    hard.reset(pos_ned=[0.0, 0.0, -5.0])  # falls ~9.9 m/s at touchdown
    for _ in range(500):
        hard.step(np.zeros(4))
    assert hard.end_reason == EndReason.GROUND_IMPACT
    frozen = hard.pos_ned.copy()
    hard.step(np.ones(4))
    assert np.array_equal(hard.pos_ned, frozen)


def test_sim_payload_release_changes_hover_equilibrium() -> None:
    vehicle = load_vehicle("delivery650")
    sim = VehicleSim(vehicle, payload_kg=1.0)
    assert sim.hover_omega_rad_s() > vehicle.hover_omega_rad_s()
    sim.reset(pos_ned=[0.0, 0.0, -10.0])
    sim.omega_rad_s[:] = sim.hover_omega_rad_s()
    cmd = _hover_cmd(sim)
    for _ in range(250):
        sim.step(cmd)
    assert abs(sim.pos_ned[2] + 10.0) < 1e-6
    sim.release_payload()
    assert sim.payload_kg == 0.0 and sim.payload_released_at_s == pytest.approx(1.0)
    assert sim.hover_omega_rad_s() == pytest.approx(vehicle.hover_omega_rad_s())
    for _ in range(250):
        sim.step(cmd)  # same thrust, lighter vehicle: climbs
    assert sim.pos_ned[2] < -11.0


@pytest.mark.parametrize("wind_ned", [(5.0, 0.0, 0.0), (0.0, -4.0, 0.0)])
def test_sim_wind_pushes_downwind(wind_ned: tuple[float, float, float]) -> None:
    world = World(empty_world().home, (), WindConfig(mean_ned_m_s=wind_ned), 0.0)
    sim = _airborne_at_hover(X500, world=world)
    cmd = _hover_cmd(sim)
    for _ in range(500):
        sim.step(cmd)
    w = np.array(wind_ned)
    along = sim.vel_ned @ w / np.linalg.norm(w)
    assert along > 0.5
    across = np.linalg.norm(sim.vel_ned - along * w / np.linalg.norm(w))
    assert across < 0.05 * along


def test_sim_batch_matches_single_over_10_s_random_inputs() -> None:
    world = World(empty_world().home, (), WindConfig(mean_ned_m_s=(1.0, -2.0, 0.0), gust_m_s=1.5, seed=3), 0.5)
    vehicle = load_vehicle("delivery650")
    seeds = np.array([11, 12, 13, 14])
    batch = BatchSim(vehicle, 4, world=world, seed=seeds)
    singles = [VehicleSim(vehicle, world=world, seed=int(s)) for s in seeds]
    start = np.array([[0, 0, -20.0], [5, 0, -20.0], [0, 5, -20.0], [5, 5, 0.0]])
    batch.reset(pos_ned=start)
    for k, s in enumerate(singles):
        s.reset(pos_ned=start[k])
    rng = np.random.default_rng(0)
    hover = vehicle.hover_omega_rad_s(0.5) / vehicle.omega_max_rad_s
    for step in range(250 * 10):
        cmd = np.clip(hover + 0.02 * rng.standard_normal((4, 4)), 0.0, 1.0)
        if step == 1200:
            batch.release_payload(np.array([True, False, True, False]))
            singles[0].release_payload()
            singles[2].release_payload()
        batch.step(cmd)
        for k, s in enumerate(singles):
            s.step(cmd[k])
    single_state = np.array([s.batch.state[0] for s in singles])
    assert np.max(np.abs(batch.state - single_state)) <= 1e-9
    assert np.ptp(batch.pos_ned[:, 0]) > 1.0  # the vehicles really flew different paths
    assert np.all(np.isfinite(batch.state))


def test_sim_gusts_are_seeded_and_deterministic() -> None:
    world = World(empty_world().home, (), WindConfig(gust_m_s=2.0, seed=5), 0.0)

    def run(seed: int) -> np.ndarray:
        sim = _airborne_at_hover(X500, world=world, seed=seed)
        out = []
        for _ in range(250 * 4):
            sim.step(_hover_cmd(sim))
            out.append(sim.wind_ned_m_s.copy())
        return np.array(out)

    a, b, c = run(1), run(1), run(2)
    assert np.array_equal(a, b)
    assert not np.allclose(a, c)
    assert 0.3 < np.std(a[:, 0]) < 4.0


def test_sim_collision_with_obstacle_ends_and_freezes() -> None:
    world = World(empty_world().home, (Sphere(10.0, 0.0, 10.0, 2.0),), WindConfig(), 0.0)
    sim = _airborne_at_hover(NO_DRAG, world=world)
    sim.vel_ned[0] = 5.0
    cmd = _hover_cmd(sim)
    for _ in range(500):
        sim.step(cmd)
    assert sim.end_reason == EndReason.COLLISION
    # stopped with the hull touching: centre within collision radius of the surface
    assert -0.1 < sim.min_clearance_m < NO_DRAG.collision_radius_m
    frozen = sim.pos_ned.copy()
    sim.step(cmd)
    assert np.array_equal(sim.pos_ned, frozen)


def test_sim_nonfinite_command_is_safe_and_nonfinite_state_ends() -> None:
    sim = _airborne_at_hover(X500)
    sim.step(np.array([np.nan, 0.5, 0.5, 0.5]))
    assert sim.end_reason == EndReason.RUNNING and np.all(np.isfinite(sim.batch.state))
    sim.rate_frd[0] = np.inf
    sim.step(_hover_cmd(sim))
    assert sim.end_reason == EndReason.NONFINITE_STATE


def test_sim_attitude_stays_level_in_hover_with_yaw() -> None:
    sim = VehicleSim(X500)
    sim.reset(pos_ned=[0.0, 0.0, -5.0], yaw_rad=1.0)
    sim.omega_rad_s[:] = sim.hover_omega_rad_s()
    for _ in range(250):
        sim.step(_hover_cmd(sim))
    assert np.allclose(euler_from_quat(sim.q_ned_frd), [0.0, 0.0, 1.0], atol=1e-12)


def test_sim_ground_friction_holds_against_wind_and_slides_to_rest() -> None:
    world = World(empty_world().home, (), WindConfig(mean_ned_m_s=(6.0, 0.0, 0.0)), 0.0)
    sim = VehicleSim(X500, world=world)
    sim.reset()
    for _ in range(250 * 5):
        sim.step(np.zeros(4))
    assert np.all(sim.pos_ned == 0.0) and sim.on_ground  # 6 m/s of wind cannot beat μ m g
    sim = VehicleSim(NO_DRAG)
    sim.reset()
    sim.vel_ned[0] = 2.0  # sliding touchdown: Coulomb friction stops it in v / (μ g) ≈ 0.25 s
    for _ in range(250):
        sim.step(np.zeros(4))
    assert sim.vel_ned[0] == 0.0
    assert sim.pos_ned[0] == pytest.approx(2.0**2 / (2 * 0.8 * GRAVITY_M_S2), rel=0.05)


def test_sim_stepper_validation_and_stop() -> None:
    with pytest.raises(ValueError, match="multiple of control_hz"):
        BatchSim(X500, 1, physics_hz=1000, control_hz=300)
    with pytest.raises(ValueError, match="payload_max_kg"):
        BatchSim(X500, 2, payload_kg=np.array([0.0, 5.0]))
    sim = BatchSim(X500, 2)
    sim.reset(pos_ned=[0.0, 0.0, -10.0])
    sim.end(EndReason.STOPPED, np.array([True, False]))
    sim.step(np.zeros((2, 4)))
    assert sim.pos_ned[0, 2] == -10.0 and sim.pos_ned[1, 2] > -10.0
    assert sim.end_reason.tolist() == [EndReason.STOPPED, EndReason.RUNNING]
    assert sim.t_us == 4000 and sim.substeps == 4
