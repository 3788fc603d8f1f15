"""Aerodynamic drag on the air-relative velocity, body FRD (SPEC §5).

``F_i = −c_i v_i |v_i|`` per body axis (quadratic body drag) plus the rotors' linear induced drag
in the rotor plane ``F_xy = −c_r v_xy`` (blade flapping / induced drag, PX4 gz ``rotorDragCoefficient``
lumped at hover speed). ``v`` is the velocity relative to the air (vehicle minus wind) in FRD.
"""

from __future__ import annotations

from numba import njit


@njit(cache=True, error_model="numpy", inline="always")
def drag_force_frd(
    v_air_x: float,
    v_air_y: float,
    v_air_z: float,
    c_body_x: float,
    c_body_y: float,
    c_body_z: float,
    c_rotor: float,
) -> tuple[float, float, float]:
    """Body quadratic + rotor linear drag (N, FRD) for the air-relative velocity ``v_air`` (m/s, FRD)."""
    fx = -c_body_x * v_air_x * abs(v_air_x) - c_rotor * v_air_x
    fy = -c_body_y * v_air_y * abs(v_air_y) - c_rotor * v_air_y
    fz = -c_body_z * v_air_z * abs(v_air_z)
    return fx, fy, fz
