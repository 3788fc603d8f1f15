"""Sensors with seeded noise and bias: IMU, barometer, magnetometer (every control step) and GPS (10 Hz).

Ground truth stays in the simulator state (:meth:`sim.vehicle.VehicleSim.ground_truth`); this module only
derives *measurements* from it (SPEC §5). Models, per sample:

* accelerometer: ``f_frd + b_a + n_a`` (specific force, m/s²); gyro: ``ω_frd + b_g + n_g``;
  ``b`` is a constant turn-on bias drawn from the seed, ``n`` white noise.
* magnetometer: ``Rᵀ m_ned + b_m + n_m`` (gauss); a constant Earth field ``m_ned`` with zero declination
  (magnetic north = true north), so a heading estimator needs no magnetic model.
* barometer: ISA pressure at ``alt_amsl = home.alt − z`` with a constant altitude bias and white noise;
  ``pressure_alt_m`` is the altitude that pressure implies; temperature is ISA.
* GPS (10 Hz): position error is a first-order Gauss–Markov process (slow wander, σ ``gps_pos_*``,
  time constant ``gps_error_time_constant_s``) plus white velocity noise; latitude/longitude are
  quantised to 1e-7° so that the MAVLink degE7 encoding is lossless.

With ``noise=False`` every bias and noise is zero (measurements equal the truth, GPS still at 10 Hz).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from mavlink_bridge.frames import DEG_E7, GeoPoint, LocalNedFrame
from mavlink_bridge.wire import GpsSample, SensorSample
from sim.vehicle import VehicleSim
from sim.vehicle_config import VehicleConfig

#: Earth magnetic field used by the magnetometer (gauss, NED): 0.47 G total, 63° inclination, 0° declination.
MAG_FIELD_NED_GAUSS = (0.21, 0.0, 0.42)
GPS_PERIOD_US = 100_000
_SEA_LEVEL_PA = 101325.0


@dataclass(frozen=True)
class SensorNoise:
    """Standard deviations of white noise (per sample) and of the turn-on biases."""

    accel_noise_m_s2: float = 0.05
    accel_bias_m_s2: float = 0.03
    gyro_noise_rad_s: float = 0.004
    gyro_bias_rad_s: float = 0.002
    mag_noise_gauss: float = 0.004
    mag_bias_gauss: float = 0.005
    baro_noise_m: float = 0.08
    baro_bias_m: float = 0.5
    gps_pos_horizontal_m: float = 0.4
    gps_pos_vertical_m: float = 0.7
    gps_vel_noise_m_s: float = 0.05
    gps_error_time_constant_s: float = 5.0


def isa_pressure_pa(alt_amsl_m: float) -> float:
    """International Standard Atmosphere pressure (Pa) in the troposphere."""
    return _SEA_LEVEL_PA * (1.0 - 2.25577e-5 * alt_amsl_m) ** 5.25588


def isa_altitude_m(pressure_pa: float) -> float:
    """Inverse of :func:`isa_pressure_pa`."""
    return (1.0 - (pressure_pa / _SEA_LEVEL_PA) ** (1.0 / 5.25588)) / 2.25577e-5


class SensorModel:
    """Measurements of one vehicle for the autopilot, deterministic for a seed."""

    def __init__(
        self,
        vehicle: VehicleConfig,
        home: GeoPoint,
        seed: int,
        noise: bool = True,
        noise_model: SensorNoise | None = None,
    ) -> None:
        self.vehicle = vehicle
        self.home = home
        self.noise = noise
        self.noise_model = noise_model or SensorNoise()
        self._frame = LocalNedFrame(home)
        self._rng = np.random.default_rng(seed)
        self._scale = 1.0 if noise else 0.0
        nm = self.noise_model
        s = self._scale
        self.accel_bias_frd_m_s2 = s * nm.accel_bias_m_s2 * self._rng.standard_normal(3)
        self.gyro_bias_frd_rad_s = s * nm.gyro_bias_rad_s * self._rng.standard_normal(3)
        self.mag_bias_frd_gauss = s * nm.mag_bias_gauss * self._rng.standard_normal(3)
        self.baro_bias_m = s * nm.baro_bias_m * float(self._rng.standard_normal())
        self._imu_draw = np.zeros(10)
        self._gps_draw = np.zeros(6)
        self._gps_error_ned_m = np.zeros(3)
        self._gps_sigma_ned_m = s * np.array([nm.gps_pos_horizontal_m, nm.gps_pos_horizontal_m, nm.gps_pos_vertical_m])
        self._gps_decay = math.exp(-GPS_PERIOD_US * 1e-6 / nm.gps_error_time_constant_s)
        self._gps_error_ned_m[:] = self._gps_sigma_ned_m * self._rng.standard_normal(3)
        self._next_gps_us = 0
        self._mag_ned = np.array(MAG_FIELD_NED_GAUSS)

    def imu_baro_mag(self, sim: VehicleSim) -> SensorSample:
        """IMU, magnetometer and barometer at the current sim time (call once per control step)."""
        nm = self.noise_model
        n = self._imu_draw
        self._rng.standard_normal(out=n)
        n *= self._scale
        x = sim.batch.state[0]
        w, a, b, c = x[6], x[7], x[8], x[9]
        # Rᵀ m_ned (frames.dcm_from_quat transposed), written out: this runs at 250 Hz
        mn, me, md = self._mag_ned
        mag_x = (1 - 2 * (b * b + c * c)) * mn + 2 * (a * b + w * c) * me + 2 * (a * c - w * b) * md
        mag_y = 2 * (a * b - w * c) * mn + (1 - 2 * (a * a + c * c)) * me + 2 * (b * c + w * a) * md
        mag_z = 2 * (a * c + w * b) * mn + 2 * (b * c - w * a) * me + (1 - 2 * (a * a + b * b)) * md
        sf = sim.batch.specific_force_frd[0]
        ab, gb, mb = self.accel_bias_frd_m_s2, self.gyro_bias_frd_rad_s, self.mag_bias_frd_gauss
        alt_amsl = self.home.alt_amsl_m - float(x[2]) + self.baro_bias_m + nm.baro_noise_m * n[9]
        pressure_pa = isa_pressure_pa(alt_amsl)
        return SensorSample(
            time_us=sim.t_us,
            accel_frd_m_s2=tuple(float(sf[k] + ab[k] + nm.accel_noise_m_s2 * n[k]) for k in range(3)),  # type: ignore[arg-type]
            gyro_frd_rad_s=tuple(float(x[10 + k] + gb[k] + nm.gyro_noise_rad_s * n[3 + k]) for k in range(3)),  # type: ignore[arg-type]
            mag_frd_gauss=(
                float(mag_x + mb[0] + nm.mag_noise_gauss * n[6]),
                float(mag_y + mb[1] + nm.mag_noise_gauss * n[7]),
                float(mag_z + mb[2] + nm.mag_noise_gauss * n[8]),
            ),
            abs_pressure_hpa=pressure_pa / 100.0,
            pressure_alt_m=alt_amsl,
            temperature_degc=15.0 - 0.0065 * alt_amsl,
        )

    def gps(self, sim: VehicleSim) -> GpsSample | None:
        """A GPS fix when one is due (every 100 ms of sim time, the first at t = 0), else None."""
        t_us = sim.t_us
        if t_us < self._next_gps_us:
            return None
        self._next_gps_us += GPS_PERIOD_US * (1 + (t_us - self._next_gps_us) // GPS_PERIOD_US)
        nm = self.noise_model
        d = self._gps_draw
        self._rng.standard_normal(out=d)
        err = self._gps_error_ned_m
        err *= self._gps_decay
        err += self._gps_sigma_ned_m * math.sqrt(1.0 - self._gps_decay**2) * d[:3]
        x = sim.batch.state[0]
        geo = self._frame.geodetic_from_ned(float(x[0] + err[0]), float(x[1] + err[1]), float(x[2] + err[2]))
        vel_sigma = self._scale * nm.gps_vel_noise_m_s
        return GpsSample(
            time_us=t_us,
            lat_deg=round(geo.lat_deg * DEG_E7) / DEG_E7,
            lon_deg=round(geo.lon_deg * DEG_E7) / DEG_E7,
            alt_amsl_m=round(geo.alt_amsl_m, 3),
            vel_ned_m_s=(
                float(x[3] + vel_sigma * d[3]),
                float(x[4] + vel_sigma * d[4]),
                float(x[5] + vel_sigma * d[5]),
            ),
            eph_m=max(2.0 * nm.gps_pos_horizontal_m * self._scale, 0.01),
            epv_m=max(2.0 * nm.gps_pos_vertical_m * self._scale, 0.01),
            fix_type=3,
            satellites_visible=12,
        )
