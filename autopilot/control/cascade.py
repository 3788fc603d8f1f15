"""The NLVG-PID cascade controller (SPEC §6.2, paper eq. 11) for n vehicles: gains, limits, mass, state.

The per-step law is in :mod:`autopilot.control.cascade_kernel` (compiled); this class owns its packed
parameters, gains, mass and work state, and hands vehicle 0's step to listeners as a :class:`ControlSample`.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from functools import partial

import numpy as np

from autopilot.control.airframe import Airframe
from autopilot.control.cascade_kernel import (
    B_GAINS,
    B_MASS,
    B_ONE,
    B_PRM,
    B_WORK,
    N_BUF,
    N_PARAMS,
    N_WORK,
    P_AINV,
    P_DT,
    P_FMAX,
    P_IX,
    P_IZ,
    P_KF,
    P_TAN_TILT,
    P_WMAX,
    W_ACC,
    W_ATT,
    W_ERR,
    W_K,
    W_OK,
    W_THR,
    W_TQ,
    W_U,
    SingleStep,
    _attitude_kernel,
    _position_flat,
    _position_kernel,
    _position_single,
)
from autopilot.control.gains import CascadeGains, CascadeLimits
from autopilot.control.mixer import QuadXMixer
from mavlink_bridge.contract.frames import GRAVITY_M_S2
from mavlink_bridge.contract.wire import fast_frozen_init


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
