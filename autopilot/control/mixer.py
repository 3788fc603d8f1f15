"""Quad-X mixer: collective thrust and body torques → motor commands u ∈ [0, 1] (SPEC §6.2).

Allocation A (``Airframe.allocation_matrix``): [T, τx, τy, τz]ᵀ = A·f, f the four rotor thrusts; the
mixer uses f = A⁻¹·w split into a collective part (c·T), a roll/pitch part d and a yaw part y.
Rotor thrust f_i = k_f·ω_i² and ω_i = u_i·ω_max, so u_i = √(f_i/k_f)/ω_max (SPEC §3).

Saturation priority (each rotor thrust must stay in [0, f_max], f_max = k_f·ω_max²):
1. roll/pitch first: if no collective can fit d, d is scaled down (ratio kept) until one does;
2. thrust next: the collective is moved (up or down) just enough to fit the roll/pitch differential,
   so attitude authority is kept when the collective is near 0 or near full (airmode for roll/pitch);
3. yaw last: the yaw part gets the largest fraction in [0, 1] that still fits, without moving thrust.
Like PX4's desaturation with yaw reduced first. Non-finite inputs leave the previous command in place.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from autopilot.control.airframe import Airframe


@njit(cache=True, inline="always")
def mix_one(thrust_n, tx, ty, tz, a, ai, f_max, k_f, omega_max, u, ui):  # pragma: no cover - numba kernel
    """Write motor commands for one vehicle into ``u[ui:ui+4]``; A⁻¹ is ``a[ai:ai+16]`` row-major.

    Returns the roll/pitch scale in [0, 1] (0 and nothing written on a non-finite input).
    """
    if not (math.isfinite(thrust_n) and math.isfinite(tx) and math.isfinite(ty) and math.isfinite(tz)):
        return 0.0
    k = 1.0
    for i in range(4):
        ri = (a[ai + 4 * i + 1] * tx + a[ai + 4 * i + 2] * ty) / a[ai + 4 * i]
        for j in range(4):
            rj = (a[ai + 4 * j + 1] * tx + a[ai + 4 * j + 2] * ty) / a[ai + 4 * j]
            diff = rj - ri
            if diff > 0.0:
                k = min(k, f_max / (a[ai + 4 * j] * diff))
    t_lo = -1e300
    t_hi = 1e300
    for i in range(4):
        d = k * (a[ai + 4 * i + 1] * tx + a[ai + 4 * i + 2] * ty)
        t_lo = max(t_lo, -d / a[ai + 4 * i])
        t_hi = min(t_hi, (f_max - d) / a[ai + 4 * i])
    t = min(max(thrust_n, t_lo), t_hi)
    s = 1.0
    for i in range(4):
        f = t * a[ai + 4 * i] + k * (a[ai + 4 * i + 1] * tx + a[ai + 4 * i + 2] * ty)
        y = a[ai + 4 * i + 3] * tz
        if y > 0.0:
            s = min(s, (f_max - f) / y)
        elif y < 0.0:
            s = min(s, f / -y)
    s = max(s, 0.0)
    for i in range(4):
        f = t * a[ai + 4 * i] + k * (a[ai + 4 * i + 1] * tx + a[ai + 4 * i + 2] * ty) + s * a[ai + 4 * i + 3] * tz
        cmd = math.sqrt(max(f, 0.0) / k_f) / omega_max
        u[ui + i] = min(max(cmd, 0.0), 1.0)
    return k


@njit(cache=True)
def _mix_batch(thrust_n, torque_frd_nm, a_inv, f_max, k_f, omega_max, u_out):  # pragma: no cover - numba kernel
    a = a_inv.reshape(-1)
    uf = u_out.reshape(-1)
    for v in range(thrust_n.shape[0]):
        mix_one(
            thrust_n[v],
            torque_frd_nm[v, 0],
            torque_frd_nm[v, 1],
            torque_frd_nm[v, 2],
            a,
            0,
            f_max,
            k_f,
            omega_max,
            uf,
            4 * v,
        )


class QuadXMixer:
    """Mixer for one airframe geometry; ``mix`` serves one vehicle or a batch."""

    def __init__(self, airframe: Airframe) -> None:
        self.airframe = airframe
        self.allocation = airframe.allocation_matrix()
        self.a_inv = np.ascontiguousarray(np.linalg.inv(self.allocation))
        if np.any(self.a_inv[:, 0] <= 0.0):
            raise ValueError(f"airframe {airframe.name}: collective thrust does not load every rotor")
        self.f_max_n = airframe.max_rotor_thrust_n

    def mix(
        self, thrust_n: np.ndarray | float, torque_frd_nm: np.ndarray, u_prev: np.ndarray | None = None
    ) -> np.ndarray:
        """Motor commands (n, 4) in [0, 1]; rows with non-finite input keep ``u_prev`` (zeros if None)."""
        thrust = np.atleast_1d(np.asarray(thrust_n, dtype=np.float64))
        torque = np.atleast_2d(np.asarray(torque_frd_nm, dtype=np.float64))
        n = max(thrust.shape[0], torque.shape[0])
        thrust = np.ascontiguousarray(np.broadcast_to(thrust, (n,)))
        torque = np.ascontiguousarray(np.broadcast_to(torque, (n, 3)))
        u = np.zeros((n, 4)) if u_prev is None else np.array(np.broadcast_to(u_prev, (n, 4)), dtype=np.float64)
        af = self.airframe
        _mix_batch(thrust, torque, self.a_inv, self.f_max_n, af.k_f, af.omega_max_rad_s, u)
        return u

    def wrench(self, u: np.ndarray) -> np.ndarray:
        """[T, τx, τy, τz] (n, 4) the commands u would produce at steady rotor speed (for tests/diagnostics)."""
        f = self.airframe.k_f * (np.asarray(u, dtype=np.float64) * self.airframe.omega_max_rad_s) ** 2
        return f @ self.allocation.T
