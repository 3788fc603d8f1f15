"""``LocalNedFrame.geodetic_from_ned`` (Bowring start + 1 fixed-point step) is within 1 mm of pymap3d where we fly."""

from __future__ import annotations

import itertools
import math

import pymap3d

from mavlink_bridge.contract.frames import GeoPoint, LocalNedFrame

_HOMES = [
    GeoPoint(lat, lon, alt)
    for lat, lon, alt in itertools.product((-70.0, -33.9, 0.0, 47.4, 80.0), (8.5,), (-50.0, 500.0, 3000.0))
]
_OFFSETS_M = [
    (n, e, d)
    for n in (-20_000.0, 0.0, 150.0, 20_000.0)
    for e in (-20_000.0, 35.0, 20_000.0)
    for d in (-9_000.0, -120.0, 0.0, 900.0)
]


def test_bowring_start_and_one_step_are_within_a_millimetre_of_pymap3d() -> None:
    worst_m = 0.0
    for home in _HOMES:
        frame = LocalNedFrame(home)
        for n, e, d in _OFFSETS_M:
            got = frame.geodetic_from_ned(n, e, d)
            lat, lon, alt = pymap3d.ned2geodetic(n, e, d, home.lat_deg, home.lon_deg, home.alt_amsl_m)
            # horizontal error in metres on the ellipsoid (1 deg of latitude ~ 111 km), vertical in metres
            err_n = abs(got.lat_deg - lat) * 111_320.0
            err_e = abs(got.lon_deg - lon) * 111_320.0 * math.cos(math.radians(lat))
            worst_m = max(worst_m, err_n, err_e, abs(got.alt_amsl_m - alt))
    assert worst_m < 1e-3


def test_round_trip_through_ned_is_sub_millimetre() -> None:
    for home in _HOMES:
        frame = LocalNedFrame(home)
        for n, e, d in _OFFSETS_M:
            geo = frame.geodetic_from_ned(n, e, d)
            back = frame.ned_from_geodetic(geo.lat_deg, geo.lon_deg, geo.alt_amsl_m)
            assert math.dist(back, (n, e, d)) < 1e-3
