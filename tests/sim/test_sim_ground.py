"""Ground contact (issue 22 item 8): the ground holds what rests on it, lets go of what it cannot hold, and the
accelerometer feels the touchdown."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from mavlink_bridge.contract.frames import GRAVITY_M_S2, quat_from_euler
from sim.vehicle import VehicleSim
from sim.vehicle_config import load_vehicle, vehicle_names
from sim.world import WindConfig, World, empty_world

MOT_SPIN_IDLE = 0.1  # the autopilot's default motor command while armed on the ground (nav_params)
CONTROL_HZ = 250


def _windy(mean_m_s: float, gust_m_s: float) -> World:
    return World(empty_world().home, (), WindConfig(mean_ned_m_s=(mean_m_s, 0.0, 0.0), gust_m_s=gust_m_s, seed=7), 0.0)


@pytest.mark.parametrize("name", vehicle_names())
def test_a_vehicle_at_idle_in_6_m_s_wind_stays_put_for_30_s(name: str) -> None:
    sim = VehicleSim(load_vehicle(name), world=_windy(6.0, 1.5))
    sim.reset(yaw_rad=0.7)
    for _ in range(CONTROL_HZ * 30):
        sim.step(np.full(4, MOT_SPIN_IDLE))
        assert sim.on_ground
    assert math.hypot(sim.pos_ned[0], sim.pos_ned[1]) < 0.003
    assert sim.pos_ned[2] == 0.0


def _tilted_on_the_ground(thrust_over_weight: float, tilt_rad: float) -> VehicleSim:
    """x500 without drag, resting tilted (pitch) with rotor speeds giving ``thrust_over_weight`` of its weight."""
    x500 = load_vehicle("x500")
    vehicle = dataclasses.replace(x500, drag_body_n_per_m2_s2=(0.0, 0.0, 0.0), rotor_drag_n_s_per_m=0.0)
    sim = VehicleSim(vehicle)
    sim.reset()
    sim.q_ned_frd[:] = quat_from_euler(0.0, tilt_rad, 0.0)
    omega = math.sqrt(thrust_over_weight * vehicle.mass_kg * GRAVITY_M_S2 / (4 * vehicle.k_f_n_per_rad2_s2))
    sim.omega_rad_s[:] = omega
    return sim


def test_friction_holds_below_the_static_limit_and_slides_above_it() -> None:
    tilt, mu = math.radians(30.0), load_vehicle("x500").ground_friction_coeff
    limit = mu / (math.sin(tilt) + mu * math.cos(tilt))  # thrust/weight where T sinθ = μ (m g − T cosθ)
    held = _tilted_on_the_ground(0.95 * limit, tilt)
    cmd = held.omega_rad_s / held.vehicle.omega_max_rad_s
    for _ in range(CONTROL_HZ * 5):
        held.step(cmd)
    assert np.all(held.pos_ned == 0.0) and held.on_ground

    ratio = 1.2 * limit
    slid = _tilted_on_the_ground(ratio, tilt)
    cmd = slid.omega_rad_s / slid.vehicle.omega_max_rad_s
    t_s = 2.0
    for _ in range(round(CONTROL_HZ * t_s)):
        slid.step(cmd)
    # pitched nose up (positive pitch) the thrust tilts backwards: it slides south at a = g (T sinθ − μ (1 − T cosθ))
    accel = GRAVITY_M_S2 * (ratio * math.sin(tilt) - mu * (1.0 - ratio * math.cos(tilt)))
    assert slid.on_ground
    assert -slid.pos_ned[0] == pytest.approx(0.5 * accel * t_s**2, rel=0.02)
    assert -slid.vel_ned[0] == pytest.approx(accel * t_s, rel=0.02)


def test_a_slide_stops_and_stays_stopped() -> None:
    sim = _tilted_on_the_ground(0.0, 0.0)
    sim.vel_ned[:] = (1.0, -1.0, 0.0)
    for _ in range(CONTROL_HZ):
        sim.step(np.zeros(4))
    assert np.all(sim.vel_ned == 0.0)
    stopped = sim.pos_ned.copy()
    distance = math.hypot(stopped[0], stopped[1])
    assert distance == pytest.approx(2.0 / (2 * 0.8 * GRAVITY_M_S2), rel=0.03)  # v² / (2 μ g)
    for _ in range(CONTROL_HZ):
        sim.step(np.zeros(4))
    assert np.array_equal(sim.pos_ned, stopped)


def test_takeoff_in_wind_leaves_the_ground_cleanly() -> None:
    sim = VehicleSim(load_vehicle("x500"), world=_windy(6.0, 0.0))
    sim.reset()
    cmd = np.full(4, 1.3 * sim.hover_omega_rad_s() / sim.vehicle.omega_max_rad_s)
    for _ in range(CONTROL_HZ):
        sim.step(cmd)
    assert not sim.on_ground and sim.pos_ned[2] < -0.5


def test_the_accelerometer_feels_the_touchdown() -> None:
    """The IMU reports the mean specific force over each control step, so the stop at touchdown (an impulse within
    one physics step) is in it: integrated over the landing it gives the vertical speed lost."""
    sim = VehicleSim(load_vehicle("x500"))
    sim.reset(pos_ned=[0.0, 0.0, -0.3])
    sim.omega_rad_s[:] = sim.hover_omega_rad_s()
    sim.vel_ned[2] = 0.7
    cmd = np.full(4, 0.9 * sim.hover_omega_rad_s() / sim.vehicle.omega_max_rad_s)
    delta_v_down = 0.0
    landed_at = None
    for k in range(CONTROL_HZ):
        before = sim.vel_ned[2]
        sim.step(cmd)
        # accelerometer (FRD, level vehicle) + gravity = the vertical acceleration, down positive
        delta_v_down += (sim.specific_force_frd[2] + GRAVITY_M_S2) / CONTROL_HZ
        if landed_at is None and sim.pos_ned[2] == 0.0:
            landed_at = k
            assert sim.vel_ned[2] - before < -0.5  # the step that touched down stopped it
    assert landed_at is not None and sim.vel_ned[2] == 0.0
    assert delta_v_down == pytest.approx(-0.7, abs=0.01)  # what an IMU integrating the impulse reads
