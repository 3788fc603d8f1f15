"""Rotors and motors: command → speed setpoint, first-order lag, thrust and torque (SPEC §5).

Numba kernels on scalars (no allocation); composed by :mod:`sim.physics`.
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True, error_model="numpy", inline="always")
def omega_command_rad_s(u: float, omega_min_rad_s: float, omega_max_rad_s: float) -> float:
    """Commanded rotor speed: ``ω_cmd = clamp(u·ω_max, ω_min, ω_max)`` for ``u > 0``, else 0 (spin down).

    A non-finite command counts as 0 (motor off): the simulator never propagates NaN into the state.
    """
    if not u > 0.0:  # also catches NaN
        return 0.0
    w = u * omega_max_rad_s
    if w < omega_min_rad_s:
        return omega_min_rad_s
    if w > omega_max_rad_s:
        return omega_max_rad_s
    return w


@njit(cache=True, error_model="numpy", inline="always")
def motor_lag_rate(omega_rad_s: float, omega_cmd_rad_s: float, time_constant_s: float) -> float:
    """First-order motor lag ``dω/dt = (ω_cmd − ω) / τ``."""
    return (omega_cmd_rad_s - omega_rad_s) / time_constant_s


@njit(cache=True, error_model="numpy", inline="always")
def rotor_wrench_frd(
    omega_rad_s: np.ndarray, rotor_xy_m: np.ndarray, rotor_yaw_dir: np.ndarray, k_f: float, k_m: float
) -> tuple[float, float, float, float]:
    """Total thrust and body torque of the four rotors, body FRD.

    Rotor j at ``(x_j, y_j, 0)`` produces ``T_j = k_f ω_j²`` along −z, so ``r × F`` gives
    ``τ_x = −Σ y_j T_j`` (roll), ``τ_y = Σ x_j T_j`` (pitch); the reaction torque is
    ``τ_z = Σ d_j k_m ω_j²`` with ``d_j = +1`` for a CCW rotor. Returns ``(T, τ_x, τ_y, τ_z)``.
    """
    thrust = 0.0
    tau_x = 0.0
    tau_y = 0.0
    tau_z = 0.0
    for j in range(4):
        w2 = omega_rad_s[j] * omega_rad_s[j]
        t_j = k_f * w2
        thrust += t_j
        tau_x -= rotor_xy_m[j, 1] * t_j
        tau_y += rotor_xy_m[j, 0] * t_j
        tau_z += rotor_yaw_dir[j] * k_m * w2
    return thrust, tau_x, tau_y, tau_z
