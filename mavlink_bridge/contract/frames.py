"""Frame conventions and the one place that converts between them.

Conventions (SPEC §3):
- World frame NED (x north, y east, z down), metres; body frame FRD.
- Quaternions are Hamilton, scalar first ``(w, x, y, z)``; ``q_ned_frd`` rotates a
  vector from body FRD into NED: ``v_ned = R(q_ned_frd) @ v_frd``.
- Euler angles are the aerospace ZYX sequence (yaw, then pitch, then roll), radians
  unless the name says ``_deg``.
- Geodetic positions are WGS-84 (degrees, metres AMSL); local NED is taken about a
  home point (``GeoPoint``). Only the edges (codec, mission files, GCS) convert.

Every function accepts a single vector or a batch with the component on the last
axis, so the same code serves one vehicle and N vehicles.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from mavlink_bridge.contract import geodetic

Vec3 = tuple[float, float, float]
#: Hamilton, w first.
Quat = tuple[float, float, float, float]

GRAVITY_M_S2 = 9.80665
DEG_E7 = 1e7


@dataclass(frozen=True, slots=True)
class GeoPoint:
    """A WGS-84 point: latitude and longitude in degrees, altitude in metres AMSL."""

    lat_deg: float
    lon_deg: float
    alt_amsl_m: float


def quat_normalize(q: np.ndarray) -> np.ndarray:
    """Unit quaternion(s) with a non-negative scalar part."""
    q = np.asarray(q, dtype=float)
    n = np.linalg.norm(q, axis=-1, keepdims=True)
    q = q / n
    return np.where(q[..., :1] < 0.0, -q, q)


def quat_multiply(p: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Hamilton product ``p ⊗ q`` (apply q first, then p when rotating vectors)."""
    p = np.asarray(p, dtype=float)
    q = np.asarray(q, dtype=float)
    pw, px, py, pz = np.moveaxis(p, -1, 0)
    qw, qx, qy, qz = np.moveaxis(q, -1, 0)
    return np.stack(
        (
            pw * qw - px * qx - py * qy - pz * qz,
            pw * qx + px * qw + py * qz - pz * qy,
            pw * qy - px * qz + py * qw + pz * qx,
            pw * qz + px * qy - py * qx + pz * qw,
        ),
        axis=-1,
    )


def quat_conjugate(q: np.ndarray) -> np.ndarray:
    """Inverse rotation of a unit quaternion."""
    q = np.asarray(q, dtype=float)
    return q * np.array([1.0, -1.0, -1.0, -1.0])


def dcm_from_quat(q_ned_frd: np.ndarray) -> np.ndarray:
    """Rotation matrix ``R_ned_frd`` (shape ``(..., 3, 3)``) from ``q_ned_frd``."""
    q = np.asarray(q_ned_frd, dtype=float)
    w, x, y, z = np.moveaxis(q, -1, 0)
    r = np.empty((*q.shape[:-1], 3, 3))
    r[..., 0, 0] = 1.0 - 2.0 * (y * y + z * z)
    r[..., 0, 1] = 2.0 * (x * y - w * z)
    r[..., 0, 2] = 2.0 * (x * z + w * y)
    r[..., 1, 0] = 2.0 * (x * y + w * z)
    r[..., 1, 1] = 1.0 - 2.0 * (x * x + z * z)
    r[..., 1, 2] = 2.0 * (y * z - w * x)
    r[..., 2, 0] = 2.0 * (x * z - w * y)
    r[..., 2, 1] = 2.0 * (y * z + w * x)
    r[..., 2, 2] = 1.0 - 2.0 * (x * x + y * y)
    return r


def rotate_frd_to_ned(q_ned_frd: np.ndarray, v_frd: np.ndarray) -> np.ndarray:
    """``v_ned = R(q_ned_frd) v_frd``."""
    return np.einsum("...ij,...j->...i", dcm_from_quat(q_ned_frd), v_frd)


def rotate_ned_to_frd(q_ned_frd: np.ndarray, v_ned: np.ndarray) -> np.ndarray:
    """``v_frd = R(q_ned_frd)^T v_ned``."""
    return np.einsum("...ji,...j->...i", dcm_from_quat(q_ned_frd), v_ned)


def quat_from_euler(
    roll_rad: float | np.ndarray, pitch_rad: float | np.ndarray, yaw_rad: float | np.ndarray
) -> np.ndarray:
    """``q_ned_frd`` from ZYX Euler angles (yaw about down, pitch, roll)."""
    cr, sr = np.cos(np.asarray(roll_rad) / 2), np.sin(np.asarray(roll_rad) / 2)
    cp, sp = np.cos(np.asarray(pitch_rad) / 2), np.sin(np.asarray(pitch_rad) / 2)
    cy, sy = np.cos(np.asarray(yaw_rad) / 2), np.sin(np.asarray(yaw_rad) / 2)
    return np.stack(
        (
            cr * cp * cy + sr * sp * sy,
            sr * cp * cy - cr * sp * sy,
            cr * sp * cy + sr * cp * sy,
            cr * cp * sy - sr * sp * cy,
        ),
        axis=-1,
    )


def euler_from_quat(q_ned_frd: np.ndarray) -> np.ndarray:
    """ZYX Euler angles ``(roll, pitch, yaw)`` in radians (last axis) from ``q_ned_frd``."""
    q = np.asarray(q_ned_frd, dtype=float)
    w, x, y, z = np.moveaxis(q, -1, 0)
    roll = np.arctan2(2.0 * (w * x + y * z), 1.0 - 2.0 * (x * x + y * y))
    pitch = np.arcsin(np.clip(2.0 * (w * y - z * x), -1.0, 1.0))
    yaw = np.arctan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))
    return np.stack((roll, pitch, yaw), axis=-1)


def ne_from_heading_frame(forward: float, right: float, yaw_rad: float) -> tuple[float, float]:
    """North and east of a horizontal vector given forward/right of heading ``yaw_rad`` (MAV_FRAME_BODY_NED's
    horizontal axes; scalar math, for per-step use)."""
    c, s = math.cos(yaw_rad), math.sin(yaw_rad)
    return c * forward - s * right, s * forward + c * right


def wrap_pi(angle_rad: float | np.ndarray) -> float | np.ndarray:
    """Wrap an angle to [-π, π)."""
    return (np.asarray(angle_rad) + np.pi) % (2.0 * np.pi) - np.pi


class LocalNedFrame:
    """Exact WGS-84 ↔ local NED about a home point (ECEF with a fixed tangent-plane rotation).

    The conversions are the compiled ones of :mod:`mavlink_bridge.contract.geodetic` (one implementation for
    this class, the simulator and the EKF); ``test_frames.py`` checks them against pymap3d.
    """

    __slots__ = ("_c", "_home_ecef", "_r", "home")

    def __init__(self, home: GeoPoint) -> None:
        self.home = home
        lat, lon = math.radians(home.lat_deg), math.radians(home.lon_deg)
        sl, cl, so, co = math.sin(lat), math.cos(lat), math.sin(lon), math.cos(lon)
        n = geodetic.WGS84_A_M / math.sqrt(1.0 - geodetic.WGS84_E2 * sl * sl)
        alt = home.alt_amsl_m
        self._home_ecef = ((n + alt) * cl * co, (n + alt) * cl * so, (n * (1.0 - geodetic.WGS84_E2) + alt) * sl)
        # rows: north, east, down expressed in ECEF
        self._r = ((-sl * co, -sl * so, cl), (-so, co, 0.0), (-cl * co, -cl * so, -sl))
        self._c = np.array(self.ecef_constants, dtype=np.float64)

    def ned_from_geodetic(self, lat_deg: float, lon_deg: float, alt_amsl_m: float) -> Vec3:
        """Local NED (m) of a WGS-84 point."""
        return geodetic.ned_from_geodetic(self._c, 0, lat_deg, lon_deg, alt_amsl_m)

    @property
    def ecef_constants(self) -> tuple[float, ...]:
        """The 12 numbers ``geodetic_from_ned`` uses: home ECEF (m), then the north, east, down rows in ECEF."""
        rn, re, rd = self._r
        return (*self._home_ecef, *rn, *re, *rd)

    def geodetic_from_ned(self, north_m: float, east_m: float, down_m: float) -> GeoPoint:
        """WGS-84 point of a local NED position (m)."""
        return GeoPoint(*geodetic.geodetic_from_ned(self._c, 0, north_m, east_m, down_m))


def deg_e7_from_deg(angle_deg: float) -> int:
    """Degrees → MAVLink int32 degE7 (rounded)."""
    return round(angle_deg * DEG_E7)


def deg_from_deg_e7(angle_deg_e7: int) -> float:
    """MAVLink int32 degE7 → degrees."""
    return angle_deg_e7 / DEG_E7
