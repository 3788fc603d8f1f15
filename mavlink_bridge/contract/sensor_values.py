"""The sensor-values array: what the simulator measures each control step, as the bridge's frame writer reads it.

The simulator's compiled sensor kernel (``sim.frame_kernel``) fills one float64 array laid out by the ``V_*``
indices below (SI units, the fields of ``SensorSample``, ``GroundTruth`` and ``GpsSample``); the bridge's
compiled writer (``mavlink_bridge.wire.frame_writer``) packs it into the lockstep datagram. Obstacle detections
travel as rows laid out by the ``D_*`` columns. Neither side knows the other's code: this layout is the
contract between them (like ``wire``'s dataclasses for the typed path).
"""

from __future__ import annotations

# --- the values array: SI units, the fields of SensorSample, GroundTruth and GpsSample -----------
V_ACCEL_FRD = 0  # 3, m/s² (specific force, with noise and bias)
V_GYRO_FRD = 3  # 3, rad/s
V_MAG_FRD = 6  # 3, gauss
V_PRESSURE_HPA = 9
V_PRESSURE_ALT = 10  # m
V_TEMPERATURE = 11  # °C
V_Q_NED_FRD = 12  # 4, w first (truth)
V_RATE_FRD = 16  # 3, rad/s (truth)
V_LAT_DEG = 19  # truth
V_LON_DEG = 20
V_ALT_AMSL = 21  # m
V_VEL_NED = 22  # 3, m/s
V_ACCEL_TRUTH_FRD = 25  # 3, m/s² (specific force)
V_GPS_LAT_DEG = 28
V_GPS_LON_DEG = 29
V_GPS_ALT_AMSL = 30  # m
V_GPS_VEL_NED = 31  # 3, m/s
V_GPS_EPH = 34  # m
V_GPS_EPV = 35  # m
V_GPS_FIX_TYPE = 36
V_GPS_SATELLITES = 37
N_VALUES = 38

# --- detection rows (float64; the integers are exact below 2**53) --------------------------------
D_POS_FRD = 0  # 3, m: nearest surface point, body FRD
D_RADIUS = 3  # m
D_TIME_US = 4
D_OBSTACLE_ID = 5
D_SHAPE = 6  # ObstacleShape value
N_DET = 7
