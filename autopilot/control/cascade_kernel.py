"""The NLVG-PID cascade's compiled kernels (SPEC §6.2, paper eq. 11): position → attitude → torques → mixer.

Per vehicle and control step (all in normalised units, so one gain set flies every wheelbase):

1. Position NLVG-PID per axis (NED, output m/s², D on measured velocity: ė = v_sp − v):
   a = a_ff + U_xyz (U_x = ẍ_desire + f_Kp·e + f_Ki·∫e + f_Kd·ė, eq. 11).
2. Limits: vertical a ∈ [−acc_up, +acc_down] (NED, down positive), horizontal |a| ≤ acc_xy_max.
3. Thrust vector f = a − g·ẑ (specific force), tilted at most tilt_max from vertical (horizontal part
   scaled); collective thrust T = m·|f|; desired body z = −f/|f|.
4. Desired attitude: roll, pitch from body z and the yaw setpoint (PX4 bodyz-to-attitude), ψ_sp as given.
5. Attitude NLVG-PID on ZYX Euler errors (yaw error wrapped to [−π, π)), D on the measured Euler rates
   (from the body rates), output Euler angular accelerations (rad/s²) in the attitude loop's normalised
   time (time scale ``att_time_scale_s``, see pid.py), limited per axis.
6. Body angular acceleration from the Euler accelerations, torque τ = J·ω̇ (+ ω×Jω if gyroscopic).
7. Quad-X mixer with saturation priority roll/pitch > thrust > yaw (mixer.py) → u ∈ [0, 1].

NaN guard: a vehicle whose state, position or yaw setpoint, mass or gains are not finite keeps its last
motor command (zeros before the first valid step); non-finite velocity/acceleration feed-forwards count
as zero (PX4: NaN = not controlled). Nothing non-finite can reach a motor.

Gains are dimensionless in each loop's normalised time (pid.py): the paper's position gains (5, 0.2, 5) at
T = 1 s are plain SI gains (poles ≈ −1.4, −3.6 rad/s); its attitude gains (8, 0.1, 5) at T = 0.15 s give
ω_n ≈ 19 rad/s, ζ ≈ 0.88 — an inner loop ~5× faster than the outer one (CascadeLimits).

One implementation serves n = 1 and n = 1000: numba kernels loop over vehicles, indexing flat arrays.
"""

from __future__ import annotations

import math

from numba import njit

from autopilot.control.mixer import mix_one
from autopilot.control.pid import N_GAIN_COLS, N_STATE_COLS, nlvg_pid_step
from mavlink_bridge.contract.frames import GRAVITY_M_S2

# packed parameter vector: CascadeLimits.as_array() then airframe constants, then A⁻¹ (row-major)
L_TILT, L_ACC_XY, L_ACC_UP, L_ACC_DOWN, L_AA_RP, L_AA_YAW, L_I_POS, L_I_ATT, L_T_POS, L_T_ATT, L_GYRO = range(11)
P_FMAX, P_KF, P_WMAX, P_DT, P_IX, P_IY, P_IZ, P_TAN_TILT, P_AINV = range(11, 20)
N_PARAMS = P_AINV + 16
# work array columns per vehicle: PID states, live gains, errors, setpoints, outputs
W_ST = 0  # 6 channels × N_STATE_COLS
W_K = W_ST + 6 * N_STATE_COLS  # 6 channels × (kp, ki, kd)
W_ERR = W_K + 18  # x, y, z, roll, pitch, yaw errors
W_ACC = W_ERR + 6  # acceleration setpoint after limits, NED
W_ATT = W_ACC + 3  # roll, pitch, yaw setpoint
W_TQ = W_ATT + 3  # torque FRD
W_THR = W_TQ + 3  # collective thrust
W_U = W_THR + 1  # motor commands
W_OK = W_U + 4  # 1.0 when the last step was valid
N_WORK = W_OK + 1


@njit(cache=True, inline="always")
def _finite_or_zero(x):  # pragma: no cover - numba kernel
    return x if math.isfinite(x) else 0.0


@njit(cache=True, inline="always")
def _pid(ch, e, de, w, u_max, i_max, gf, gb, prm, wf, wb):  # pragma: no cover - numba kernel
    """Channel ``ch`` of the vehicle whose gain rows start at gf[gb] and work row at wf[wb]."""
    return nlvg_pid_step(
        e,
        de,
        gf,
        gb + ch * N_GAIN_COLS,
        w,
        prm[P_DT],
        u_max,
        i_max,
        wf,
        wb + W_ST + ch * N_STATE_COLS,
        wf,
        wb + W_K + 3 * ch,
    )


@njit(cache=True)
def _attitude_stage(qv, rate, v, roll_d, pitch_d, yaw_d, thrust_n, gf, prm, wf):  # pragma: no cover - numba kernel
    """Steps 5-7 for vehicle v (rows of qv, rate (n, 4), (n, 3)); returns False (nothing written) on bad input.

    ``gf``/``wf`` are the flat gain table and work array (indexed, never sliced, in the hot loop).
    """
    gb = v * 6 * N_GAIN_COLS
    wb = v * N_WORK
    qw, qx, qy, qz = qv[v, 0], qv[v, 1], qv[v, 2], qv[v, 3]
    qn = math.sqrt(qw * qw + qx * qx + qy * qy + qz * qz)
    p, q, r = rate[v, 0], rate[v, 1], rate[v, 2]
    if not (math.isfinite(qn) and qn > 1e-9 and math.isfinite(p + q + r)):
        return False
    if not (math.isfinite(roll_d) and math.isfinite(pitch_d) and math.isfinite(yaw_d) and math.isfinite(thrust_n)):
        return False
    qw, qx, qy, qz = qw / qn, qx / qn, qy / qn, qz / qn
    r21 = 2.0 * (qw * qx + qy * qz)
    r22 = 1.0 - 2.0 * (qx * qx + qy * qy)
    sp = min(max(2.0 * (qw * qy - qz * qx), -1.0), 1.0)  # sin(pitch) = −R20
    roll = math.atan2(r21, r22)
    pitch = math.asin(sp)
    yaw = math.atan2(2.0 * (qw * qz + qx * qy), 1.0 - 2.0 * (qy * qy + qz * qz))
    cp = math.sqrt(r21 * r21 + r22 * r22)  # cos(pitch) >= 0, and (sin, cos)(roll) = (R21, R22)/cos(pitch)
    if cp > 1e-9:
        sr, cr = r21 / cp, r22 / cp
    else:
        sr, cr = 0.0, 1.0
    cp_safe = max(cp, 0.05)
    roll_rate = p + (q * sr + r * cr) * sp / cp_safe
    pitch_rate = q * cr - r * sr
    yaw_rate = (q * sr + r * cr) / cp_safe
    e_roll = roll_d - roll
    e_pitch = pitch_d - pitch
    e_yaw = yaw_d - yaw
    if not (-math.pi <= e_yaw < math.pi):
        e_yaw = (e_yaw + math.pi) % (2.0 * math.pi) - math.pi
    w = 1.0 / prm[L_T_ATT]
    i_max = prm[L_I_ATT]
    acc_roll = _pid(3, e_roll, -roll_rate, w, prm[L_AA_RP], i_max, gf, gb, prm, wf, wb)
    acc_pitch = _pid(4, e_pitch, -pitch_rate, w, prm[L_AA_RP], i_max, gf, gb, prm, wf, wb)
    acc_yaw = _pid(5, e_yaw, -yaw_rate, w, prm[L_AA_YAW], i_max, gf, gb, prm, wf, wb)
    dp = acc_roll - sp * acc_yaw
    dq = cr * acc_pitch + sr * cp * acc_yaw
    dr = -sr * acc_pitch + cr * cp * acc_yaw
    ix, iy, iz = prm[P_IX], prm[P_IY], prm[P_IZ]
    tx, ty, tz = ix * dp, iy * dq, iz * dr
    if prm[L_GYRO] != 0.0:
        tx += q * iz * r - r * iy * q
        ty += r * ix * p - p * iz * r
        tz += p * iy * q - q * ix * p
    wf[wb + W_ERR + 3] = e_roll
    wf[wb + W_ERR + 4] = e_pitch
    wf[wb + W_ERR + 5] = e_yaw
    wf[wb + W_ATT] = roll_d
    wf[wb + W_ATT + 1] = pitch_d
    wf[wb + W_ATT + 2] = yaw_d
    wf[wb + W_TQ] = tx
    wf[wb + W_TQ + 1] = ty
    wf[wb + W_TQ + 2] = tz
    wf[wb + W_THR] = thrust_n
    mix_one(thrust_n, tx, ty, tz, prm, P_AINV, prm[P_FMAX], prm[P_KF], prm[P_WMAX], wf, wb + W_U)
    return True


@njit(cache=True)
def _attitude_kernel(qv, rate, att_in, thrust_in, gains, prm, work):  # pragma: no cover - numba kernel
    gf = gains.reshape(-1)
    wf = work.reshape(-1)
    for v in range(qv.shape[0]):
        ok = _attitude_stage(qv, rate, v, att_in[v, 0], att_in[v, 1], att_in[v, 2], thrust_in[v], gf, prm, wf)
        wf[v * N_WORK + W_OK] = 1.0 if ok else 0.0


@njit(cache=True)
def _position_one(pos, vel, qv, rate, pos_sp, vel_sp, acc_ff, yaw_sp, m, v, gf, prm, wf):  # pragma: no cover
    """Steps 1-7 for vehicle v (rows of the (n, k) inputs; yaw_sp, m its scalars); False on non-finite input."""
    finite = math.isfinite(m) and m > 0.0 and math.isfinite(yaw_sp)
    for k in range(3):
        finite = finite and math.isfinite(pos[v, k] + vel[v, k] + pos_sp[v, k])
    if not finite:
        return False
    gb = v * 6 * N_GAIN_COLS
    wb = v * N_WORK
    w = 1.0 / prm[L_T_POS]
    i_max = prm[L_I_POS]
    acc_xy = prm[L_ACC_XY]
    u_z = max(prm[L_ACC_UP], prm[L_ACC_DOWN])
    e0 = pos_sp[v, 0] - pos[v, 0]
    e1 = pos_sp[v, 1] - pos[v, 1]
    e2 = pos_sp[v, 2] - pos[v, 2]
    de0 = _finite_or_zero(vel_sp[v, 0]) - vel[v, 0]
    de1 = _finite_or_zero(vel_sp[v, 1]) - vel[v, 1]
    de2 = _finite_or_zero(vel_sp[v, 2]) - vel[v, 2]
    a0 = _finite_or_zero(acc_ff[v, 0]) + _pid(0, e0, de0, w, acc_xy, i_max, gf, gb, prm, wf, wb)
    a1 = _finite_or_zero(acc_ff[v, 1]) + _pid(1, e1, de1, w, acc_xy, i_max, gf, gb, prm, wf, wb)
    a2 = _finite_or_zero(acc_ff[v, 2]) + _pid(2, e2, de2, w, u_z, i_max, gf, gb, prm, wf, wb)
    wf[wb + W_ERR] = e0
    wf[wb + W_ERR + 1] = e1
    wf[wb + W_ERR + 2] = e2
    a2 = min(max(a2, -prm[L_ACC_UP]), prm[L_ACC_DOWN])
    h = math.sqrt(a0 * a0 + a1 * a1)
    if h > acc_xy:
        a0 *= acc_xy / h
        a1 *= acc_xy / h
    fx, fy, fz = a0, a1, a2 - GRAVITY_M_S2  # specific force wanted, NED; fz < 0
    h = math.sqrt(fx * fx + fy * fy)
    h_max = -fz * prm[P_TAN_TILT]
    if h > h_max:
        fx *= h_max / h
        fy *= h_max / h
    fn = math.sqrt(fx * fx + fy * fy + fz * fz)
    wf[wb + W_ACC] = fx
    wf[wb + W_ACC + 1] = fy
    wf[wb + W_ACC + 2] = fz + GRAVITY_M_S2
    zx, zy, zz = -fx / fn, -fy / fn, -fz / fn  # desired body z (down) in NED
    sy, cy = math.sin(yaw_sp), math.cos(yaw_sp)
    # x_B = y_C × z_B with y_C = (−sin ψ, cos ψ, 0)
    xx, xy, xz = cy * zz, sy * zz, -sy * zy - cy * zx
    xn = math.sqrt(xx * xx + xy * xy + xz * xz)
    xx, xy, xz = xx / xn, xy / xn, xz / xn
    # y_B = z_B × x_B; roll = atan2(R21, R22), pitch = −asin(R20)
    yz = zx * xy - zy * xx
    roll_d = math.atan2(yz, zz)
    pitch_d = -math.asin(min(max(xz, -1.0), 1.0))
    return _attitude_stage(qv, rate, v, roll_d, pitch_d, yaw_sp, m * fn, gf, prm, wf)


@njit(cache=True)
def _position_kernel(pos, vel, qv, rate, pos_sp, vel_sp, acc_ff, yaw_sp, gains, mass, prm, work):  # pragma: no cover
    gf = gains.reshape(-1)
    wf = work.reshape(-1)
    for v in range(pos.shape[0]):
        ok = _position_one(pos, vel, qv, rate, pos_sp, vel_sp, acc_ff, yaw_sp[v], mass[v], v, gf, prm, wf)
        wf[v * N_WORK + W_OK] = 1.0 if ok else 0.0


@njit(cache=True)
def _position_single(pos, vel, q4, rate3, pos_sp, vel_sp, acc_ff, yaw_sp, gains, mass, prm, work):  # pragma: no cover
    """n = 1 entry with 1-D inputs (viewed as one-row batches here, not in Python); the same per-vehicle code."""
    ok = _position_one(
        pos.reshape((1, 3)),
        vel.reshape((1, 3)),
        q4.reshape((1, 4)),
        rate3.reshape((1, 3)),
        pos_sp.reshape((1, 3)),
        vel_sp.reshape((1, 3)),
        acc_ff.reshape((1, 3)),
        yaw_sp,
        mass[0],
        0,
        gains.reshape(-1),
        prm,
        work.reshape(-1),
    )
    work[0, W_OK] = 1.0 if ok else 0.0


# n = 1: gains, mass, parameters, work row and the input rows are views of one flat buffer (one array argument
# is cheaper for numba's dispatcher than five): offsets of each in it
B_GAINS = 0
B_MASS = B_GAINS + 6 * N_GAIN_COLS
B_PRM = B_MASS + 1
B_WORK = B_PRM + N_PARAMS
B_ONE = B_WORK + N_WORK
N_BUF = B_ONE + 28


@njit(cache=True)
def _position_flat(buf, pos, vel, q4, rate3, pos_sp, vel_sp, acc_ff, yaw_sp):  # pragma: no cover - numba kernel
    """n = 1 entry on tuples (numba unboxes them faster than arrays are filled from Python), copied into the
    (7, 4) input rows of the flat buffer (``B_*`` offsets); the same per-vehicle code. Returns
    ``(u0, u1, u2, u3, thrust_n, e_n, e_e, e_d, e_roll, e_pitch)``."""
    one = buf[B_ONE:N_BUF].reshape((7, 4))
    for k in range(3):
        one[0, k] = pos[k]
        one[1, k] = vel[k]
        one[3, k] = rate3[k]
        one[4, k] = pos_sp[k]
        one[5, k] = vel_sp[k]
        one[6, k] = acc_ff[k]
    for k in range(4):
        one[2, k] = q4[k]
    wf = buf[B_WORK:B_ONE]
    ok = _position_one(
        one[0:1, 0:3],
        one[1:2, 0:3],
        one[2:3, 0:4],
        one[3:4, 0:3],
        one[4:5, 0:3],
        one[5:6, 0:3],
        one[6:7, 0:3],
        yaw_sp,
        buf[B_MASS],
        0,
        buf[B_GAINS:B_MASS],
        buf[B_PRM:B_WORK],
        wf,
    )
    wf[W_OK] = 1.0 if ok else 0.0
    return (
        wf[W_U],
        wf[W_U + 1],
        wf[W_U + 2],
        wf[W_U + 3],
        wf[W_THR],
        wf[W_ERR],
        wf[W_ERR + 1],
        wf[W_ERR + 2],
        wf[W_ERR + 3],
        wf[W_ERR + 4],
    )


#: What :meth:`CascadeController.update_position_single` returns:
#: ``(u0, u1, u2, u3, thrust_n, e_n_m, e_e_m, e_d_m, e_roll_rad, e_pitch_rad)``.
SingleStep = tuple[float, float, float, float, float, float, float, float, float, float]
