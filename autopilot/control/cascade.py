"""The NLVG-PID cascade (SPEC §6.2, paper eq. 11): position → acceleration → attitude → torques → mixer.

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
from collections.abc import Callable
from dataclasses import dataclass
from functools import partial

import numpy as np
from numba import njit

from autopilot.control.airframe import Airframe
from autopilot.control.gains import CascadeGains, CascadeLimits
from autopilot.control.mixer import QuadXMixer, mix_one
from autopilot.control.pid import N_GAIN_COLS, N_STATE_COLS, nlvg_pid_step
from mavlink_bridge.contract.frames import GRAVITY_M_S2
from mavlink_bridge.contract.wire import fast_frozen_init

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


@dataclass(frozen=True)
class CascadeDiagnostics:
    """Live views of the last step (overwritten by the next update; copy to keep). Shapes with n vehicles.

    pos_err_ned (n,3) m; att_err_rad (n,3) roll/pitch/yaw; kp, ki, kd (n,6) live k(s) per channel in
    CHANNELS order; acc_sp_ned (n,3) m/s² after limits; att_sp_rad (n,3); torque_frd_nm (n,3);
    thrust_n (n,); motor_cmd (n,4); valid (n,) 1.0 where the last step ran, 0.0 where the NaN guard held.
    """

    pos_err_ned: np.ndarray
    att_err_rad: np.ndarray
    kp: np.ndarray
    ki: np.ndarray
    kd: np.ndarray
    acc_sp_ned: np.ndarray
    att_sp_rad: np.ndarray
    torque_frd_nm: np.ndarray
    thrust_n: np.ndarray
    motor_cmd: np.ndarray
    valid: np.ndarray


def _rows(x: object, n: int, k: int) -> np.ndarray:
    a = np.asarray(x, dtype=np.float64)
    if a.shape == (n, k):
        return a if a.flags.c_contiguous else np.ascontiguousarray(a)
    if n == 1 and a.shape == (k,):
        return a.reshape(1, k)
    return np.ascontiguousarray(np.broadcast_to(a, (n, k)))


def _row1(x: object, k: int) -> np.ndarray:
    a = np.asarray(x, dtype=np.float64)
    return a if a.shape == (k,) else np.ascontiguousarray(a.reshape(k))


def _vector(x: object, n: int) -> np.ndarray:
    a = np.asarray(x, dtype=np.float64)
    if a.shape == (n,):
        return a
    if a.ndim == 0:
        return np.full(n, float(a))
    return np.ascontiguousarray(np.broadcast_to(a, (n,)))


@fast_frozen_init
@dataclass(frozen=True, slots=True)
class ControlSample:
    """Vehicle 0's last cascade step, copied for listeners (:meth:`CascadeController.sample`).

    ``values`` holds, in order: attitude error (roll, pitch, yaw, rad), attitude setpoint (rad), the live k(s) of
    each channel in CHANNELS order for k_p, then k_i, then k_d (eqs. 4-9), collective thrust (N) and torque
    (FRD, N·m); the class constants slice it.
    """

    values: tuple[float, ...]

    ATT_ERR = slice(0, 3)
    ATT_SP = slice(3, 6)
    KP = slice(6, 12)
    KI = slice(12, 18)
    KD = slice(18, 24)
    THRUST = 24
    TORQUE = slice(25, 28)
    SIZE = 28


def _sample_index() -> np.ndarray:
    """Offsets into one vehicle's work row, in :class:`ControlSample` order."""
    kp = [W_K + 3 * c for c in range(6)]
    index = [*range(W_ERR + 3, W_ERR + 6), *range(W_ATT, W_ATT + 3), *kp, *(k + 1 for k in kp), *(k + 2 for k in kp)]
    index += [W_THR, *range(W_TQ, W_TQ + 3)]
    return np.asarray(index, dtype=np.intp)


_SAMPLE_INDEX = _sample_index()


class CascadeController:
    """NLVG-PID cascade for n vehicles of one airframe (n = 1: the single vehicle, same code).

    Inputs are NED/FRD arrays shaped (n, k) — or (k,) when n = 1; scalars broadcast to every vehicle.
    """

    def __init__(
        self,
        airframe: Airframe,
        gains: CascadeGains,
        n: int = 1,
        dt_s: float = 1.0 / 250.0,
        limits: CascadeLimits | None = None,
    ) -> None:
        if n < 1 or not (math.isfinite(dt_s) and dt_s > 0.0):
            raise ValueError(f"need n >= 1 and dt_s > 0, got n={n}, dt_s={dt_s}")
        self.airframe = airframe
        self.n = n
        self.dt_s = float(dt_s)
        self.limits = limits or CascadeLimits()
        mixer = QuadXMixer(airframe)
        prm = np.zeros(N_PARAMS)
        prm[:P_FMAX] = self.limits.as_array()
        prm[P_FMAX] = mixer.f_max_n
        prm[P_KF] = airframe.k_f
        prm[P_WMAX] = airframe.omega_max_rad_s
        prm[P_DT] = self.dt_s
        prm[P_IX : P_IZ + 1] = airframe.inertia_kg_m2
        prm[P_TAN_TILT] = math.tan(self.limits.tilt_max_rad)
        prm[P_AINV:] = mixer.a_inv.ravel()
        table = gains.table(n)
        if n == 1:  # one flat buffer, the arrays are views of it (_position_flat)
            buf = np.zeros(N_BUF)
            self._gains = buf[B_GAINS:B_MASS].reshape(table.shape)
            self._mass = buf[B_MASS:B_PRM]
            self._prm = buf[B_PRM:B_WORK]
            self._work = buf[B_WORK:B_ONE].reshape((1, N_WORK))
            self._one = buf[B_ONE:N_BUF].reshape((7, 4))  # update_position_single's inputs as rows
            self._gains[:] = table
            self._mass[:] = airframe.mass_kg
            self._prm[:] = prm
            #: ``update_single(pos, vel, q, rate, pos_sp, vel_sp, acc_ff, yaw_sp)``: :meth:`update_position_single`
            #: without its Python frame (the per-step call of one autopilot; n = 1 only).
            self.update_single: Callable[..., SingleStep] = partial(_position_flat, buf)
        else:
            self._prm = prm
            self._mass = np.full(n, airframe.mass_kg)
            self._work = np.zeros((n, N_WORK))
            self._one = np.zeros((7, 4))
            self._gains = table
        self.gains = gains
        wk = self._work
        self.diagnostics = CascadeDiagnostics(
            pos_err_ned=wk[:, W_ERR : W_ERR + 3],
            att_err_rad=wk[:, W_ERR + 3 : W_ERR + 6],
            kp=wk[:, W_K : W_K + 18 : 3],
            ki=wk[:, W_K + 1 : W_K + 18 : 3],
            kd=wk[:, W_K + 2 : W_K + 18 : 3],
            acc_sp_ned=wk[:, W_ACC : W_ACC + 3],
            att_sp_rad=wk[:, W_ATT : W_ATT + 3],
            torque_frd_nm=wk[:, W_TQ : W_TQ + 3],
            thrust_n=wk[:, W_THR],
            motor_cmd=wk[:, W_U : W_U + 4],
            valid=wk[:, W_OK],
        )

    def sample(self) -> ControlSample:
        """Vehicle 0's last step as a frozen message (one gather, one tuple)."""
        return ControlSample(tuple(self._work[0].take(_SAMPLE_INDEX).tolist()))

    def state_array(self) -> np.ndarray:
        """The controller's state (integrators, held outputs, last step), copied: :meth:`load_state` takes it."""
        return self._work.copy()

    def load_state(self, work: np.ndarray) -> None:
        """Continue from :meth:`state_array` of a cascade with the same n (bumpless rebuild after a limit change)."""
        self._work[:] = work

    @property
    def mass_kg(self) -> np.ndarray:
        """The mass (n,) the controller uses."""
        return self._mass.copy()

    def reset(self, mask: np.ndarray | None = None) -> None:
        """Clear integrators, held outputs and commands (all vehicles, or where ``mask`` is True)."""
        if mask is None:
            self._work[:] = 0.0
        else:
            self._work[np.asarray(mask, dtype=bool)] = 0.0

    def set_gains(self, gains: CascadeGains) -> None:
        """Change gains live (in flight); integrator states are kept (bumpless: I stores ∫k_i·e)."""
        self._gains[:] = gains.table(self.n)
        self.gains = gains

    def set_mass_kg(self, mass_kg: float | np.ndarray) -> None:
        """Mass used for thrust (e.g. after payload release); finite positive, scalar or (n,)."""
        m = np.broadcast_to(np.asarray(mass_kg, dtype=np.float64), (self.n,))
        if not np.all(np.isfinite(m) & (m > 0.0)):
            raise ValueError(f"mass_kg must be finite and positive, got {mass_kg!r}")
        self._mass[:] = m

    def update_position(
        self,
        pos_ned: np.ndarray,
        vel_ned: np.ndarray,
        q_ned_frd: np.ndarray,
        rate_frd: np.ndarray,
        pos_sp_ned: np.ndarray,
        vel_sp_ned: np.ndarray,
        acc_ff_ned: np.ndarray,
        yaw_sp_rad: float | np.ndarray,
    ) -> np.ndarray:
        """Full cascade step (SPEC §6.2); returns motor commands (n, 4) in [0, 1], PX4 quad-x order."""
        n = self.n
        pos = np.asarray(pos_ned, dtype=np.float64)
        if n == 1 and pos.shape == (3,):
            _position_single(
                pos,
                _row1(vel_ned, 3),
                _row1(q_ned_frd, 4),
                _row1(rate_frd, 3),
                _row1(pos_sp_ned, 3),
                _row1(vel_sp_ned, 3),
                _row1(acc_ff_ned, 3),
                yaw_sp_rad if type(yaw_sp_rad) is float else float(np.asarray(yaw_sp_rad, dtype=np.float64).flat[0]),
                self._gains,
                self._mass,
                self._prm,
                self._work,
            )
            return self._work[:, W_U : W_U + 4].copy()
        _position_kernel(
            _rows(pos, n, 3),
            _rows(vel_ned, n, 3),
            _rows(q_ned_frd, n, 4),
            _rows(rate_frd, n, 3),
            _rows(pos_sp_ned, n, 3),
            _rows(vel_sp_ned, n, 3),
            _rows(acc_ff_ned, n, 3),
            _vector(yaw_sp_rad, n),
            self._gains,
            self._mass,
            self._prm,
            self._work,
        )
        return self._work[:, W_U : W_U + 4].copy()

    def update_position_single(
        self,
        pos_ned: tuple[float, float, float],
        vel_ned: tuple[float, float, float],
        q_ned_frd: tuple[float, float, float, float],
        rate_frd: tuple[float, float, float],
        pos_sp_ned: tuple[float, float, float],
        vel_sp_ned: tuple[float, float, float],
        acc_ff_ned: tuple[float, float, float],
        yaw_sp_rad: float,
    ) -> SingleStep:
        """:meth:`update_position` for n = 1 on float tuples (the per-step path of one autopilot).

        Same kernel, same results bit for bit; returns the motor commands, the collective thrust (N)
        and the position and roll/pitch errors of this step (:data:`SingleStep`); :attr:`diagnostics` is
        updated as by :meth:`update_position`. Pass floats, not ints (each element type compiles anew).
        """
        if self.n != 1:
            raise ValueError(f"update_position_single needs n = 1, this cascade has n = {self.n}")
        return self.update_single(pos_ned, vel_ned, q_ned_frd, rate_frd, pos_sp_ned, vel_sp_ned, acc_ff_ned, yaw_sp_rad)

    def update_attitude(
        self,
        q_ned_frd: np.ndarray,
        rate_frd: np.ndarray,
        att_sp_rad: np.ndarray,
        thrust_n: float | np.ndarray,
    ) -> np.ndarray:
        """Attitude loop only (steps 5-7): roll/pitch/yaw setpoint (n, 3) rad and collective thrust (n,) N."""
        n = self.n
        _attitude_kernel(
            _rows(q_ned_frd, n, 4),
            _rows(rate_frd, n, 3),
            _rows(att_sp_rad, n, 3),
            _vector(thrust_n, n),
            self._gains,
            self._prm,
            self._work,
        )
        return self._work[:, W_U : W_U + 4].copy()

    def hover_thrust_n(self) -> np.ndarray:
        """m·g per vehicle (N), e.g. the collective for an attitude-only experiment."""
        return self._mass * GRAVITY_M_S2
