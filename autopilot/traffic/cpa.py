"""Closest point of approach and loss of separation for straight-line relative motion (SPEC §13).

Relative motion of a track about the own vehicle: ``r(t) = r0 + v·t`` (NED, m; ``v`` = track velocity − own
velocity). Separation is a vertical cylinder (:class:`SeparationVolume`): it is lost while the horizontal distance
is below the radius AND the vertical distance below the half-height, so the loss interval is the intersection of
the horizontal one (``|r_h + v_h t| < H``, a quadratic in t) and the vertical one (``|r_z + v_z t| < V``, linear),
clipped to the look-ahead horizon. The *separation ratio* ``max(d_h/H, |d_v|/V)`` is >= 1 exactly when separated.

With ``column`` the track's volume reaches down to the ground (a hovering or landing UAV's landing column,
:func:`autopilot.traffic.rules.owns_column`): below the track only the horizontal distance separates, so the
vertical distance counts only when the vehicle is above the track (``d_v = max(r_z, 0)``, NED down).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from autopilot.traffic.param_decls import SeparationVolume
from mavlink_bridge.contract.frames import Vec3

_EPS = 1e-9


@dataclass(frozen=True, slots=True)
class Approach:
    """The predicted encounter with one track over the horizon."""

    t_cpa_s: float  # time of the closest horizontal approach, clipped to [0, horizon]
    hor_cpa_m: float  # horizontal distance then
    ver_cpa_m: float  # vertical distance then (track below own > 0, NED down)
    loss_in_s: float  # first time inside the separation volume (nan: never within the horizon)
    loss_out_s: float  # time it leaves the volume again (clipped to the horizon; nan: never)

    @property
    def conflict(self) -> bool:
        return not math.isnan(self.loss_in_s)


def separation_ratio(rel_ned_m: Vec3, volume: SeparationVolume, column: bool = False) -> float:
    """``max(d_h/H, |d_v|/V)``: >= 1 when separated (either distance outside the volume); ``column``: the track's
    volume reaches down to the ground (``d_v`` counts only above the track)."""
    dv = max(rel_ned_m[2], 0.0) if column else abs(rel_ned_m[2])
    return max(math.hypot(rel_ned_m[0], rel_ned_m[1]) / volume.hor_m, dv / volume.ver_m)


def _horizontal_interval(rn: float, re: float, vn: float, ve: float, radius: float) -> tuple[float, float] | None:
    a = vn * vn + ve * ve
    c = rn * rn + re * re - radius * radius
    if a < _EPS:
        return (-math.inf, math.inf) if c < 0.0 else None
    b = 2.0 * (rn * vn + re * ve)
    disc = b * b - 4.0 * a * c
    if disc <= 0.0:
        return None
    s = math.sqrt(disc)
    return ((-b - s) / (2.0 * a), (-b + s) / (2.0 * a))


def _vertical_interval(rz: float, vz: float, half_height: float, column: bool) -> tuple[float, float] | None:
    if column:  # inside while the vehicle is less than half_height above the track: r_z + v_z t < half_height
        if abs(vz) < _EPS:
            return (-math.inf, math.inf) if rz < half_height else None
        t = (half_height - rz) / vz
        return (-math.inf, t) if vz > 0.0 else (t, math.inf)
    if abs(vz) < _EPS:
        return (-math.inf, math.inf) if abs(rz) < half_height else None
    t1, t2 = (-half_height - rz) / vz, (half_height - rz) / vz
    return (min(t1, t2), max(t1, t2))


def predict_approach(
    rel_pos_ned_m: Vec3, rel_vel_ned_m_s: Vec3, horizon_s: float, volume: SeparationVolume, column: bool = False
) -> Approach:
    """CPA and loss-of-separation interval of the straight relative motion within ``[0, horizon_s]`` (``column``:
    the track's volume reaches down to the ground)."""
    rn, re, rz = rel_pos_ned_m
    vn, ve, vz = rel_vel_ned_m_s
    a = vn * vn + ve * ve
    t_cpa = 0.0 if a < _EPS else min(max(-(rn * vn + re * ve) / a, 0.0), horizon_s)
    hor = math.hypot(rn + vn * t_cpa, re + ve * t_cpa)
    ver = rz + vz * t_cpa
    h = _horizontal_interval(rn, re, vn, ve, volume.hor_m)
    v = _vertical_interval(rz, vz, volume.ver_m, column)
    t_in = t_out = math.nan
    if h is not None and v is not None:
        lo, hi = max(h[0], v[0], 0.0), min(h[1], v[1], horizon_s)
        if lo < hi:
            t_in, t_out = lo, hi
    return Approach(t_cpa, hor, ver, t_in, t_out)
