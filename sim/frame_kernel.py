"""The simulator's per-step measurements and truth in one numba call: the implementation of the sim's sensors.

``SensorValues.fill()`` writes, for the current state of row 0, the IMU/baro/mag sample, the GPS fix (when
due) and the ground truth into one float64 array laid out by ``mavlink_bridge.contract.sensor_values`` (the
bridge's compiled frame writer packs that array into the lockstep datagram), and advances the
``SensorModel``'s state (noise position, GPS error process, next GPS time) as its Python methods do.
``tests/sim/test_sim_frame_writer.py`` checks the values against the sensor model's Python methods, and the
geodetic conversion against pymap3d.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from mavlink_bridge.contract.frames import DEG_E7, LocalNedFrame
from mavlink_bridge.contract.geodetic import geodetic_from_ned
from mavlink_bridge.contract.sensor_values import (
    N_VALUES,
    V_ACCEL_FRD,
    V_ACCEL_TRUTH_FRD,
    V_ALT_AMSL,
    V_GPS_ALT_AMSL,
    V_GPS_EPH,
    V_GPS_EPV,
    V_GPS_FIX_TYPE,
    V_GPS_LAT_DEG,
    V_GPS_LON_DEG,
    V_GPS_SATELLITES,
    V_GPS_VEL_NED,
    V_GYRO_FRD,
    V_LAT_DEG,
    V_LON_DEG,
    V_MAG_FRD,
    V_PRESSURE_ALT,
    V_PRESSURE_HPA,
    V_Q_NED_FRD,
    V_TEMPERATURE,
    V_VEL_NED,
)
from sim.sensors import _SEA_LEVEL_PA, GPS_PERIOD_US, MAG_FIELD_NED_GAUSS, SensorModel
from sim.vehicle import VehicleSim

_njit = njit(cache=True)

# --- constants array layout ---------------------------------------------------------------------
C_HOME_ALT = 0  # sensor model home altitude, m AMSL
C_BARO_BIAS = 1
C_BARO_NOISE = 2
C_ACCEL_NOISE = 3
C_GYRO_NOISE = 4
C_MAG_NOISE = 5
C_MAG_FIELD_NED = 6  # 3
C_ACCEL_BIAS = 9  # 3
C_GYRO_BIAS = 12  # 3
C_MAG_BIAS = 15  # 3
C_GPS_DECAY = 18
C_GPS_INNOVATION = 19  # 3
C_GPS_VEL_SIGMA = 22
C_GPS_EPH = 23
C_GPS_EPV = 24
C_GPS_FIX_TYPE = 25
C_GPS_SATELLITES = 26
C_TRUTH_FRAME = 27  # 12: home ECEF (3), rows north/east/down in ECEF (9)
C_GPS_FRAME = 39  # 12
N_CONSTANTS = 51
#: noise values one step may use: IMU/baro/mag (10) and a GPS fix (6)
NOISE_PER_STEP = 16

_DEG_E7 = DEG_E7
_GPS_PERIOD_US = GPS_PERIOD_US


def frame_constants(frame: LocalNedFrame) -> list[float]:
    """The 12 numbers of ``LocalNedFrame.geodetic_from_ned``: home ECEF, then the NED rows in ECEF."""
    return list(frame.ecef_constants)


@_njit
def fill_values(
    state: np.ndarray,
    specific_force_frd: np.ndarray,
    t_us: int,
    c: np.ndarray,
    noise: np.ndarray,
    counters: np.ndarray,
    gps_error_ned_m: np.ndarray,
    v: np.ndarray,
) -> bool:
    """``SensorModel.imu_baro_mag``, ``SensorModel.gps`` and ``VehicleSim.ground_truth`` of row 0 into ``v``.

    Advances ``counters`` ([noise index, next GPS µs]) and ``gps_error_ned_m`` as those methods do; the
    caller reserved ``NOISE_PER_STEP`` noise values. Returns True when a GPS fix was due (``v`` holds it).
    Raises where the reference would fail to encode (baro altitude beyond the ISA model, pow overflow).
    """
    i = counters[0]
    if i < 0 or i + NOISE_PER_STEP > noise.shape[0]:
        raise IndexError("fill_values: reserve NOISE_PER_STEP noise values first")
    x = state[0]
    sf = specific_force_frd[0]
    counters[0] = i + 10
    # IMU, magnetometer, barometer (SensorModel.imu_baro_mag)
    w, a, b, cq = x[6], x[7], x[8], x[9]
    mn, me, md = c[C_MAG_FIELD_NED], c[C_MAG_FIELD_NED + 1], c[C_MAG_FIELD_NED + 2]
    mag_x = (1 - 2 * (b * b + cq * cq)) * mn + 2 * (a * b + w * cq) * me + 2 * (a * cq - w * b) * md
    mag_y = 2 * (a * b - w * cq) * mn + (1 - 2 * (a * a + cq * cq)) * me + 2 * (b * cq + w * a) * md
    mag_z = 2 * (a * cq + w * b) * mn + 2 * (b * cq - w * a) * me + (1 - 2 * (a * a + b * b)) * md
    an, gn, mgn = c[C_ACCEL_NOISE], c[C_GYRO_NOISE], c[C_MAG_NOISE]
    for k in range(3):
        v[V_ACCEL_FRD + k] = sf[k] + c[C_ACCEL_BIAS + k] + an * noise[i + k]
        v[V_GYRO_FRD + k] = x[10 + k] + c[C_GYRO_BIAS + k] + gn * noise[i + 3 + k]
    v[V_MAG_FRD] = mag_x + c[C_MAG_BIAS] + mgn * noise[i + 6]
    v[V_MAG_FRD + 1] = mag_y + c[C_MAG_BIAS + 1] + mgn * noise[i + 7]
    v[V_MAG_FRD + 2] = mag_z + c[C_MAG_BIAS + 2] + mgn * noise[i + 8]
    alt_amsl = c[C_HOME_ALT] - x[2] + c[C_BARO_BIAS] + c[C_BARO_NOISE] * noise[i + 9]
    base = 1.0 - 2.25577e-5 * alt_amsl  # sensors.isa_pressure_pa
    if base < 0.0:
        raise ValueError("baro altitude above the ISA model (Python's pow would give a complex pressure)")
    power = base**5.25588
    if math.isinf(power) and not math.isinf(base):
        raise OverflowError("baro pressure overflow")
    v[V_PRESSURE_HPA] = _SEA_LEVEL_PA * power / 100.0
    v[V_PRESSURE_ALT] = alt_amsl
    v[V_TEMPERATURE] = 15.0 - 0.0065 * alt_amsl
    # ground truth (VehicleSim.ground_truth)
    for k in range(7):  # q, rates
        v[V_Q_NED_FRD + k] = x[6 + k]
    lat, lon, alt = geodetic_from_ned(c, C_TRUTH_FRAME, x[0], x[1], x[2])
    v[V_LAT_DEG] = lat
    v[V_LON_DEG] = lon
    v[V_ALT_AMSL] = alt
    for k in range(3):
        v[V_VEL_NED + k] = x[3 + k]
        v[V_ACCEL_TRUTH_FRD + k] = sf[k]
    # GPS (SensorModel.gps)
    next_gps_us = counters[1]
    if t_us < next_gps_us:
        return False
    counters[1] = next_gps_us + _GPS_PERIOD_US * (1 + (t_us - next_gps_us) // _GPS_PERIOD_US)
    j = counters[0]
    counters[0] = j + 6
    decay = c[C_GPS_DECAY]
    for k in range(3):
        gps_error_ned_m[k] = gps_error_ned_m[k] * decay + c[C_GPS_INNOVATION + k] * noise[j + k]
    lat, lon, alt = geodetic_from_ned(
        c, C_GPS_FRAME, x[0] + gps_error_ned_m[0], x[1] + gps_error_ned_m[1], x[2] + gps_error_ned_m[2]
    )
    v[V_GPS_LAT_DEG] = np.rint(lat * _DEG_E7) / _DEG_E7 if math.isfinite(lat) else lat
    v[V_GPS_LON_DEG] = np.rint(lon * _DEG_E7) / _DEG_E7 if math.isfinite(lon) else lon
    v[V_GPS_ALT_AMSL] = np.rint(alt * 1000.0) / 1000.0 if math.isfinite(alt) else alt
    vs = c[C_GPS_VEL_SIGMA]
    for k in range(3):
        v[V_GPS_VEL_NED + k] = x[3 + k] + vs * noise[j + 3 + k]
    v[V_GPS_EPH] = c[C_GPS_EPH]
    v[V_GPS_EPV] = c[C_GPS_EPV]
    v[V_GPS_FIX_TYPE] = c[C_GPS_FIX_TYPE]
    v[V_GPS_SATELLITES] = c[C_GPS_SATELLITES]
    return True


def sensor_constants(sensors: SensorModel, vehicle: VehicleSim) -> np.ndarray:
    """The ``C_*`` array of a sensor model and a vehicle (truth about the vehicle's world home)."""
    nm = sensors.noise_model
    c = np.zeros(N_CONSTANTS)
    c[C_HOME_ALT] = sensors.home.alt_amsl_m
    c[C_BARO_BIAS] = sensors.baro_bias_m
    c[C_BARO_NOISE] = nm.baro_noise_m
    c[C_ACCEL_NOISE] = nm.accel_noise_m_s2
    c[C_GYRO_NOISE] = nm.gyro_noise_rad_s
    c[C_MAG_NOISE] = nm.mag_noise_gauss
    c[C_MAG_FIELD_NED : C_MAG_FIELD_NED + 3] = MAG_FIELD_NED_GAUSS
    c[C_ACCEL_BIAS : C_ACCEL_BIAS + 3] = sensors._accel_bias
    c[C_GYRO_BIAS : C_GYRO_BIAS + 3] = sensors._gyro_bias
    c[C_MAG_BIAS : C_MAG_BIAS + 3] = sensors._mag_bias
    c[C_GPS_DECAY] = sensors._gps_decay
    c[C_GPS_INNOVATION : C_GPS_INNOVATION + 3] = sensors._gps_innovation_ned_m
    c[C_GPS_VEL_SIGMA] = sensors._gps_vel_sigma_m_s
    c[C_GPS_EPH] = sensors._gps_eph_m
    c[C_GPS_EPV] = sensors._gps_epv_m
    c[C_GPS_FIX_TYPE] = 3
    c[C_GPS_SATELLITES] = 12
    c[C_TRUTH_FRAME : C_TRUTH_FRAME + 12] = frame_constants(vehicle._home_frame)
    c[C_GPS_FRAME : C_GPS_FRAME + 12] = frame_constants(sensors._frame)
    return c


class SensorValues:
    """The sim's measurements and truth of each step in one numba call (``fill_values``) into ``values``.

    ``values`` (``N_VALUES``, layout ``mavlink_bridge.contract.sensor_values``) is reused every step.
    """

    __slots__ = ("_batch", "_constants", "_sensors", "values")

    def __init__(self, vehicle: VehicleSim, sensors: SensorModel) -> None:
        self._batch = vehicle.batch
        self._sensors = sensors
        self._constants = sensor_constants(sensors, vehicle)
        self.values = np.zeros(N_VALUES)

    def fill(self) -> bool:
        """Measurements, GPS (when due) and truth of now into ``values``; True when a GPS fix is in it."""
        s, b = self._sensors, self._batch
        if s._counters[0] + NOISE_PER_STEP > s._noise.shape[0]:
            s._reserve_noise(NOISE_PER_STEP)
        return fill_values(
            b.state,
            b.specific_force_frd,
            b.t_us,
            self._constants,
            s._noise,
            s._counters,
            s._gps_error_ned_m,
            self.values,
        )
