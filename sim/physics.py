"""6-DOF quadrotor rigid-body dynamics and the fixed-step RK4 kernel shared by every stepper (SPEC §5).

State of one vehicle, ``x`` (17,): ``pos_ned`` [0:3] (m), ``vel_ned`` [3:6] (m/s), ``q_ned_frd`` [6:10]
(Hamilton, w first, body → NED), ``rate_frd`` [10:13] (rad/s), rotor speeds ``omega`` [13:17] (rad/s).

Equations (m = airframe + payload; payload is a point mass at the centre of gravity, so the inertia J
does not change with it):

* ``ṗ = v``
* ``m v̇ = R(q) (F_drag − T e_z) + m g e_z + F_ground``          (thrust along body −z, NED gravity +z)
* ``q̇ = ½ q ⊗ (0, ω)``                                          (renormalised after each step)
* ``J ω̇ = τ − ω × J ω``                                          (Euler; ``ω̇ = 0`` while the gear holds it)
* ``Ω̇_j = (Ω_cmd,j − Ω_j) / τ_m``                               (motor lag, :mod:`sim.motors`)

with rotor wrench from :mod:`sim.motors`, drag from :mod:`sim.aerodynamics`, wind from
:mod:`sim.wind` and ground reaction from :mod:`sim.ground`. The accelerometer truth is the specific
force ``f = (F_drag − T e_z + Rᵀ F_ground) / m`` (FRD): −g e_z at rest on level ground, 0 in free fall.

:func:`step_vehicles` is the only integrator: :class:`sim.batch.BatchSim` calls it for N vehicles and
:class:`sim.vehicle.VehicleSim` for one, so both run the same code.

Numba notes: kernels use ``error_model="numpy"`` (no per-division Python checks) and the per-effect
helpers are inlined. The on-disk cache (``cache=True``) is keyed on each function's own file only:
after editing a helper module (motors, aerodynamics, ground, wind, world), delete ``sim/__pycache__``
so that this module recompiles. A cold compile takes ~20 s once per checkout.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from mavlink_bridge.contract.frames import GRAVITY_M_S2
from sim.aerodynamics import drag_force_frd
from sim.ground import ground_reaction_ned, resolve_touchdown
from sim.motors import motor_lag_rate, omega_command_rad_s, rotor_wrench_frd
from sim.wind import gust_step
from sim.world import min_obstacle_distance_m

N_STATE = 17
POS, VEL, QUAT, RATE, OMEGA = 0, 3, 6, 10, 13

# Packed vehicle parameters (``vp``): index constants
P_MASS_KG = 0
P_JX, P_JY, P_JZ = 1, 2, 3
P_KF, P_KM = 4, 5
P_OMEGA_MAX, P_OMEGA_MIN, P_TAU_MOTOR = 6, 7, 8
P_DRAG_X, P_DRAG_Y, P_DRAG_Z, P_ROTOR_DRAG = 9, 10, 11, 12
P_MU, P_IMPACT_SPEED, P_COLLISION_RADIUS = 13, 14, 15
N_PARAMS = 16

# End reasons as plain ints for the kernel (mirror of sim.end_reason.EndReason)
_RUNNING, _COLLISION, _GROUND_IMPACT, _NONFINITE = 0, 3, 4, 6

# Scratch rows used by the kernel (one (N_SCRATCH, N_STATE) array, preallocated by the caller)
_K1, _K2, _K3, _K4, _XT, _XPREV, _OMEGA_CMD, _SF, _SF_STAGE, _SF_SUM = 0, 1, 2, 3, 4, 5, 6, 7, 8, 9
N_SCRATCH = 10

_G = GRAVITY_M_S2


@njit(cache=True, error_model="numpy", inline="always")
def derivative(
    x: np.ndarray,
    omega_cmd: np.ndarray,
    mass_kg: float,
    vp: np.ndarray,
    rotor_xy: np.ndarray,
    rotor_dir: np.ndarray,
    wind_x: float,
    wind_y: float,
    wind_z: float,
    in_contact: bool,
    dt: float,
    xdot: np.ndarray,
    sf_frd: np.ndarray,
) -> float:
    """Fill ``xdot`` = dx/dt and ``sf_frd`` = specific force (m/s², FRD); return the ground normal force (N)."""
    qw, qx, qy, qz = x[6], x[7], x[8], x[9]
    inv = 1.0 / math.sqrt(qw * qw + qx * qx + qy * qy + qz * qz)
    w, a, b, c = qw * inv, qx * inv, qy * inv, qz * inv
    # R = R_ned_frd (frames.dcm_from_quat)
    r00 = 1.0 - 2.0 * (b * b + c * c)
    r01 = 2.0 * (a * b - w * c)
    r02 = 2.0 * (a * c + w * b)
    r10 = 2.0 * (a * b + w * c)
    r11 = 1.0 - 2.0 * (a * a + c * c)
    r12 = 2.0 * (b * c - w * a)
    r20 = 2.0 * (a * c - w * b)
    r21 = 2.0 * (b * c + w * a)
    r22 = 1.0 - 2.0 * (a * a + b * b)

    vn, ve, vd = x[3], x[4], x[5]
    an, ae, ad = vn - wind_x, ve - wind_y, vd - wind_z  # air-relative, NED
    ax = r00 * an + r10 * ae + r20 * ad  # Rᵀ v_air
    ay = r01 * an + r11 * ae + r21 * ad
    az = r02 * an + r12 * ae + r22 * ad

    omega = x[13:17]
    thrust, tau_x, tau_y, tau_z = rotor_wrench_frd(omega, rotor_xy, rotor_dir, vp[P_KF], vp[P_KM])
    dx_, dy_, dz_ = drag_force_frd(ax, ay, az, vp[P_DRAG_X], vp[P_DRAG_Y], vp[P_DRAG_Z], vp[P_ROTOR_DRAG])
    fbx, fby, fbz = dx_, dy_, dz_ - thrust  # body-frame aerodynamic + rotor force, FRD

    fn = r00 * fbx + r01 * fby + r02 * fbz
    fe = r10 * fbx + r11 * fby + r12 * fbz
    fd = r20 * fbx + r21 * fby + r22 * fbz + mass_kg * _G
    gx, gy, gz, normal = ground_reaction_ned(in_contact, fn, fe, fd, vn, ve, mass_kg, vp[P_MU], dt)

    inv_m = 1.0 / mass_kg
    xdot[0] = vn
    xdot[1] = ve
    xdot[2] = vd
    xdot[3] = (fn + gx) * inv_m
    xdot[4] = (fe + gy) * inv_m
    xdot[5] = (fd + gz) * inv_m
    sf_frd[0] = (fbx + r00 * gx + r10 * gy + r20 * gz) * inv_m
    sf_frd[1] = (fby + r01 * gx + r11 * gy + r21 * gz) * inv_m
    sf_frd[2] = (fbz + r02 * gx + r12 * gy + r22 * gz) * inv_m

    p, q, r = x[10], x[11], x[12]
    xdot[6] = 0.5 * (-qx * p - qy * q - qz * r)
    xdot[7] = 0.5 * (qw * p + qy * r - qz * q)
    xdot[8] = 0.5 * (qw * q - qx * r + qz * p)
    xdot[9] = 0.5 * (qw * r + qx * q - qy * p)

    if normal > 0.0:  # the landing gear reacts every torque
        xdot[10] = 0.0
        xdot[11] = 0.0
        xdot[12] = 0.0
    else:
        jx, jy, jz = vp[P_JX], vp[P_JY], vp[P_JZ]
        xdot[10] = (tau_x - (q * jz * r - r * jy * q)) / jx
        xdot[11] = (tau_y - (r * jx * p - p * jz * r)) / jy
        xdot[12] = (tau_z - (p * jy * q - q * jx * p)) / jz

    tau_m = vp[P_TAU_MOTOR]
    for j in range(4):
        xdot[13 + j] = motor_lag_rate(x[13 + j], omega_cmd[j], tau_m)
    return normal


@njit(cache=True, error_model="numpy")
def rk4_step(
    x: np.ndarray,
    omega_cmd: np.ndarray,
    mass_kg: float,
    vp: np.ndarray,
    rotor_xy: np.ndarray,
    rotor_dir: np.ndarray,
    wind_x: float,
    wind_y: float,
    wind_z: float,
    in_contact: bool,
    dt: float,
    scratch: np.ndarray,
) -> float:
    """One classical RK4 step of ``x`` in place (quaternion renormalised); returns the initial normal force and
    leaves the specific force at the start of the step in ``scratch[_SF]``."""
    k1, k2, k3, k4, xt, sf = scratch[_K1], scratch[_K2], scratch[_K3], scratch[_K4], scratch[_XT], scratch[_SF]
    sf_stage = scratch[_SF_STAGE]
    normal = derivative(x, omega_cmd, mass_kg, vp, rotor_xy, rotor_dir, wind_x, wind_y, wind_z, in_contact, dt, k1, sf)
    h = 0.5 * dt
    for s in range(N_STATE):
        xt[s] = x[s] + h * k1[s]
    derivative(xt, omega_cmd, mass_kg, vp, rotor_xy, rotor_dir, wind_x, wind_y, wind_z, in_contact, dt, k2, sf_stage)
    for s in range(N_STATE):
        xt[s] = x[s] + h * k2[s]
    derivative(xt, omega_cmd, mass_kg, vp, rotor_xy, rotor_dir, wind_x, wind_y, wind_z, in_contact, dt, k3, sf_stage)
    for s in range(N_STATE):
        xt[s] = x[s] + dt * k3[s]
    derivative(xt, omega_cmd, mass_kg, vp, rotor_xy, rotor_dir, wind_x, wind_y, wind_z, in_contact, dt, k4, sf_stage)
    d6 = dt / 6.0
    for s in range(N_STATE):
        x[s] += d6 * (k1[s] + 2.0 * k2[s] + 2.0 * k3[s] + k4[s])
    n = math.sqrt(x[6] * x[6] + x[7] * x[7] + x[8] * x[8] + x[9] * x[9])
    for s in range(6, 10):
        x[s] /= n
    return normal


@njit(cache=True, error_model="numpy", inline="always")
def _add_impulse(x: np.ndarray, dv_n: float, dv_e: float, dv_d: float, inv_dt: float, sf_sum: np.ndarray) -> None:
    """Add a contact's velocity change ``dv`` (NED, m/s, over one physics step) to the specific-force sum, FRD:
    ``Rᵀ dv / dt`` (what an accelerometer feels of a touchdown or of friction stopping a slide)."""
    if dv_n == 0.0 and dv_e == 0.0 and dv_d == 0.0:
        return
    w, a, b, c = x[6], x[7], x[8], x[9]
    an, ae, ad = dv_n * inv_dt, dv_e * inv_dt, dv_d * inv_dt
    sf_sum[0] += (1.0 - 2.0 * (b * b + c * c)) * an + 2.0 * (a * b + w * c) * ae + 2.0 * (a * c - w * b) * ad
    sf_sum[1] += 2.0 * (a * b - w * c) * an + (1.0 - 2.0 * (a * a + c * c)) * ae + 2.0 * (b * c + w * a) * ad
    sf_sum[2] += 2.0 * (a * c + w * b) * an + 2.0 * (b * c - w * a) * ae + (1.0 - 2.0 * (a * a + b * b)) * ad


@njit(cache=True, error_model="numpy")
def _all_finite(x: np.ndarray) -> bool:
    for s in range(x.shape[0]):  # noqa: SIM110 (numba: an explicit loop, no generator)
        if not math.isfinite(x[s]):
            return False
    return True


@njit(cache=True, error_model="numpy")
def step_vehicles(
    state: np.ndarray,
    motor_cmd: np.ndarray,
    payload_kg: np.ndarray,
    vp: np.ndarray,
    rotor_xy: np.ndarray,
    rotor_dir: np.ndarray,
    wind_mean_ned: np.ndarray,
    gust_ned: np.ndarray,
    gust_sigma_m_s: float,
    gust_decay: float,
    rng_state: np.ndarray,
    end_reason: np.ndarray,
    on_ground: np.ndarray,
    min_clearance_m: np.ndarray,
    specific_force_frd: np.ndarray,
    obstacle_kinds: np.ndarray,
    obstacle_params: np.ndarray,
    dt: float,
    substeps: int,
    scratch: np.ndarray,
) -> None:
    """Advance every running vehicle by ``substeps`` RK4 steps of ``dt`` under constant motor commands.

    Per physics step: gusts advance (OU), the contact flag is taken from the start state
    (``z ≥ 0`` and ``v_z ≥ 0``), RK4 integrates, touchdown is resolved, and the run ends on a
    non-finite state (the last finite state is kept), a ground impact or an obstacle penetration
    (centre closer than the collision radius). Ended vehicles are skipped (frozen).
    """
    omega_cmd = scratch[_OMEGA_CMD]
    xprev = scratch[_XPREV]
    sf = scratch[_SF]
    sf_sum = scratch[_SF_SUM]
    for i in range(state.shape[0]):
        if end_reason[i] != _RUNNING:
            continue
        x = state[i]
        mass = vp[P_MASS_KG] + payload_kg[i]
        for j in range(4):
            omega_cmd[j] = omega_command_rad_s(motor_cmd[i, j], vp[P_OMEGA_MIN], vp[P_OMEGA_MAX])
        loaded = False
        sf_sum[0] = sf_sum[1] = sf_sum[2] = 0.0
        steps_done = 0
        for _ in range(substeps):
            gust_step(gust_ned, rng_state, i, gust_sigma_m_s, gust_decay)
            wx = wind_mean_ned[0] + gust_ned[i, 0]
            wy = wind_mean_ned[1] + gust_ned[i, 1]
            wz = wind_mean_ned[2] + gust_ned[i, 2]
            for s in range(N_STATE):
                xprev[s] = x[s]
            contact = x[2] >= 0.0 and x[5] >= 0.0
            normal = rk4_step(x, omega_cmd, mass, vp, rotor_xy, rotor_dir, wx, wy, wz, contact, dt, scratch)
            loaded = normal > 0.0
            if not _all_finite(x):
                for s in range(N_STATE):
                    x[s] = xprev[s]
                end_reason[i] = _NONFINITE
                break
            for k in range(3):
                sf_sum[k] += sf[k]
            steps_done += 1
            vn, ve, vd = x[3], x[4], x[5]
            if resolve_touchdown(x, loaded, vp[P_IMPACT_SPEED], xprev[3], xprev[4]):
                end_reason[i] = _GROUND_IMPACT
                break
            _add_impulse(x, x[3] - vn, x[4] - ve, x[5] - vd, 1.0 / dt, sf_sum)
            if obstacle_kinds.shape[0] > 0:
                d = min_obstacle_distance_m(obstacle_kinds, obstacle_params, x[0], x[1], x[2])
                if d < min_clearance_m[i]:
                    min_clearance_m[i] = d
                if d < vp[P_COLLISION_RADIUS]:
                    end_reason[i] = _COLLISION
                    break
        # contact at the end state (wind of the last physics step)
        contact = x[2] >= 0.0 and x[5] >= 0.0
        wx = wind_mean_ned[0] + gust_ned[i, 0]
        wy = wind_mean_ned[1] + gust_ned[i, 1]
        wz = wind_mean_ned[2] + gust_ned[i, 2]
        normal = derivative(x, omega_cmd, mass, vp, rotor_xy, rotor_dir, wx, wy, wz, contact, dt, scratch[_K1], sf)
        on_ground[i] = contact and (normal > 0.0 or loaded)
        # accelerometer truth: the mean specific force over the control step (an IMU integrates: a delta velocity
        # over the period), contact impulses included; a run that ended keeps the end state's
        if steps_done == substeps:
            for k in range(3):
                specific_force_frd[i, k] = sf_sum[k] / substeps
        else:
            for k in range(3):
                specific_force_frd[i, k] = sf[k]
