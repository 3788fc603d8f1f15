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

from mavlink_bridge.contract.frames import DEG_E7, GeoPoint, LocalNedFrame
from mavlink_bridge.contract.wire import GpsSample, SensorSample
from sim.vehicle import VehicleSim
from sim.vehicle_config import VehicleConfig

#: Earth magnetic field used by the magnetometer (gauss, NED): 0.47 G total, 63° inclination, 0° declination.
MAG_FIELD_NED_GAUSS = (0.21, 0.0, 0.42)
GPS_PERIOD_US = 100_000
_SEA_LEVEL_PA = 101325.0
#: Standard normals drawn from the generator at once (the per-sample stream is unchanged).
NOISE_BLOCK = 4000


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


def _quantize_deg_e7(angle_deg: float) -> float:
    """``angle_deg`` on the 1e-7° grid of the MAVLink degE7 encoding (non-finite values pass through)."""
    return round(angle_deg * DEG_E7) / DEG_E7 if math.isfinite(angle_deg) else angle_deg


class SensorModel:
    """Measurements of one vehicle for the autopilot, deterministic for a seed.

    Per-step work is scalar ``math`` on one ``tolist()`` of the state; the white noise is drawn
    from the seeded generator in blocks of ``NOISE_BLOCK`` standard normals and consumed in
    order (10 per IMU sample, 6 per GPS fix), which is the same stream as drawing per sample.
    """

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
        gps_sigma_ned_m = s * np.array([nm.gps_pos_horizontal_m, nm.gps_pos_horizontal_m, nm.gps_pos_vertical_m])
        self._gps_decay = math.exp(-GPS_PERIOD_US * 1e-6 / nm.gps_error_time_constant_s)
        #: Gauss–Markov GPS position error (m, NED); an array shared with the fused frame kernel
        self._gps_error_ned_m: np.ndarray = gps_sigma_ned_m * self._rng.standard_normal(3)
        self._gps_innovation_ned_m: list[float] = (gps_sigma_ned_m * math.sqrt(1.0 - self._gps_decay**2)).tolist()
        self._gps_vel_sigma_m_s = s * nm.gps_vel_noise_m_s
        self._gps_eph_m = max(2.0 * nm.gps_pos_horizontal_m * s, 0.01)
        self._gps_epv_m = max(2.0 * nm.gps_pos_vertical_m * s, 0.01)
        # per-step constants as Python floats (scalar math is several times faster than numpy on 3-vectors)
        self._accel_bias: list[float] = self.accel_bias_frd_m_s2.tolist()
        self._gyro_bias: list[float] = self.gyro_bias_frd_rad_s.tolist()
        self._mag_bias: list[float] = self.mag_bias_frd_gauss.tolist()
        #: scaled standard normals (those before ``_counters[0]`` are used); refilled by blocks
        self._noise = np.zeros(0)
        #: [next noise index, sim time of the next GPS fix (µs)]: an array so that the compiled
        #: sensor kernel (``sim.frame_kernel``) advances the same state as these methods
        self._counters = np.zeros(2, dtype=np.int64)

    def _reserve_noise(self, count: int) -> None:
        """Make the next ``count`` noise values available (refill keeps the unused ones: same stream)."""
        pos = int(self._counters[0])
        if pos + count > self._noise.shape[0]:
            block = self._rng.standard_normal(NOISE_BLOCK)
            block *= self._scale
            self._noise = np.concatenate((self._noise[pos:], block))
            self._counters[0] = 0

    def _take_noise(self, count: int) -> list[float]:
        """The next ``count`` scaled standard normals."""
        self._reserve_noise(count)
        pos = int(self._counters[0])
        self._counters[0] = pos + count
        return self._noise[pos : pos + count].tolist()

    def imu_baro_mag(self, sim: VehicleSim) -> SensorSample:
        """IMU, magnetometer and barometer at the current sim time (call once per control step)."""
        nm = self.noise_model
        n = self._take_noise(10)
        batch = sim.batch
        x = batch.state[0].tolist()
        sf = batch.specific_force_frd[0].tolist()
        w, a, b, c = x[6], x[7], x[8], x[9]
        # Rᵀ m_ned (frames.dcm_from_quat transposed), written out: this runs at 250 Hz
        mn, me, md = MAG_FIELD_NED_GAUSS
        mag_x = (1 - 2 * (b * b + c * c)) * mn + 2 * (a * b + w * c) * me + 2 * (a * c - w * b) * md
        mag_y = 2 * (a * b - w * c) * mn + (1 - 2 * (a * a + c * c)) * me + 2 * (b * c + w * a) * md
        mag_z = 2 * (a * c + w * b) * mn + 2 * (b * c - w * a) * me + (1 - 2 * (a * a + b * b)) * md
        ab, gb, mb = self._accel_bias, self._gyro_bias, self._mag_bias
        an, gn, mgn = nm.accel_noise_m_s2, nm.gyro_noise_rad_s, nm.mag_noise_gauss
        alt_amsl = self.home.alt_amsl_m - x[2] + self.baro_bias_m + nm.baro_noise_m * n[9]
        return SensorSample(
            batch.t_us,
            (sf[0] + ab[0] + an * n[0], sf[1] + ab[1] + an * n[1], sf[2] + ab[2] + an * n[2]),
            (x[10] + gb[0] + gn * n[3], x[11] + gb[1] + gn * n[4], x[12] + gb[2] + gn * n[5]),
            (mag_x + mb[0] + mgn * n[6], mag_y + mb[1] + mgn * n[7], mag_z + mb[2] + mgn * n[8]),
            isa_pressure_pa(alt_amsl) / 100.0,
            alt_amsl,
            15.0 - 0.0065 * alt_amsl,
        )

    def gps(self, sim: VehicleSim) -> GpsSample | None:
        """A GPS fix when one is due (every 100 ms of sim time, the first at t = 0), else None."""
        t_us = sim.batch.t_us
        next_gps_us = int(self._counters[1])
        if t_us < next_gps_us:
            return None
        self._counters[1] = next_gps_us + GPS_PERIOD_US * (1 + (t_us - next_gps_us) // GPS_PERIOD_US)
        n = self._take_noise(6)
        e, g, decay = self._gps_error_ned_m.tolist(), self._gps_innovation_ned_m, self._gps_decay
        err = (e[0] * decay + g[0] * n[0], e[1] * decay + g[1] * n[1], e[2] * decay + g[2] * n[2])
        self._gps_error_ned_m[:] = err
        x = sim.batch.state[0].tolist()
        geo = self._frame.geodetic_from_ned(x[0] + err[0], x[1] + err[1], x[2] + err[2])
        vs = self._gps_vel_sigma_m_s
        return GpsSample(
            t_us,
            _quantize_deg_e7(geo.lat_deg),
            _quantize_deg_e7(geo.lon_deg),
            round(geo.alt_amsl_m, 3),
            (x[3] + vs * n[3], x[4] + vs * n[4], x[5] + vs * n[5]),
            self._gps_eph_m,
            self._gps_epv_m,
            3,
            12,
        )
