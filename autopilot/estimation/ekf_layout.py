"""Array layout of the EKF (``ekf_kernel``): indices into its preallocated arrays, status flag bits, constants.

``x`` nominal state, ``P`` error covariance (rows ``E_*``), ``prm`` tuning and origin, ``aux`` alignment
accumulators, timers (sim seconds), test ratios and flags, ``out`` what a ``VehicleState`` is built from,
``work`` the accumulated error state and scratch. :func:`new_arrays` allocates one filter's set once.
"""

from __future__ import annotations

import math

import numpy as np

from mavlink_bridge.contract.frames import GRAVITY_M_S2

# nominal state x
X_Q, X_VEL, X_POS, X_GYRO_BIAS, X_ACCEL_BIAS, X_MAG_BIAS, N_X = 0, 4, 7, 10, 13, 16, 19
# error state (rows/columns of P)
E_ATT, E_VEL, E_POS, E_GYRO_BIAS, E_ACCEL_BIAS, E_MAG_BIAS, N_E = 0, 3, 6, 9, 12, 15, 18

# prm: tuning (EstimatorParams) and, from the first fix, the origin's ECEF constants
P_GYR_NOISE, P_ACC_NOISE, P_GYR_B_NOISE, P_ACC_B_NOISE = 0, 1, 2, 3
P_GPS_P_NOISE, P_GPS_V_NOISE, P_BARO_NOISE, P_MAG_NOISE = 4, 5, 6, 7
P_GPS_P_GATE, P_GPS_V_GATE, P_BARO_GATE, P_MAG_GATE = 8, 9, 10, 11
P_MAG_DECL, P_ALIGN_SAMPLES, P_GPS_HGT_NOISE, P_GPS_RESET_S = 12, 13, 14, 15
P_FUSE_TIMEOUT_S, P_NOAID_S, P_NOAID_VALID_S, P_GPS_MAX_EPH = 16, 17, 18, 19
P_ECEF = 20  # 12 values: home ECEF, then the north, east, down rows (LocalNedFrame.ecef_constants)
P_MAG_B_NOISE = 32
P_ZUPT_NOISE, P_ZUPT_PERIOD_S = 33, 34  # zero-velocity update on the ground (PX4 EKF2's ZeroVelocityUpdate)
N_PRM = 35

# aux: alignment accumulators, timers (sim seconds), test ratios, flags
A_T, A_ALIGN_N, A_ACC_SUM, A_MAG_SUM, A_GYR_SUM = 0, 1, 2, 5, 8
A_HAS_ORIGIN, A_POS_INIT, A_BARO_OFFSET, A_BARO_REF_OK = 11, 12, 13, 14
A_T_GPS_POS, A_T_GPS_VEL, A_T_BARO, A_T_MAG, A_T_GPS_HGT = 15, 16, 17, 18, 19
A_POS_TR, A_VEL_TR, A_HGT_TR, A_MAG_TR = 20, 21, 22, 23
A_T_POS_REJECT, A_T_BARO_SEEN, A_T_MAG_SEEN, A_T_IMU_BAD = 24, 25, 26, 27
A_FLAGS, A_VERSION, A_T_ALIGNED, A_T_GPS_SEEN, A_T_GPS_START = 28, 29, 30, 31, 32
A_MAG_EARTH = 33  # 3 values: the Earth field (gauss, NED) from the alignment's strength and inclination
A_T_BUMP = 36  # when the status version last changed
A_BARO_DATUM = 37  # the baro altitude until aligned (low-passed): the height datum, the ground started on
A_T_ZUPT = 38  # the last zero-velocity update
N_AUX = 39
STATUS_PERIOD_S = 0.1  # the status version changes at least this often (accuracies, test ratios)

# status flag bits (aux[A_FLAGS])
F_ALIGNED = 1
F_GPS_FUSED = 2
F_BARO_FUSED = 4
F_MAG_FUSED = 8
F_DEAD_RECKONING = 16
F_POS_HORIZ_VALID = 32
F_POS_VERT_VALID = 64
F_GPS_HGT = 128  # height from GPS (baro absent or rejected)
F_POS_INIT = 256  # position and velocity initialised from GPS
F_POS_REJECTED = 512  # the latest GPS position failed its gate
F_VEL_REJECTED = 1024
F_BARO_REJECTED = 2048
F_MAG_REJECTED = 4096
F_IMU_BAD = 8192  # a non-finite IMU sample within the last FUSE_TIMEOUT
F_MOVING = 16384  # alignment restarted: the vehicle was not still
F_MAG_ABSENT = 32768
F_BARO_ABSENT = 65536
F_AT_REST = 131072  # landed (the land detector) and the IMU still: zero velocity fused

# out: what a VehicleState is built from
O_Q, O_VEL, O_POS, O_RATE, O_EULER, O_GEO, O_VALID, O_ACC_H, O_ACC_V, O_VEL_ACC = 0, 4, 7, 10, 13, 16, 19, 20, 21, 22
N_OUT = 24

# work: the accumulated error state and the scratch matrices of the covariance prediction
W_DX = 0
W_PHI = N_E  # N_E * N_E: B = A P of the covariance prediction
W_TMP = W_PHI + N_E * N_E  # N_E * N_E: A Bᵀ
W_H = W_TMP + N_E * N_E  # a measurement Jacobian row
W_PHT = W_H + N_E  # P Hᵀ
N_WORK = W_PHT + N_E

NEVER = -1.0e9
G = GRAVITY_M_S2
ALIGN_ACC_TOL_M_S2 = 1.0  # |f| within g ± this while aligning
ALIGN_GYRO_MAX_RAD_S = 0.2  # and |ω| below this
MAG_MIN_GAUSS = 0.05  # a field weaker than this is "no magnetometer"


def new_arrays() -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``x, P, aux, prm, work, out`` for one filter (identity attitude, timers "never")."""
    x = np.zeros(N_X)
    x[X_Q] = 1.0
    aux = np.zeros(N_AUX)
    for k in (A_T, A_T_GPS_POS, A_T_GPS_VEL, A_T_BARO, A_T_MAG, A_T_GPS_HGT, A_T_POS_REJECT):
        aux[k] = NEVER
    for k in (A_T_BARO_SEEN, A_T_MAG_SEEN, A_T_IMU_BAD, A_T_ALIGNED, A_T_GPS_SEEN, A_T_GPS_START, A_T_BUMP):
        aux[k] = NEVER
    for k in (A_POS_TR, A_VEL_TR, A_HGT_TR, A_MAG_TR, A_BARO_DATUM):
        aux[k] = math.nan
    aux[A_T_ZUPT] = NEVER
    return x, np.eye(N_E), aux, np.zeros(N_PRM), np.zeros(N_WORK), np.zeros(N_OUT)
