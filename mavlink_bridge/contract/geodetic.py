"""WGS-84 <-> local NED about an origin: the one implementation, compiled (numba), for every caller.

The origin is 12 numbers (``LocalNedFrame.ecef_constants``): its ECEF position (m), then the north, east and
down axes expressed in ECEF. ``LocalNedFrame`` (Python), the simulator's per-step truth and GPS
(``sim.frame_kernel``) and the EKF's GPS fusion (``autopilot.estimation``) all call these two functions;
``tests/mavlink_bridge/contract/test_frames.py`` checks them against pymap3d.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

WGS84_A_M = 6378137.0
WGS84_F = 1.0 / 298.257223563
WGS84_E2 = WGS84_F * (2.0 - WGS84_F)
WGS84_B_M = WGS84_A_M * (1.0 - WGS84_F)
WGS84_EP2 = WGS84_E2 / (1.0 - WGS84_E2)
#: Fixed-point steps of ``geodetic_from_ned`` after Bowring's start: 1 stays < 1 mm from pymap3d from
#: -1 km to 10 km altitude, any latitude, within 20 km of home (``test_frames_geodetic_iterations.py``).
GEODETIC_ITERATIONS = 1
#: How many numbers describe an origin (ECEF position, then the N, E, D axes in ECEF).
N_ORIGIN = 12
Triple = tuple[float, float, float]


@njit(cache=True)
def ned_from_geodetic(
    c: np.ndarray, o: int, lat_deg: float, lon_deg: float, alt_m: float
) -> tuple[float, float, float]:
    """Local NED (m) of a WGS-84 point, about the origin ``c[o:o+12]``."""
    lat, lon = math.radians(lat_deg), math.radians(lon_deg)
    s, co = math.sin(lat), math.cos(lat)
    n = WGS84_A_M / math.sqrt(1.0 - WGS84_E2 * s * s)
    dx = (n + alt_m) * co * math.cos(lon) - c[o]
    dy = (n + alt_m) * co * math.sin(lon) - c[o + 1]
    dz = (n * (1.0 - WGS84_E2) + alt_m) * s - c[o + 2]
    return (
        c[o + 3] * dx + c[o + 4] * dy + c[o + 5] * dz,
        c[o + 6] * dx + c[o + 7] * dy,
        c[o + 9] * dx + c[o + 10] * dy + c[o + 11] * dz,
    )


@njit(cache=True)
def geodetic_from_ned(
    c: np.ndarray, o: int, north_m: float, east_m: float, down_m: float
) -> tuple[float, float, float]:
    """(lat °, lon °, alt m) of a local NED position about the origin ``c[o:o+12]`` (Bowring's start, then
    ``GEODETIC_ITERATIONS`` fixed-point steps on the latitude)."""
    x = c[o] + c[o + 3] * north_m + c[o + 6] * east_m + c[o + 9] * down_m
    y = c[o + 1] + c[o + 4] * north_m + c[o + 7] * east_m + c[o + 10] * down_m
    z = c[o + 2] + c[o + 5] * north_m + c[o + 8] * east_m + c[o + 11] * down_m
    lon = math.atan2(y, x)
    p = math.hypot(x, y)
    theta = math.atan2(z * WGS84_A_M, p * WGS84_B_M)
    st, ct = math.sin(theta), math.cos(theta)
    lat = math.atan2(z + WGS84_EP2 * WGS84_B_M * st * st * st, p - WGS84_E2 * WGS84_A_M * ct * ct * ct)
    alt = 0.0
    for _ in range(GEODETIC_ITERATIONS):
        s = math.sin(lat)
        n = WGS84_A_M / math.sqrt(1.0 - WGS84_E2 * s * s)
        alt = p / math.cos(lat) - n
        lat = math.atan2(z, p * (1.0 - WGS84_E2 * n / (n + alt)))
    return math.degrees(lat), math.degrees(lon), alt
