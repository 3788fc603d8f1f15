"""The EKF's compiled building blocks: scalar measurement updates, error injection, resets, WGS-84 about the
origin (``LocalNedFrame`` arithmetic repeated in numba), the magnetometer's Jacobian row.

Scalar sequential update (Kalman, one measurement at a time): ``S = h P hᵀ + R``, ``K = P hᵀ / S``,
``δx ← δx + K (y − h δx)``, ``P ← P − K h P``.
"""

from __future__ import annotations

import math

from numba import njit

from autopilot.estimation.ekf_layout import (
    A_ACC_SUM,
    A_ALIGN_N,
    A_BARO_REF_OK,
    A_FLAGS,
    A_GYR_SUM,
    A_HGT_TR,
    A_MAG_EARTH,
    A_MAG_SUM,
    A_POS_TR,
    A_T_ALIGNED,
    A_T_BARO,
    A_T_GPS_HGT,
    A_T_GPS_POS,
    A_T_GPS_SEEN,
    A_T_GPS_VEL,
    A_T_POS_REJECT,
    A_VEL_TR,
    ALIGN_ACC_TOL_M_S2,
    ALIGN_GYRO_MAX_RAD_S,
    E_ACCEL_BIAS,
    E_ATT,
    E_GYRO_BIAS,
    E_MAG_BIAS,
    E_POS,
    E_VEL,
    F_ALIGNED,
    F_MAG_ABSENT,
    F_MOVING,
    F_POS_INIT,
    F_POS_REJECTED,
    F_VEL_REJECTED,
    MAG_MIN_GAUSS,
    N_E,
    NEVER,
    P_ALIGN_SAMPLES,
    P_BARO_GATE,
    P_ECEF,
    P_FUSE_TIMEOUT_S,
    P_GPS_HGT_NOISE,
    P_GPS_P_GATE,
    P_GPS_P_NOISE,
    P_GPS_RESET_S,
    P_GPS_V_GATE,
    P_GPS_V_NOISE,
    P_GYR_NOISE,
    P_MAG_DECL,
    P_NOAID_S,
    W_DX,
    W_PHT,
    X_ACCEL_BIAS,
    X_GYRO_BIAS,
    X_MAG_BIAS,
    X_POS,
    X_Q,
    X_VEL,
    G,
)
from mavlink_bridge.contract import geodetic


@njit(cache=True)
def set_euler(x, roll, pitch, yaw):  # pragma: no cover - numba kernel
    """``x[X_Q:X_Q+4]`` from ZYX Euler angles (rad)."""
    cr, sr = math.cos(0.5 * roll), math.sin(0.5 * roll)
    cp, sp = math.cos(0.5 * pitch), math.sin(0.5 * pitch)
    cy, sy = math.cos(0.5 * yaw), math.sin(0.5 * yaw)
    x[X_Q] = cr * cp * cy + sr * sp * sy
    x[X_Q + 1] = sr * cp * cy - cr * sp * sy
    x[X_Q + 2] = cr * sp * cy + sr * cp * sy
    x[X_Q + 3] = cr * cp * sy - sr * sp * cy


@njit(cache=True)
def ned_from_geodetic(prm, lat_deg, lon_deg, alt_m, out3):  # pragma: no cover - numba kernel
    """GPS position to local NED about the origin in ``prm[P_ECEF:]`` (:mod:`mavlink_bridge.contract.geodetic`)."""
    out3[0], out3[1], out3[2] = geodetic.ned_from_geodetic(prm, P_ECEF, lat_deg, lon_deg, alt_m)


@njit(cache=True)
def geodetic_from_ned(prm, n_m, e_m, d_m, out, at):  # pragma: no cover - numba kernel
    """The estimate's (lat °, lon °, alt m) into ``out[at:at+3]`` (:mod:`mavlink_bridge.contract.geodetic`)."""
    out[at], out[at + 1], out[at + 2] = geodetic.geodetic_from_ned(prm, P_ECEF, n_m, e_m, d_m)


@njit(cache=True)
def fuse(P, dx, col, i, h, y, r_var):  # pragma: no cover - numba kernel
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
def fuse_row(P, dx, h, pht, y, r_var):  # pragma: no cover - numba kernel
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
def mag_row(x, aux, j, h):  # pragma: no cover - numba kernel
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
def innovation_test_ratio(P, i, y, r_var, gate):  # pragma: no cover - numba kernel
    """Innovation test ratio ``y² / (gate² S)`` (> 1: reject)."""
    return y * y / (gate * gate * (P[i, i] + r_var))


@njit(cache=True)
def inject(x, P, dx):  # pragma: no cover - numba kernel
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
def reset_cov_block(P, at, var):  # pragma: no cover - numba kernel
    """Decorrelate states ``at..at+2`` and set their variance (a state reset)."""
    for k in range(at, at + 3):
        for j in range(N_E):
            P[k, j] = 0.0
            P[j, k] = 0.0
        P[k, k] = var


@njit(cache=True)
def fuse_gps(x, P, aux, prm, work, t_s, gps3, gvn, gve, gvd, eph_m, epv_m):  # pragma: no cover - numba kernel
    """GPS velocity (3) and horizontal position (2) as gated groups; GPS height when baro is not fused."""
    dx = work[W_DX : W_DX + N_E]
    flags = int(aux[A_FLAGS])
    if not (flags & F_POS_INIT):  # the first fix after alignment: reset position and velocity (PX4 on GPS start)
        for k in range(3):
            x[X_POS + k] = gps3[k]
            x[X_VEL + k] = (gvn, gve, gvd)[k]
        reset_cov_block(P, E_POS, max(prm[P_GPS_P_NOISE], eph_m) ** 2)
        P[E_POS + 2, E_POS + 2] = max(prm[P_GPS_HGT_NOISE], epv_m) ** 2
        reset_cov_block(P, E_VEL, max(prm[P_GPS_V_NOISE], 0.1) ** 2)
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
        ratio = max(ratio, innovation_test_ratio(P, E_VEL + k, gv[k] - x[X_VEL + k], r_vel, prm[P_GPS_V_GATE]))
    aux[A_VEL_TR] = ratio
    if ratio <= 1.0:
        for k in range(3):
            fuse(P, dx, work[W_PHT : W_PHT + N_E], E_VEL + k, 1.0, gv[k] - x[X_VEL + k], r_vel)
        aux[A_T_GPS_VEL] = t_s
        flags &= ~F_VEL_REJECTED
    else:
        flags |= F_VEL_REJECTED
    # horizontal position
    r_pos = max(prm[P_GPS_P_NOISE], eph_m) ** 2
    ratio = 0.0
    for k in range(2):
        ratio = max(ratio, innovation_test_ratio(P, E_POS + k, gps3[k] - x[X_POS + k], r_pos, prm[P_GPS_P_GATE]))
    aux[A_POS_TR] = ratio
    if ratio <= 1.0:
        for k in range(2):
            fuse(P, dx, work[W_PHT : W_PHT + N_E], E_POS + k, 1.0, gps3[k] - x[X_POS + k], r_pos)
        aux[A_T_GPS_POS] = t_s
        aux[A_T_POS_REJECT] = NEVER
        flags &= ~F_POS_REJECTED
    else:
        flags |= F_POS_REJECTED
        gps_was_lost = t_s - aux[A_T_GPS_SEEN] > prm[P_NOAID_S]  # GPS back after an outage: restart on it
        if aux[A_T_POS_REJECT] == NEVER and not gps_was_lost:
            aux[A_T_POS_REJECT] = t_s
        elif gps_was_lost or t_s - aux[A_T_POS_REJECT] > prm[P_GPS_RESET_S]:
            # back after an outage, or rejected for too long: trust the receiver again (PX4's reset to GPS)
            for k in range(2):
                x[X_POS + k] = gps3[k]
                x[X_VEL + k] = gv[k]
            reset_cov_block(P, E_POS, r_pos)
            P[E_POS + 2, E_POS + 2] = max(P[E_POS + 2, E_POS + 2], 0.01)
            aux[A_T_POS_REJECT] = NEVER
            aux[A_T_GPS_POS] = t_s
            flags &= ~F_POS_REJECTED
    # height from GPS while the baro is not fused (absent or rejected)
    if t_s - aux[A_T_BARO] > prm[P_FUSE_TIMEOUT_S]:
        r_hgt = max(prm[P_GPS_HGT_NOISE], epv_m) ** 2
        y = gps3[2] - x[X_POS + 2]
        tr = innovation_test_ratio(P, E_POS + 2, y, r_hgt, prm[P_BARO_GATE])
        aux[A_HGT_TR] = tr
        if tr <= 1.0 or t_s - aux[A_T_GPS_HGT] > prm[P_GPS_RESET_S]:
            if tr > 1.0:  # rejected for too long: reset the height to the receiver's
                x[X_POS + 2] = gps3[2]
                P[E_POS + 2, E_POS + 2] = r_hgt
            else:
                fuse(P, dx, work[W_PHT : W_PHT + N_E], E_POS + 2, 1.0, y, r_hgt)
            aux[A_T_GPS_HGT] = t_s
    aux[A_FLAGS] = flags


@njit(cache=True)
def align(x, P, aux, prm, ax, ay, az, gx, gy, gz, mx, my, mz, t_s):  # pragma: no cover - numba kernel
    """Average still samples; after ``P_ALIGN_SAMPLES`` of them: level from f, heading from m, gyro bias from ω."""
    f_norm = math.sqrt(ax * ax + ay * ay + az * az)
    w_norm = math.sqrt(gx * gx + gy * gy + gz * gz)
    m_norm = math.sqrt(mx * mx + my * my + mz * mz)
    flags = int(aux[A_FLAGS])
    if abs(f_norm - G) > ALIGN_ACC_TOL_M_S2 or w_norm > ALIGN_GYRO_MAX_RAD_S:
        for k in range(9):
            aux[A_ACC_SUM + k] = 0.0
        aux[A_ALIGN_N] = 0.0
        aux[A_FLAGS] = flags | F_MOVING
        return
    if not (m_norm > MAG_MIN_GAUSS and math.isfinite(m_norm)):
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
    set_euler(x, roll, pitch, yaw)
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
    tilt_var = (0.05 / G) ** 2 + (0.02) ** 2  # accel bias / g and a margin
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
