"""Ground contact at z = 0 (NED, down positive; the ground is z ≥ 0) (SPEC §5).

A vehicle is *in contact* when it starts a physics step with ``z ≥ 0`` and ``v_z ≥ 0``. In contact the
ground pushes back with a normal force ``N = max(0, F_z)`` (``F`` the net NED force on the vehicle), so
it never sinks and, since the reaction is never larger than the load, never launches. While loaded
(``N > 0``) the gear holds the attitude (torques are reacted) and Coulomb friction ``μN`` acts on the
horizontal motion (static when at rest). When thrust exceeds the load, ``N = 0``: the vehicle lifts off
with a continuous acceleration. A step that ends below the surface is a touchdown: perfectly inelastic
(no bounce), and a vertical speed above the vehicle's limit is a ground impact.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

_REST_SPEED_M_S = 1e-9
_STOPPED_M_S = 1e-6  # a slide slower than this after a step has stopped (friction decays it geometrically)


@njit(cache=True, error_model="numpy", inline="always")
def ground_reaction_ned(
    in_contact: bool,
    f_x: float,
    f_y: float,
    f_z: float,
    vel_x: float,
    vel_y: float,
    mass_kg: float,
    mu: float,
    dt: float,
) -> tuple[float, float, float, float]:
    """Ground reaction force (N, NED) for a net force ``f`` on a vehicle moving at ``vel`` (horizontal).

    Returns ``(r_x, r_y, r_z, N)``: the normal force ``N = max(0, f_z)`` pushes up (``r_z = −N``). Coulomb
    friction is the horizontal force that would bring the vehicle to rest within one physics step ``dt``,
    ``−(f_h + m v / dt)``, capped at ``μN``: at rest it cancels any horizontal force up to ``μN`` (static);
    while sliding fast it is ``μN`` against the motion (kinetic; ``m v / dt`` dominates ``f_h``). Continuous
    in ``v``, so RK4 does not chatter across the stop.
    """
    if not in_contact or f_z <= 0.0:
        return 0.0, 0.0, 0.0, 0.0
    normal = f_z
    limit = mu * normal
    stop = mass_kg / dt
    need_x = f_x + stop * vel_x
    need_y = f_y + stop * vel_y
    need = math.sqrt(need_x * need_x + need_y * need_y)
    if need <= limit:
        return -need_x, -need_y, -normal, normal
    return -limit * need_x / need, -limit * need_y / need, -normal, normal


@njit(cache=True, error_model="numpy", inline="always")
def resolve_touchdown(
    x: np.ndarray, was_loaded: bool, impact_speed_m_s: float, vel_n_before: float, vel_e_before: float
) -> bool:
    """Enforce ``z ≤ 0`` after a physics step on state ``x`` (in place). Returns True on a ground impact.

    A step ending below ground puts the vehicle on the surface with ``v_z = 0`` (inelastic) unless it
    arrived faster than ``impact_speed_m_s``. A loaded vehicle (``was_loaded``) has its body rates
    zeroed (gear holds it); if it was sliding (horizontal velocity ``vel_*_before`` at the start of the
    step) and friction reversed its horizontal velocity or brought it below ``_STOPPED_M_S``, it stopped:
    the velocity is zero (from rest, the static limit decides the next step).
    """
    if x[2] < 0.0:
        return False
    if x[5] > impact_speed_m_s:
        x[2] = 0.0
        return True
    x[2] = 0.0
    if x[5] > 0.0:
        x[5] = 0.0
    if was_loaded:
        x[10] = 0.0
        x[11] = 0.0
        x[12] = 0.0
        sliding = vel_n_before * vel_n_before + vel_e_before * vel_e_before > _REST_SPEED_M_S * _REST_SPEED_M_S
        reversed_ = x[3] * vel_n_before + x[4] * vel_e_before <= 0.0
        if sliding and (reversed_ or x[3] * x[3] + x[4] * x[4] < _STOPPED_M_S * _STOPPED_M_S):
            x[3] = 0.0
            x[4] = 0.0
    return False
