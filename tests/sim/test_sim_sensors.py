"""Sensors (issue 2): GPS 10 Hz in degE7, IMU specific force at rest, magnetometer heading, baro, seeding."""

from __future__ import annotations

import numpy as np
import pytest

from mavlink_bridge.contract.frames import GRAVITY_M_S2, GeoPoint, LocalNedFrame, deg_e7_from_deg, deg_from_deg_e7
from sim.sensors import MAG_FIELD_NED_GAUSS, NOISE_BLOCK, SensorModel, isa_altitude_m, isa_pressure_pa
from sim.vehicle import VehicleSim
from sim.vehicle_config import load_vehicle

HOME = GeoPoint(30.2635, 120.1233, 12.0)
X500 = load_vehicle("x500")


def _flying_sim() -> VehicleSim:
    sim = VehicleSim(X500)
    sim.reset(pos_ned=[30.0, -20.0, -15.0], yaw_rad=0.7)
    sim.omega_rad_s[:] = sim.hover_omega_rad_s()
    sim.vel_ned[:] = [3.0, 1.0, -0.5]
    return sim


def test_sim_gps_is_10_hz_and_degE7_round_trips() -> None:
    sim = _flying_sim()
    sensors = SensorModel(X500, HOME, seed=1, noise=False)
    frame = LocalNedFrame(HOME)
    cmd = np.full(4, sim.hover_omega_rad_s() / X500.omega_max_rad_s)
    fixes = []
    for _ in range(250 * 2):
        fix = sensors.gps(sim)
        if fix is not None:
            fixes.append(fix)
            lat_e7, lon_e7 = deg_e7_from_deg(fix.lat_deg), deg_e7_from_deg(fix.lon_deg)
            assert deg_from_deg_e7(lat_e7) == fix.lat_deg and deg_from_deg_e7(lon_e7) == fix.lon_deg
            ned = frame.ned_from_geodetic(fix.lat_deg, fix.lon_deg, fix.alt_amsl_m)
            assert np.linalg.norm(np.array(ned) - sim.pos_ned) < 0.02  # degE7 ~ 1.1 cm
            assert np.allclose(fix.vel_ned_m_s, sim.vel_ned)
        sim.step(cmd)
    assert len(fixes) == 20
    assert np.all(np.diff([f.time_us for f in fixes]) == 100_000)
    assert fixes[0].time_us == 0 and fixes[0].fix_type == 3


def test_sim_imu_at_rest_reads_minus_g_in_body_z() -> None:
    sim = VehicleSim(X500)
    sim.reset()
    truth = SensorModel(X500, HOME, seed=3, noise=False)
    noisy = SensorModel(X500, HOME, seed=3)
    samples = []
    for _ in range(500):
        sim.step(np.zeros(4))
        s = truth.imu_baro_mag(sim)
        assert s.accel_frd_m_s2 == pytest.approx((0.0, 0.0, -GRAVITY_M_S2), abs=1e-12)
        assert s.gyro_frd_rad_s == (0.0, 0.0, 0.0)
        samples.append(noisy.imu_baro_mag(sim).accel_frd_m_s2)
    mean = np.mean(samples, axis=0)
    assert np.allclose(mean, [0.0, 0.0, -GRAVITY_M_S2], atol=0.15)  # bias + averaged noise
    assert 0.02 < np.std(np.array(samples)[:, 2]) < 0.1  # the noise is there
    assert np.allclose(mean, noisy.accel_bias_frd_m_s2 + np.array([0.0, 0.0, -GRAVITY_M_S2]), atol=0.02)


def test_sim_mag_and_baro_follow_attitude_and_altitude() -> None:
    sim = _flying_sim()
    s = SensorModel(X500, HOME, seed=0, noise=False).imu_baro_mag(sim)
    yaw = np.arctan2(-s.mag_frd_gauss[1], s.mag_frd_gauss[0])  # level: heading from the horizontal field
    assert yaw == pytest.approx(0.7, abs=1e-9)
    assert s.mag_frd_gauss[2] == pytest.approx(MAG_FIELD_NED_GAUSS[2], abs=1e-12)
    assert s.pressure_alt_m == pytest.approx(HOME.alt_amsl_m + 15.0, abs=1e-9)
    assert isa_altitude_m(s.abs_pressure_hpa * 100.0) == pytest.approx(27.0, abs=1e-6)
    assert isa_pressure_pa(0.0) == 101325.0
    assert s.abs_pressure_hpa < isa_pressure_pa(HOME.alt_amsl_m) / 100.0  # higher -> lower pressure


def test_sim_sensors_are_seeded_and_deterministic() -> None:
    def record(seed: int) -> list:
        sim = _flying_sim()
        sensors = SensorModel(X500, HOME, seed=seed)
        cmd = np.full(4, sim.hover_omega_rad_s() / X500.omega_max_rad_s)
        out = []
        for _ in range(100):
            out.append(sensors.imu_baro_mag(sim))
            out.append(sensors.gps(sim))
            sim.step(cmd)
        return out

    a, b, c = record(5), record(5), record(6)
    assert a == b
    assert a != c
    assert sum(x is not None for x in a) == 100 + 4  # 100 IMU samples, GPS at t = 0, 0.1, 0.2, 0.3 s


def test_sim_ground_truth_is_noise_free_and_geodetic() -> None:
    sim = _flying_sim()
    gt = sim.ground_truth(HOME)
    ned = LocalNedFrame(HOME).ned_from_geodetic(gt.lat_deg, gt.lon_deg, gt.alt_amsl_m)
    assert np.allclose(ned, sim.pos_ned, atol=1e-6)
    assert gt.q_ned_frd == tuple(sim.q_ned_frd) and gt.vel_ned_m_s == tuple(sim.vel_ned)
    assert gt.time_us == 0


def test_sim_block_noise_is_the_per_sample_stream_across_block_refills() -> None:
    """Noise drawn in blocks equals drawing 10 normals per IMU sample and 6 per GPS fix, in call order."""
    sim = _flying_sim()
    sensors = SensorModel(X500, HOME, seed=9)
    nm = sensors.noise_model
    ref = np.random.default_rng(9)
    ref.standard_normal(3 * 3 + 1 + 3)  # turn-on biases and the initial GPS error
    cmd = np.full(4, sim.hover_omega_rad_s() / X500.omega_max_rad_s)
    assert NOISE_BLOCK % (25 * 10 + 6) != 0  # a GPS cycle uses 256 normals: refills must split a sample
    n_samples = 2 * NOISE_BLOCK // 10 + 7  # crosses block boundaries, GPS draws interleaved
    for _ in range(n_samples):
        s = sensors.imu_baro_mag(sim)
        n = ref.standard_normal(10)
        sf, rate = sim.specific_force_frd, sim.rate_frd
        for k in range(3):
            assert s.accel_frd_m_s2[k] == sf[k] + sensors.accel_bias_frd_m_s2[k] + nm.accel_noise_m_s2 * n[k]
            assert s.gyro_frd_rad_s[k] == rate[k] + sensors.gyro_bias_frd_rad_s[k] + nm.gyro_noise_rad_s * n[3 + k]
        alt = HOME.alt_amsl_m - sim.pos_ned[2] + sensors.baro_bias_m + nm.baro_noise_m * n[9]
        assert s.pressure_alt_m == alt
        fix = sensors.gps(sim)
        if fix is not None:
            d = ref.standard_normal(6)
            assert fix.vel_ned_m_s == tuple(sim.vel_ned + nm.gps_vel_noise_m_s * d[3:])
        sim.step(cmd)
