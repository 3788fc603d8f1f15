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

from numba import njit

from autopilot.estimation.ekf_layout import (
    A_BARO_DATUM,
    A_BARO_OFFSET,
    A_BARO_REF_OK,
    A_FLAGS,
    A_HAS_ORIGIN,
    A_HGT_TR,
    A_MAG_TR,
    A_T,
    A_T_BARO,
    A_T_BARO_SEEN,
    A_T_BUMP,
    A_T_GPS_HGT,
    A_T_GPS_POS,
    A_T_GPS_SEEN,
    A_T_GPS_START,
    A_T_GPS_VEL,
    A_T_IMU_BAD,
    A_T_MAG,
    A_T_MAG_SEEN,
    A_T_ZUPT,
    A_VERSION,
    ALIGN_ACC_TOL_M_S2,
    ALIGN_GYRO_MAX_RAD_S,
    E_ACCEL_BIAS,
    E_ATT,
    E_GYRO_BIAS,
    E_MAG_BIAS,
    E_POS,
    E_VEL,
    F_ALIGNED,
    F_AT_REST,
    F_BARO_ABSENT,
    F_BARO_FUSED,
    F_BARO_REJECTED,
    F_DEAD_RECKONING,
    F_GPS_FUSED,
    F_GPS_HGT,
    F_IMU_BAD,
    F_MAG_ABSENT,
    F_MAG_FUSED,
    F_MAG_REJECTED,
    F_MOVING,
    F_POS_HORIZ_VALID,
    F_POS_INIT,
    F_POS_REJECTED,
    F_POS_VERT_VALID,
    F_VEL_REJECTED,
    MAG_MIN_GAUSS,
    N_E,
    N_X,
    NEVER,
    O_ACC_H,
    O_ACC_V,
    O_EULER,
    O_GEO,
    O_POS,
    O_Q,
    O_RATE,
    O_VALID,
    O_VEL,
    O_VEL_ACC,
    P_ACC_B_NOISE,
    P_ACC_NOISE,
    P_BARO_GATE,
    P_BARO_NOISE,
    P_FUSE_TIMEOUT_S,
    P_GYR_B_NOISE,
    P_GYR_NOISE,
    P_MAG_B_NOISE,
    P_MAG_GATE,
    P_MAG_NOISE,
    P_NOAID_S,
    P_NOAID_VALID_S,
    P_ZUPT_NOISE,
    P_ZUPT_PERIOD_S,
    STATUS_PERIOD_S,
    W_DX,
    W_H,
    W_PHI,
    W_PHT,
    W_TMP,
    X_ACCEL_BIAS,
    X_GYRO_BIAS,
    X_POS,
    X_Q,
    X_VEL,
    G,
)
from autopilot.estimation.ekf_math import (
    align,
    fuse,
    fuse_gps,
    fuse_row,
    geodetic_from_ned,
    inject,
    innovation_test_ratio,
    mag_row,
    ned_from_geodetic,
)


@njit(cache=True)
def _a_times(m, out, ra, sk, dt):  # pragma: no cover - numba kernel
    """``out = A m`` for the sparse ``A = F dt``: attitude rows ``−R dt`` on the gyro bias, velocity rows
    ``−[R f]× dt`` on the attitude and ``−R dt`` on the accel bias, position rows ``dt`` on the velocity."""
    for c in range(N_E):
        for i in range(3):
            out[E_ATT + i, c] = (
                ra[i][0] * m[E_GYRO_BIAS, c] + ra[i][1] * m[E_GYRO_BIAS + 1, c] + ra[i][2] * m[E_GYRO_BIAS + 2, c]
            )
            out[E_VEL + i, c] = (
                sk[i][0] * m[E_ATT, c] + sk[i][1] * m[E_ATT + 1, c] + sk[i][2] * m[E_ATT + 2, c]
                + ra[i][0] * m[E_ACCEL_BIAS, c] + ra[i][1] * m[E_ACCEL_BIAS + 1, c] + ra[i][2] * m[E_ACCEL_BIAS + 2, c]
            )  # fmt: skip
            out[E_POS + i, c] = dt * m[E_VEL + i, c]
        for r in range(E_GYRO_BIAS, N_E):
            out[r, c] = 0.0


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
        acc = (an, ae, ad + G)[k]
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
    # Φ P Φᵀ = P + B + Bᵀ + A Bᵀ with Φ = I + A (A = F dt, 27 non-zeros) and B = A P: a tenth of a dense product
    b = work[W_PHI : W_PHI + N_E * N_E].reshape((N_E, N_E))
    d = work[W_TMP : W_TMP + N_E * N_E].reshape((N_E, N_E))
    ra = ((-r00 * dt, -r01 * dt, -r02 * dt), (-r10 * dt, -r11 * dt, -r12 * dt), (-r20 * dt, -r21 * dt, -r22 * dt))
    # δv' = −[a]× δθ with a = R f: −[a]× = [[0, a_d, −a_e], [−a_d, 0, a_n], [a_e, −a_n, 0]]
    sk = ((0.0, ad * dt, -ae * dt), (-ad * dt, 0.0, an * dt), (ae * dt, -an * dt, 0.0))
    _a_times(P, b, ra, sk, dt)  # B = A P
    _a_times(b.T, d, ra, sk, dt)  # D = A Bᵀ = (A P Aᵀ)ᵀ
    for i in range(N_E):
        for j in range(i, N_E):
            v = P[i, j] + b[i, j] + b[j, i] + d[j, i]
            P[i, j] = v
            P[j, i] = v
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
def ekf_step(
    x, P, aux, prm, work, out, t_us, ax, ay, az, gx, gy, gz, mx, my, mz, baro_alt_m,
    has_gps, gps_lat_deg, gps_lon_deg, gps_alt_m, gvn, gve, gvd, eph_m, epv_m, landed,
):  # fmt: skip  # pragma: no cover - numba kernel
    """One control step: align or predict, fuse what arrived, fill ``out``; returns the status version.

    Non-finite samples are skipped source by source (an IMU sample with a NaN skips the prediction).
    ``has_gps``: 1 when this step carries a usable 3D fix (the caller checked fix type and set the origin).
    ``landed``: 1 while the land detector says the vehicle is on the ground (PX4's ``vehicle_land_detected``);
    with a still IMU the velocity is observed as zero (the ZUPT, every ``P_ZUPT_PERIOD_S``, ungated).
    The version changes when a flag changes, GPS was fused, or every ``STATUS_PERIOD_S`` (the caller rebuilds
    its status then).
    """
    t_s = t_us * 1e-6
    dt = t_s - aux[A_T]
    first = aux[A_T] == NEVER
    aux[A_T] = t_s
    old_flags = int(aux[A_FLAGS])
    bump = False
    imu_ok = math.isfinite(ax + ay + az + gx + gy + gz)
    m_norm = math.sqrt(mx * mx + my * my + mz * mz)
    mag_ok = math.isfinite(m_norm) and m_norm > MAG_MIN_GAUSS
    baro_ok = math.isfinite(baro_alt_m)
    baro_gap_s = t_s - aux[A_T_BARO_SEEN]  # since the previous finite baro sample
    if baro_ok:
        aux[A_T_BARO_SEEN] = t_s
    if mag_ok:
        aux[A_T_MAG_SEEN] = t_s
    if not imu_ok:
        aux[A_T_IMU_BAD] = t_s
    timeout = prm[P_FUSE_TIMEOUT_S]
    at_rest = False
    if not (old_flags & F_ALIGNED):
        if imu_ok:
            align(x, P, aux, prm, ax, ay, az, gx, gy, gz, mx, my, mz, t_s)
        if baro_ok:  # the height datum: the baro on the ground until aligned (low-passed, ~0.2 s)
            datum = aux[A_BARO_DATUM]
            aux[A_BARO_DATUM] = baro_alt_m if not math.isfinite(datum) else datum + 0.02 * (baro_alt_m - datum)
    else:
        if imu_ok and not first and dt > 0.0:
            _predict(x, P, prm, work, min(dt, 0.05), ax, ay, az, gx, gy, gz)
        dx = work[W_DX : W_DX + N_E]
        # GPS (origin set by the caller at the first good fix)
        if has_gps == 1 and math.isfinite(gps_lat_deg + gps_lon_deg + gps_alt_m + gvn + gve + gvd):
            gps3 = out[O_RATE : O_RATE + 3]  # scratch until the output is written below
            ned_from_geodetic(prm, gps_lat_deg, gps_lon_deg, gps_alt_m, gps3)
            was_init = int(aux[A_FLAGS]) & F_POS_INIT
            fuse_gps(x, P, aux, prm, work, t_s, gps3, gvn, gve, gvd, eph_m, epv_m)
            if not was_init and baro_ok and math.isfinite(aux[A_BARO_DATUM]):
                x[X_POS + 2] = aux[A_BARO_DATUM] - baro_alt_m  # the height from the datum, not the fix
            aux[A_T_GPS_SEEN] = t_s
            bump = True
        # on the ground and still: zero velocity (PX4 EKF2's ZeroVelocityUpdate while landed and at rest)
        if landed == 1 and imu_ok:
            f_norm = math.sqrt(ax * ax + ay * ay + az * az)
            w_norm = math.sqrt(gx * gx + gy * gy + gz * gz)
            at_rest = abs(f_norm - G) <= ALIGN_ACC_TOL_M_S2 and w_norm <= ALIGN_GYRO_MAX_RAD_S
            if at_rest and t_s - aux[A_T_ZUPT] >= prm[P_ZUPT_PERIOD_S]:
                r_zupt = prm[P_ZUPT_NOISE] ** 2
                for k in range(3):
                    fuse(P, dx, work[W_PHT : W_PHT + N_E], E_VEL + k, 1.0, -x[X_VEL + k], r_zupt)
                aux[A_T_ZUPT] = t_s
        pos_init = int(aux[A_FLAGS]) & F_POS_INIT
        # baro height: h = baro − offset, referenced to the filter height when (re)initialised
        if baro_ok and pos_init:
            if aux[A_BARO_REF_OK] == 0.0 or baro_gap_s > timeout:
                aux[A_BARO_OFFSET] = baro_alt_m + x[X_POS + 2]
                aux[A_BARO_REF_OK] = 1.0
            y = -(baro_alt_m - aux[A_BARO_OFFSET]) - x[X_POS + 2]  # in down
            r_baro = prm[P_BARO_NOISE] ** 2
            tr = innovation_test_ratio(P, E_POS + 2, y, r_baro, prm[P_BARO_GATE])
            aux[A_HGT_TR] = tr
            if tr <= 1.0:
                fuse(P, dx, work[W_PHT : W_PHT + N_E], E_POS + 2, 1.0, y, r_baro)
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
                y = meas[j] - mag_row(x, aux, j, h)
                s_var = r_mag
                for a in range(N_E):
                    if h[a] != 0.0:
                        for b in range(N_E):
                            s_var += h[a] * P[a, b] * h[b]
                ratio = max(ratio, y * y / (prm[P_MAG_GATE] ** 2 * s_var))
            aux[A_MAG_TR] = ratio
            if ratio <= 1.0:
                for j in range(3):
                    y = meas[j] - mag_row(x, aux, j, h)
                    fuse_row(P, dx, h, pht, y, r_mag)
                aux[A_T_MAG] = t_s
                aux[A_FLAGS] = int(aux[A_FLAGS]) & ~F_MAG_REJECTED
            else:
                aux[A_FLAGS] = int(aux[A_FLAGS]) | F_MAG_REJECTED
        inject(x, P, dx)
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
    if at_rest:
        flags |= F_AT_REST
    aux[A_FLAGS] = flags
    if flags != old_flags:
        bump = True
    if bump or t_s - aux[A_T_BUMP] >= STATUS_PERIOD_S:
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
        geodetic_from_ned(prm, x[X_POS], x[X_POS + 1], x[X_POS + 2], out, O_GEO)
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
