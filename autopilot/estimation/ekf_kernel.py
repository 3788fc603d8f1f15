"""The EKF's per-step work in one numba call: alignment, IMU prediction, GPS/baro/mag fusion, output.

An error-state (indirect) Kalman filter in the spirit of PX4 EKF2 (``EKF/covariance.cpp``,
``EKF/gps_fusion.cpp``, ``EKF/baro_height_control.cpp``, ``EKF/mag_fusion.cpp``); written from the
equations, not from that code. Nominal state ``x`` (``X_*``): ``q_ned_frd`` (4), ``vel_ned_m_s`` (3),
``pos_ned_m`` (3), ``gyro_bias_frd_rad_s`` (3), ``accel_bias_frd_m_s2`` (3), ``mag_bias_frd_gauss`` (3).
Error state (``E_*``, 18): ``δθ_ned`` (global attitude error, ``R_true = (I + [δθ]×) R̂``), ``δv``, ``δp``,
``δb_g``, ``δb_a``, ``δb_m``.

Prediction (``dt`` from the sensor timestamps), with ``ω = ω_m − b_g`` and ``f = f_m − b_a``:
``q ← q ⊗ exp(ω dt)``, ``v ← v + (R f + g) dt``, ``p ← p + v dt + ½ (R f + g) dt²``; the error dynamics
``δθ' = −R δb_g``, ``δv' = −[R f]× δθ − R δb_a``, ``δp' = δv`` give ``Φ = I + F dt`` and
``P ← Φ P Φᵀ + Q`` with ``Q`` from the noise densities (PX4's EKF2_GYR_NOISE, EKF2_ACC_NOISE,
EKF2_GYR_B_NOISE, EKF2_ACC_B_NOISE, EKF2_MAG_B_NOISE as per-sample sigmas times dt).

Updates are scalar and sequential (``S = h P hᵀ + R``, ``K = P hᵀ / S``, ``P ← P − K h P``): GPS velocity (3),
GPS horizontal position (2), baro height (or GPS height while the baro is not fused) observe one error state
each (``h = e_i``); the magnetometer's three body components ``m = R̂ᵀ m_ned + b_m`` have
``h = [R̂ᵀ [m_ned]×, 0, …, e_j]``. A group is rejected as a whole when any component's test ratio
``y² / (gate² S)`` exceeds 1 (PX4's innovation consistency check). The accumulated error is injected into the
nominal state after the step's updates (``q ← δq(δθ) ⊗ q``).

All state lives in preallocated arrays (``x``, ``P``, ``aux``, ``work``, ``out``); nothing is allocated here.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from mavlink_bridge.contract.frames import (
    _GEODETIC_ITERATIONS,
    _WGS84_A_M,
    _WGS84_B_M,
    _WGS84_E2,
    _WGS84_EP2,
    GRAVITY_M_S2,
)

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
N_PRM = 33

# aux: alignment accumulators, timers (sim seconds), test ratios, flags
A_T, A_ALIGN_N, A_ACC_SUM, A_MAG_SUM, A_GYR_SUM = 0, 1, 2, 5, 8
A_HAS_ORIGIN, A_POS_INIT, A_BARO_OFFSET, A_BARO_REF_OK = 11, 12, 13, 14
A_T_GPS_POS, A_T_GPS_VEL, A_T_BARO, A_T_MAG, A_T_GPS_HGT = 15, 16, 17, 18, 19
A_POS_TR, A_VEL_TR, A_HGT_TR, A_MAG_TR = 20, 21, 22, 23
A_T_POS_REJECT, A_T_BARO_SEEN, A_T_MAG_SEEN, A_T_IMU_BAD = 24, 25, 26, 27
A_FLAGS, A_VERSION, A_T_ALIGNED, A_T_GPS_SEEN, A_T_GPS_START = 28, 29, 30, 31, 32
A_MAG_EARTH = 33  # 3 values: the Earth field (gauss, NED) from the alignment's strength and inclination
A_T_BUMP = 36  # when the status version last changed
N_AUX = 37
_STATUS_PERIOD_S = 0.1  # the status version changes at least this often (accuracies, test ratios)

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

# out: what a VehicleState is built from
O_Q, O_VEL, O_POS, O_RATE, O_EULER, O_GEO, O_VALID, O_ACC_H, O_ACC_V, O_VEL_ACC = 0, 4, 7, 10, 13, 16, 19, 20, 21, 22
N_OUT = 24

# work: the accumulated error state and the scratch matrices of the covariance prediction
W_DX = 0
W_PHI = N_E  # N_E * N_E
W_TMP = W_PHI + N_E * N_E  # N_E * N_E
W_H = W_TMP + N_E * N_E  # a measurement Jacobian row
W_PHT = W_H + N_E  # P Hᵀ
N_WORK = W_PHT + N_E

_NEVER = -1.0e9
_G = GRAVITY_M_S2
_ALIGN_ACC_TOL_M_S2 = 1.0  # |f| within g ± this while aligning
_ALIGN_GYRO_MAX_RAD_S = 0.2  # and |ω| below this
_MAG_MIN_GAUSS = 0.05  # a field weaker than this is "no magnetometer"


@njit(cache=True, inline="always")
def _dcm(q, r):  # pragma: no cover - numba kernel
    """R(q) (body FRD → NED) into the 3x3 ``r``."""
    w, a, b, c = q[0], q[1], q[2], q[3]
    r[0, 0] = 1 - 2 * (b * b + c * c)
    r[0, 1] = 2 * (a * b - w * c)
    r[0, 2] = 2 * (a * c + w * b)
    r[1, 0] = 2 * (a * b + w * c)
    r[1, 1] = 1 - 2 * (a * a + c * c)
    r[1, 2] = 2 * (b * c - w * a)
    r[2, 0] = 2 * (a * c - w * b)
    r[2, 1] = 2 * (b * c + w * a)
    r[2, 2] = 1 - 2 * (a * a + b * b)


@njit(cache=True)
def _set_euler(x, roll, pitch, yaw):  # pragma: no cover - numba kernel
    """``x[X_Q:X_Q+4]`` from ZYX Euler angles (rad)."""
    cr, sr = math.cos(0.5 * roll), math.sin(0.5 * roll)
    cp, sp = math.cos(0.5 * pitch), math.sin(0.5 * pitch)
    cy, sy = math.cos(0.5 * yaw), math.sin(0.5 * yaw)
    x[X_Q] = cr * cp * cy + sr * sp * sy
    x[X_Q + 1] = sr * cp * cy - cr * sp * sy
    x[X_Q + 2] = cr * sp * cy + sr * cp * sy
    x[X_Q + 3] = cr * cp * sy - sr * sp * cy


@njit(cache=True)
def _ned_from_geodetic(prm, lat_deg, lon_deg, alt_m, out3):  # pragma: no cover - numba kernel
    """``LocalNedFrame.ned_from_geodetic`` about the origin in ``prm[P_ECEF:]``."""
    lat, lon = math.radians(lat_deg), math.radians(lon_deg)
    s, c = math.sin(lat), math.cos(lat)
    n = _WGS84_A_M / math.sqrt(1.0 - _WGS84_E2 * s * s)
    dx = (n + alt_m) * c * math.cos(lon) - prm[P_ECEF]
    dy = (n + alt_m) * c * math.sin(lon) - prm[P_ECEF + 1]
    dz = (n * (1.0 - _WGS84_E2) + alt_m) * s - prm[P_ECEF + 2]
    e = P_ECEF + 3
    out3[0] = prm[e] * dx + prm[e + 1] * dy + prm[e + 2] * dz
    out3[1] = prm[e + 3] * dx + prm[e + 4] * dy
    out3[2] = prm[e + 6] * dx + prm[e + 7] * dy + prm[e + 8] * dz


@njit(cache=True)
def _geodetic_from_ned(prm, n_m, e_m, d_m, out, at):  # pragma: no cover - numba kernel
    """``LocalNedFrame.geodetic_from_ned`` (Bowring start + fixed-point steps) into ``out[at:at+3]``."""
    e = P_ECEF + 3
    x = prm[P_ECEF] + prm[e] * n_m + prm[e + 3] * e_m + prm[e + 6] * d_m
    y = prm[P_ECEF + 1] + prm[e + 1] * n_m + prm[e + 4] * e_m + prm[e + 7] * d_m
    z = prm[P_ECEF + 2] + prm[e + 2] * n_m + prm[e + 5] * e_m + prm[e + 8] * d_m
    lon = math.atan2(y, x)
    p = math.sqrt(x * x + y * y)
    theta = math.atan2(z * _WGS84_A_M, p * _WGS84_B_M)
    st, ct = math.sin(theta), math.cos(theta)
    lat = math.atan2(z + _WGS84_EP2 * _WGS84_B_M * st * st * st, p - _WGS84_E2 * _WGS84_A_M * ct * ct * ct)
    alt = 0.0
    for _ in range(_GEODETIC_ITERATIONS):
        s = math.sin(lat)
        nn = _WGS84_A_M / math.sqrt(1.0 - _WGS84_E2 * s * s)
        alt = p / math.cos(lat) - nn
        lat = math.atan2(z, p * (1.0 - _WGS84_E2 * nn / (nn + alt)))
    out[at] = math.degrees(lat)
    out[at + 1] = math.degrees(lon)
    out[at + 2] = alt


@njit(cache=True)
def _fuse(P, dx, col, i, h, y, r_var):  # pragma: no cover - numba kernel
    """Scalar update of a measurement ``z = h δx_i + v`` (``h = ±1``); ``col`` is scratch for ``P e_i``."""
    s = P[i, i] + r_var
    if not (s > 0.0):
        return
    for k in range(N_E):
        col[k] = P[k, i]
    resid = y - h * dx[i]
    for k in range(N_E):
        dx[k] += col[k] * h * resid / s
    # P ← P − (P e_i)(P e_i)ᵀ / S (h² = 1, P symmetric)
    for a in range(N_E):
        ka = col[a] / s
        if ka != 0.0:
            for b in range(N_E):
                P[a, b] -= ka * col[b]


@njit(cache=True)
def _fuse_row(P, dx, h, pht, y, r_var):  # pragma: no cover - numba kernel
    """Scalar update with a general Jacobian row ``h``: ``S = h P hᵀ + R``, ``K = P hᵀ / S``, ``P ← P − K h P``."""
    s = r_var
    hdx = 0.0
    for a in range(N_E):
        acc = 0.0
        for b in range(N_E):
            if h[b] != 0.0:
                acc += P[a, b] * h[b]
        pht[a] = acc
        s += h[a] * acc
        hdx += h[a] * dx[a]
    if not (s > 0.0):
        return
    resid = y - hdx
    for a in range(N_E):
        dx[a] += pht[a] * resid / s
    for a in range(N_E):
        ka = pht[a] / s
        if ka != 0.0:
            for b in range(N_E):
                P[a, b] -= ka * pht[b]


@njit(cache=True)
def _mag_row(x, aux, j, h):  # pragma: no cover - numba kernel
    """Jacobian row of body-axis ``j`` of ``m = R̂ᵀ m_ned + b_m`` (``∂/∂δθ = R̂ᵀ [m_ned]×``, ``∂/∂δb_m = e_j``);
    returns the predicted component."""
    w, a, b, c = x[X_Q], x[X_Q + 1], x[X_Q + 2], x[X_Q + 3]
    # column j of R̂ (= row j of R̂ᵀ)
    if j == 0:
        r0, r1, r2 = 1 - 2 * (b * b + c * c), 2 * (a * b + w * c), 2 * (a * c - w * b)
    elif j == 1:
        r0, r1, r2 = 2 * (a * b - w * c), 1 - 2 * (a * a + c * c), 2 * (b * c + w * a)
    else:
        r0, r1, r2 = 2 * (a * c + w * b), 2 * (b * c - w * a), 1 - 2 * (a * a + b * b)
    mn, me, md = aux[A_MAG_EARTH], aux[A_MAG_EARTH + 1], aux[A_MAG_EARTH + 2]
    for k in range(N_E):
        h[k] = 0.0
    # [m]× = [[0, −md, me], [md, 0, −mn], [−me, mn, 0]]; row = (r0, r1, r2) [m]×
    h[E_ATT] = r1 * md - r2 * me
    h[E_ATT + 1] = -r0 * md + r2 * mn
    h[E_ATT + 2] = r0 * me - r1 * mn
    h[E_MAG_BIAS + j] = 1.0
    return r0 * mn + r1 * me + r2 * md + x[X_MAG_BIAS + j]


@njit(cache=True)
def _test_ratio(P, i, y, r_var, gate):  # pragma: no cover - numba kernel
    """Innovation test ratio ``y² / (gate² S)`` (> 1: reject)."""
    return y * y / (gate * gate * (P[i, i] + r_var))


@njit(cache=True)
def _inject(x, P, dx):  # pragma: no cover - numba kernel
    """Add the accumulated error to the nominal state (``q ← δq(δθ) ⊗ q``), zero it, keep P symmetric."""
    hx, hy, hz = 0.5 * dx[E_ATT], 0.5 * dx[E_ATT + 1], 0.5 * dx[E_ATT + 2]
    w, a, b, c = x[X_Q], x[X_Q + 1], x[X_Q + 2], x[X_Q + 3]
    nw = w - hx * a - hy * b - hz * c
    na = a + hx * w + hy * c - hz * b
    nb = b - hx * c + hy * w + hz * a
    nc = c + hx * b - hy * a + hz * w
    norm = math.sqrt(nw * nw + na * na + nb * nb + nc * nc)
    x[X_Q], x[X_Q + 1], x[X_Q + 2], x[X_Q + 3] = nw / norm, na / norm, nb / norm, nc / norm
    for k in range(3):
        x[X_VEL + k] += dx[E_VEL + k]
        x[X_POS + k] += dx[E_POS + k]
        x[X_GYRO_BIAS + k] += dx[E_GYRO_BIAS + k]
        x[X_ACCEL_BIAS + k] += dx[E_ACCEL_BIAS + k]
        x[X_MAG_BIAS + k] += dx[E_MAG_BIAS + k]
    for k in range(N_E):
        dx[k] = 0.0
    for a in range(N_E):
        if P[a, a] < 1e-12:
            P[a, a] = 1e-12
        for b in range(a + 1, N_E):
            m = 0.5 * (P[a, b] + P[b, a])
            P[a, b] = m
            P[b, a] = m


@njit(cache=True)
def _reset_cov_block(P, at, var):  # pragma: no cover - numba kernel
    """Decorrelate states ``at..at+2`` and set their variance (a state reset)."""
    for k in range(at, at + 3):
        for j in range(N_E):
            P[k, j] = 0.0
            P[j, k] = 0.0
        P[k, k] = var


@njit(cache=True)
def _align(x, P, aux, prm, ax, ay, az, gx, gy, gz, mx, my, mz, t_s):  # pragma: no cover - numba kernel
    """Average still samples; after ``P_ALIGN_SAMPLES`` of them: level from f, heading from m, gyro bias from ω."""
    f_norm = math.sqrt(ax * ax + ay * ay + az * az)
    w_norm = math.sqrt(gx * gx + gy * gy + gz * gz)
    m_norm = math.sqrt(mx * mx + my * my + mz * mz)
    flags = int(aux[A_FLAGS])
    if abs(f_norm - _G) > _ALIGN_ACC_TOL_M_S2 or w_norm > _ALIGN_GYRO_MAX_RAD_S:
        for k in range(9):
            aux[A_ACC_SUM + k] = 0.0
        aux[A_ALIGN_N] = 0.0
        aux[A_FLAGS] = flags | F_MOVING
        return
    if not (m_norm > _MAG_MIN_GAUSS and math.isfinite(m_norm)):
        aux[A_FLAGS] = (flags | F_MAG_ABSENT) & ~F_MOVING
        return  # heading needs the magnetometer: wait for it
    aux[A_FLAGS] = flags & ~(F_MOVING | F_MAG_ABSENT)
    aux[A_ACC_SUM] += ax
    aux[A_ACC_SUM + 1] += ay
    aux[A_ACC_SUM + 2] += az
    aux[A_MAG_SUM] += mx
    aux[A_MAG_SUM + 1] += my
    aux[A_MAG_SUM + 2] += mz
    aux[A_GYR_SUM] += gx
    aux[A_GYR_SUM + 1] += gy
    aux[A_GYR_SUM + 2] += gz
    aux[A_ALIGN_N] += 1.0
    n = aux[A_ALIGN_N]
    if n < prm[P_ALIGN_SAMPLES]:
        return
    fx, fy, fz = aux[A_ACC_SUM] / n, aux[A_ACC_SUM + 1] / n, aux[A_ACC_SUM + 2] / n
    # at rest f_frd = Rᵀ (0, 0, −g)
    roll = math.atan2(-fy, -fz)
    pitch = math.atan2(fx, math.sqrt(fy * fy + fz * fz))
    bx, by, bz = aux[A_MAG_SUM] / n, aux[A_MAG_SUM + 1] / n, aux[A_MAG_SUM + 2] / n
    # the field levelled (yaw 0): R_y(pitch) R_x(roll) m; heading = declination − atan2(m_e, m_n)
    cr, sr, cp, sp = math.cos(roll), math.sin(roll), math.cos(pitch), math.sin(pitch)
    m_n = cp * bx + sp * sr * by + sp * cr * bz
    m_e = cr * by - sr * bz
    yaw = prm[P_MAG_DECL] - math.atan2(m_e, m_n)
    _set_euler(x, roll, pitch, yaw)
    # the Earth field: strength and inclination as measured, direction from the declination (PX4 takes them from
    # the World Magnetic Model); the heading is not taken from the field, so a body bias does not bend it
    m_h = math.sqrt(m_n * m_n + m_e * m_e)
    aux[A_MAG_EARTH] = m_h * math.cos(prm[P_MAG_DECL])
    aux[A_MAG_EARTH + 1] = m_h * math.sin(prm[P_MAG_DECL])
    aux[A_MAG_EARTH + 2] = -sp * bx + cp * sr * by + cp * cr * bz
    for k in range(3):
        x[X_VEL + k] = 0.0
        x[X_POS + k] = 0.0
        x[X_GYRO_BIAS + k] = aux[A_GYR_SUM + k] / n
        x[X_ACCEL_BIAS + k] = 0.0
    for a in range(N_E):
        for b in range(N_E):
            P[a, b] = 0.0
    tilt_var = (0.05 / _G) ** 2 + (0.02) ** 2  # accel bias / g and a margin
    P[0, 0] = tilt_var
    P[1, 1] = tilt_var
    P[2, 2] = 0.1**2
    for k in range(3):
        P[E_VEL + k, E_VEL + k] = 0.5**2
        P[E_POS + k, E_POS + k] = 100.0**2  # unknown until the first fix
        P[E_GYRO_BIAS + k, E_GYRO_BIAS + k] = (prm[P_GYR_NOISE] / math.sqrt(n)) ** 2 + 0.002**2
        P[E_ACCEL_BIAS + k, E_ACCEL_BIAS + k] = 0.1**2
        x[X_MAG_BIAS + k] = 0.0
        P[E_MAG_BIAS + k, E_MAG_BIAS + k] = 0.02**2
    aux[A_FLAGS] = int(aux[A_FLAGS]) | F_ALIGNED
    aux[A_T_ALIGNED] = t_s


@njit(cache=True)
def _predict(x, P, prm, work, dt, ax, ay, az, gx, gy, gz):  # pragma: no cover - numba kernel
    """Strapdown propagation of ``x`` and ``P ← Φ P Φᵀ + Q`` over ``dt``."""
    wx, wy, wz = gx - x[X_GYRO_BIAS], gy - x[X_GYRO_BIAS + 1], gz - x[X_GYRO_BIAS + 2]
    fx, fy, fz = ax - x[X_ACCEL_BIAS], ay - x[X_ACCEL_BIAS + 1], az - x[X_ACCEL_BIAS + 2]
    w, a, b, c = x[X_Q], x[X_Q + 1], x[X_Q + 2], x[X_Q + 3]
    r00 = 1 - 2 * (b * b + c * c)
    r01 = 2 * (a * b - w * c)
    r02 = 2 * (a * c + w * b)
    r10 = 2 * (a * b + w * c)
    r11 = 1 - 2 * (a * a + c * c)
    r12 = 2 * (b * c - w * a)
    r20 = 2 * (a * c - w * b)
    r21 = 2 * (b * c + w * a)
    r22 = 1 - 2 * (a * a + b * b)
    an = r00 * fx + r01 * fy + r02 * fz  # R f (specific force in NED)
    ae = r10 * fx + r11 * fy + r12 * fz
    ad = r20 * fx + r21 * fy + r22 * fz
    # nominal state
    for k in range(3):
        acc = (an, ae, ad + _G)[k]
        x[X_POS + k] += x[X_VEL + k] * dt + 0.5 * acc * dt * dt
        x[X_VEL + k] += acc * dt
    # q ← q ⊗ exp(ω dt) (exact for a constant ω over the step)
    ang = math.sqrt(wx * wx + wy * wy + wz * wz) * dt
    if ang > 1e-12:
        s = math.sin(0.5 * ang) / (ang / dt)
        dw, da, db, dc = math.cos(0.5 * ang), wx * s, wy * s, wz * s
    else:
        dw, da, db, dc = 1.0, 0.5 * wx * dt, 0.5 * wy * dt, 0.5 * wz * dt
    nw = w * dw - a * da - b * db - c * dc
    na = w * da + a * dw + b * dc - c * db
    nb = w * db - a * dc + b * dw + c * da
    nc = w * dc + a * db - b * da + c * dw
    norm = math.sqrt(nw * nw + na * na + nb * nb + nc * nc)
    x[X_Q], x[X_Q + 1], x[X_Q + 2], x[X_Q + 3] = nw / norm, na / norm, nb / norm, nc / norm
    # Φ = I + F dt
    phi = work[W_PHI : W_PHI + N_E * N_E].reshape((N_E, N_E))
    tmp = work[W_TMP : W_TMP + N_E * N_E].reshape((N_E, N_E))
    for i in range(N_E):
        for j in range(N_E):
            phi[i, j] = 0.0
        phi[i, i] = 1.0
    rot = ((r00, r01, r02), (r10, r11, r12), (r20, r21, r22))
    for i in range(3):
        for j in range(3):
            phi[E_ATT + i, E_GYRO_BIAS + j] = -rot[i][j] * dt
            phi[E_VEL + i, E_ACCEL_BIAS + j] = -rot[i][j] * dt
    # δv' = −[a]× δθ with a = R f: −[a]× = [[0, a_d, −a_e], [−a_d, 0, a_n], [a_e, −a_n, 0]]
    phi[E_VEL, E_ATT + 1] = ad * dt
    phi[E_VEL, E_ATT + 2] = -ae * dt
    phi[E_VEL + 1, E_ATT] = -ad * dt
    phi[E_VEL + 1, E_ATT + 2] = an * dt
    phi[E_VEL + 2, E_ATT] = ae * dt
    phi[E_VEL + 2, E_ATT + 1] = -an * dt
    for i in range(3):
        phi[E_POS + i, E_VEL + i] = dt
    # tmp = Φ P (Φ's sparsity: skip its zeros)
    for i in range(N_E):
        for j in range(N_E):
            acc = 0.0
            for k in range(N_E):
                f = phi[i, k]
                if f != 0.0:
                    acc += f * P[k, j]
            tmp[i, j] = acc
    # P = tmp Φᵀ
    for i in range(N_E):
        for j in range(i, N_E):
            acc = 0.0
            for k in range(N_E):
                f = phi[j, k]
                if f != 0.0:
                    acc += tmp[i, k] * f
            P[i, j] = acc
            P[j, i] = acc
    q_att = (prm[P_GYR_NOISE] * dt) ** 2
    q_vel = (prm[P_ACC_NOISE] * dt) ** 2
    q_bg = (prm[P_GYR_B_NOISE] * dt) ** 2
    q_ba = (prm[P_ACC_B_NOISE] * dt) ** 2
    q_bm = (prm[P_MAG_B_NOISE] * dt) ** 2
    for k in range(3):
        P[E_MAG_BIAS + k, E_MAG_BIAS + k] += q_bm
        P[E_ATT + k, E_ATT + k] += q_att
        P[E_VEL + k, E_VEL + k] += q_vel
        P[E_GYRO_BIAS + k, E_GYRO_BIAS + k] += q_bg
        P[E_ACCEL_BIAS + k, E_ACCEL_BIAS + k] += q_ba


@njit(cache=True)
def _fuse_gps(x, P, aux, prm, work, t_s, gps3, gvn, gve, gvd, eph_m, epv_m):  # pragma: no cover - numba kernel
    """GPS velocity (3) and horizontal position (2) as gated groups; GPS height when baro is not fused."""
    dx = work[W_DX : W_DX + N_E]
    flags = int(aux[A_FLAGS])
    if not (flags & F_POS_INIT):  # the first fix after alignment: reset position and velocity (PX4 on GPS start)
        for k in range(3):
            x[X_POS + k] = gps3[k]
            x[X_VEL + k] = (gvn, gve, gvd)[k]
        _reset_cov_block(P, E_POS, max(prm[P_GPS_P_NOISE], eph_m) ** 2)
        P[E_POS + 2, E_POS + 2] = max(prm[P_GPS_HGT_NOISE], epv_m) ** 2
        _reset_cov_block(P, E_VEL, max(prm[P_GPS_V_NOISE], 0.1) ** 2)
        aux[A_FLAGS] = flags | F_POS_INIT
        aux[A_T_GPS_POS] = t_s
        aux[A_T_GPS_VEL] = t_s
        aux[A_BARO_REF_OK] = 0.0  # re-reference the baro to this height
        return
    # velocity
    r_vel = prm[P_GPS_V_NOISE] ** 2
    gv = (gvn, gve, gvd)
    ratio = 0.0
    for k in range(3):
        ratio = max(ratio, _test_ratio(P, E_VEL + k, gv[k] - x[X_VEL + k], r_vel, prm[P_GPS_V_GATE]))
    aux[A_VEL_TR] = ratio
    if ratio <= 1.0:
        for k in range(3):
            _fuse(P, dx, work[W_PHT : W_PHT + N_E], E_VEL + k, 1.0, gv[k] - x[X_VEL + k], r_vel)
        aux[A_T_GPS_VEL] = t_s
        flags &= ~F_VEL_REJECTED
    else:
        flags |= F_VEL_REJECTED
    # horizontal position
    r_pos = max(prm[P_GPS_P_NOISE], eph_m) ** 2
    ratio = 0.0
    for k in range(2):
        ratio = max(ratio, _test_ratio(P, E_POS + k, gps3[k] - x[X_POS + k], r_pos, prm[P_GPS_P_GATE]))
    aux[A_POS_TR] = ratio
    if ratio <= 1.0:
        for k in range(2):
            _fuse(P, dx, work[W_PHT : W_PHT + N_E], E_POS + k, 1.0, gps3[k] - x[X_POS + k], r_pos)
        aux[A_T_GPS_POS] = t_s
        aux[A_T_POS_REJECT] = _NEVER
        flags &= ~F_POS_REJECTED
    else:
        flags |= F_POS_REJECTED
        gps_was_lost = t_s - aux[A_T_GPS_SEEN] > prm[P_NOAID_S]  # GPS back after an outage: restart on it
        if aux[A_T_POS_REJECT] == _NEVER and not gps_was_lost:
            aux[A_T_POS_REJECT] = t_s
        elif gps_was_lost or t_s - aux[A_T_POS_REJECT] > prm[P_GPS_RESET_S]:
            # back after an outage, or rejected for too long: trust the receiver again (PX4's reset to GPS)
            for k in range(2):
                x[X_POS + k] = gps3[k]
                x[X_VEL + k] = gv[k]
            _reset_cov_block(P, E_POS, r_pos)
            P[E_POS + 2, E_POS + 2] = max(P[E_POS + 2, E_POS + 2], 0.01)
            aux[A_T_POS_REJECT] = _NEVER
            aux[A_T_GPS_POS] = t_s
            flags &= ~F_POS_REJECTED
    # height from GPS while the baro is not fused (absent or rejected)
    if t_s - aux[A_T_BARO] > prm[P_FUSE_TIMEOUT_S]:
        r_hgt = max(prm[P_GPS_HGT_NOISE], epv_m) ** 2
        y = gps3[2] - x[X_POS + 2]
        tr = _test_ratio(P, E_POS + 2, y, r_hgt, prm[P_BARO_GATE])
        aux[A_HGT_TR] = tr
        if tr <= 1.0 or t_s - aux[A_T_GPS_HGT] > prm[P_GPS_RESET_S]:
            if tr > 1.0:  # rejected for too long: reset the height to the receiver's
                x[X_POS + 2] = gps3[2]
                P[E_POS + 2, E_POS + 2] = r_hgt
            else:
                _fuse(P, dx, work[W_PHT : W_PHT + N_E], E_POS + 2, 1.0, y, r_hgt)
            aux[A_T_GPS_HGT] = t_s
    aux[A_FLAGS] = flags


@njit(cache=True)
def ekf_step(
    x, P, aux, prm, work, out, t_us, ax, ay, az, gx, gy, gz, mx, my, mz, baro_alt_m,
    has_gps, gps_lat_deg, gps_lon_deg, gps_alt_m, gvn, gve, gvd, eph_m, epv_m,
):  # fmt: skip  # pragma: no cover - numba kernel
    """One control step: align or predict, fuse what arrived, fill ``out``; returns the status version.

    Non-finite samples are skipped source by source (an IMU sample with a NaN skips the prediction).
    ``has_gps``: 1 when this step carries a usable 3D fix (the caller checked fix type and set the origin).
    The version changes when a flag changes, GPS was fused, or every ``_STATUS_PERIOD_S`` (the caller rebuilds
    its status then).
    """
    t_s = t_us * 1e-6
    dt = t_s - aux[A_T]
    first = aux[A_T] == _NEVER
    aux[A_T] = t_s
    old_flags = int(aux[A_FLAGS])
    bump = False
    imu_ok = math.isfinite(ax + ay + az + gx + gy + gz)
    m_norm = math.sqrt(mx * mx + my * my + mz * mz)
    mag_ok = math.isfinite(m_norm) and m_norm > _MAG_MIN_GAUSS
    baro_ok = math.isfinite(baro_alt_m)
    baro_gap_s = t_s - aux[A_T_BARO_SEEN]  # since the previous finite baro sample
    if baro_ok:
        aux[A_T_BARO_SEEN] = t_s
    if mag_ok:
        aux[A_T_MAG_SEEN] = t_s
    if not imu_ok:
        aux[A_T_IMU_BAD] = t_s
    timeout = prm[P_FUSE_TIMEOUT_S]
    if not (old_flags & F_ALIGNED):
        if imu_ok:
            _align(x, P, aux, prm, ax, ay, az, gx, gy, gz, mx, my, mz, t_s)
    else:
        if imu_ok and not first and dt > 0.0:
            _predict(x, P, prm, work, min(dt, 0.05), ax, ay, az, gx, gy, gz)
        dx = work[W_DX : W_DX + N_E]
        # GPS (origin set by the caller at the first good fix)
        if has_gps == 1 and math.isfinite(gps_lat_deg + gps_lon_deg + gps_alt_m + gvn + gve + gvd):
            gps3 = out[O_RATE : O_RATE + 3]  # scratch until the output is written below
            _ned_from_geodetic(prm, gps_lat_deg, gps_lon_deg, gps_alt_m, gps3)
            _fuse_gps(x, P, aux, prm, work, t_s, gps3, gvn, gve, gvd, eph_m, epv_m)
            aux[A_T_GPS_SEEN] = t_s
            bump = True
        pos_init = int(aux[A_FLAGS]) & F_POS_INIT
        # baro height: h = baro − offset, referenced to the filter height when (re)initialised
        if baro_ok and pos_init:
            if aux[A_BARO_REF_OK] == 0.0 or baro_gap_s > timeout:
                aux[A_BARO_OFFSET] = baro_alt_m + x[X_POS + 2]
                aux[A_BARO_REF_OK] = 1.0
            y = -(baro_alt_m - aux[A_BARO_OFFSET]) - x[X_POS + 2]  # in down
            r_baro = prm[P_BARO_NOISE] ** 2
            tr = _test_ratio(P, E_POS + 2, y, r_baro, prm[P_BARO_GATE])
            aux[A_HGT_TR] = tr
            if tr <= 1.0:
                _fuse(P, dx, work[W_PHT : W_PHT + N_E], E_POS + 2, 1.0, y, r_baro)
                aux[A_T_BARO] = t_s
                aux[A_FLAGS] = int(aux[A_FLAGS]) & ~F_BARO_REJECTED
            else:
                aux[A_FLAGS] = int(aux[A_FLAGS]) | F_BARO_REJECTED
        # magnetometer: the three body components, m = R̂ᵀ m_ned + b_m (PX4's 3-axis mag fusion), gated together
        if mag_ok:
            h = work[W_H : W_H + N_E]
            pht = work[W_PHT : W_PHT + N_E]
            r_mag = prm[P_MAG_NOISE] ** 2
            meas = (mx, my, mz)
            ratio = 0.0
            for j in range(3):
                y = meas[j] - _mag_row(x, aux, j, h)
                s_var = r_mag
                for a in range(N_E):
                    if h[a] != 0.0:
                        for b in range(N_E):
                            s_var += h[a] * P[a, b] * h[b]
                ratio = max(ratio, y * y / (prm[P_MAG_GATE] ** 2 * s_var))
            aux[A_MAG_TR] = ratio
            if ratio <= 1.0:
                for j in range(3):
                    y = meas[j] - _mag_row(x, aux, j, h)
                    _fuse_row(P, dx, h, pht, y, r_mag)
                aux[A_T_MAG] = t_s
                aux[A_FLAGS] = int(aux[A_FLAGS]) & ~F_MAG_REJECTED
            else:
                aux[A_FLAGS] = int(aux[A_FLAGS]) | F_MAG_REJECTED
        _inject(x, P, dx)
    # flags
    flags = int(aux[A_FLAGS])
    aligned = flags & F_ALIGNED
    pos_init = flags & F_POS_INIT
    keep = F_ALIGNED | F_POS_INIT | F_POS_REJECTED | F_VEL_REJECTED | F_BARO_REJECTED | F_MAG_REJECTED
    flags &= keep | F_MOVING
    if aligned:
        flags &= ~F_MOVING
    flags |= 0 if mag_ok else F_MAG_ABSENT
    flags |= 0 if baro_ok else F_BARO_ABSENT
    gps_fused = pos_init and t_s - aux[A_T_GPS_POS] <= timeout
    if gps_fused:
        flags |= F_GPS_FUSED
        if not old_flags & F_GPS_FUSED:
            aux[A_T_GPS_START] = t_s
    if aligned and t_s - aux[A_T_BARO] <= timeout:
        flags |= F_BARO_FUSED
    elif pos_init and t_s - aux[A_T_GPS_HGT] <= timeout:
        flags |= F_GPS_HGT
    if aligned and t_s - aux[A_T_MAG] <= timeout:
        flags |= F_MAG_FUSED
    no_aid_s = t_s - max(aux[A_T_GPS_POS], aux[A_T_GPS_VEL])
    if pos_init and no_aid_s > prm[P_NOAID_S]:
        flags |= F_DEAD_RECKONING
    if pos_init and no_aid_s <= prm[P_NOAID_VALID_S]:
        flags |= F_POS_HORIZ_VALID
    if pos_init and flags & (F_BARO_FUSED | F_GPS_HGT):
        flags |= F_POS_VERT_VALID
    if t_s - aux[A_T_IMU_BAD] <= timeout:
        flags |= F_IMU_BAD
    aux[A_FLAGS] = flags
    if flags != old_flags:
        bump = True
    if bump or t_s - aux[A_T_BUMP] >= _STATUS_PERIOD_S:
        aux[A_VERSION] += 1.0
        aux[A_T_BUMP] = t_s
    # output
    for k in range(4):
        out[O_Q + k] = x[X_Q + k]
    for k in range(3):
        out[O_VEL + k] = x[X_VEL + k]
        out[O_POS + k] = x[X_POS + k]
    if imu_ok:
        out[O_RATE] = gx - x[X_GYRO_BIAS]
        out[O_RATE + 1] = gy - x[X_GYRO_BIAS + 1]
        out[O_RATE + 2] = gz - x[X_GYRO_BIAS + 2]
    else:
        out[O_RATE] = out[O_RATE + 1] = out[O_RATE + 2] = 0.0
    w, a, b, c = x[X_Q], x[X_Q + 1], x[X_Q + 2], x[X_Q + 3]
    out[O_EULER] = math.atan2(2.0 * (w * a + b * c), 1.0 - 2.0 * (a * a + b * b))
    out[O_EULER + 1] = math.asin(max(-1.0, min(1.0, 2.0 * (w * b - c * a))))
    out[O_EULER + 2] = math.atan2(2.0 * (w * c + a * b), 1.0 - 2.0 * (b * b + c * c))
    if aux[A_HAS_ORIGIN] == 1.0:
        _geodetic_from_ned(prm, x[X_POS], x[X_POS + 1], x[X_POS + 2], out, O_GEO)
    else:
        out[O_GEO] = out[O_GEO + 1] = out[O_GEO + 2] = math.nan
    finite = True
    for k in range(N_X):
        if not math.isfinite(x[k]):
            finite = False
    out[O_VALID] = 1.0 if (aligned and pos_init and finite) else 0.0
    out[O_ACC_H] = math.sqrt(max(P[E_POS, E_POS], P[E_POS + 1, E_POS + 1]))
    out[O_ACC_V] = math.sqrt(P[E_POS + 2, E_POS + 2])
    out[O_VEL_ACC] = math.sqrt(max(P[E_VEL, E_VEL], P[E_VEL + 1, E_VEL + 1], P[E_VEL + 2, E_VEL + 2]))
    return int(aux[A_VERSION])


def new_arrays() -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``x, P, aux, prm, work, out`` for one filter (identity attitude, timers "never")."""
    x = np.zeros(N_X)
    x[X_Q] = 1.0
    aux = np.zeros(N_AUX)
    for k in (A_T, A_T_GPS_POS, A_T_GPS_VEL, A_T_BARO, A_T_MAG, A_T_GPS_HGT, A_T_POS_REJECT):
        aux[k] = _NEVER
    for k in (A_T_BARO_SEEN, A_T_MAG_SEEN, A_T_IMU_BAD, A_T_ALIGNED, A_T_GPS_SEEN, A_T_GPS_START, A_T_BUMP):
        aux[k] = _NEVER
    for k in (A_POS_TR, A_VEL_TR, A_HGT_TR, A_MAG_TR):
        aux[k] = math.nan
    return x, np.eye(N_E), aux, np.zeros(N_PRM), np.zeros(N_WORK), np.zeros(N_OUT)
