"""Frame conventions: quaternion/Euler round trips, rotation direction, geodetic vs pymap3d."""

from __future__ import annotations

import numpy as np
import pymap3d
import pytest

from mavlink_bridge.contract.frames import (
    GeoPoint,
    LocalNedFrame,
    dcm_from_quat,
    euler_from_quat,
    quat_conjugate,
    quat_from_euler,
    quat_multiply,
    rotate_frd_to_ned,
    rotate_ned_to_frd,
)


def test_euler_round_trip_batch() -> None:
    rng = np.random.default_rng(1)
    eul = np.column_stack((rng.uniform(-3, 3, 50), rng.uniform(-1.5, 1.5, 50), rng.uniform(-3, 3, 50)))
    back = euler_from_quat(quat_from_euler(eul[:, 0], eul[:, 1], eul[:, 2]))
    np.testing.assert_allclose(back, eul, atol=1e-9)


def test_yaw_90_maps_body_forward_to_east() -> None:
    q = quat_from_euler(0.0, 0.0, np.pi / 2)
    np.testing.assert_allclose(rotate_frd_to_ned(q, np.array([1.0, 0, 0])), [0, 1, 0], atol=1e-12)
    np.testing.assert_allclose(rotate_ned_to_frd(q, np.array([0, 1.0, 0])), [1, 0, 0], atol=1e-12)


def test_positive_roll_puts_body_right_axis_down() -> None:
    q = quat_from_euler(np.pi / 2, 0.0, 0.0)
    np.testing.assert_allclose(rotate_frd_to_ned(q, np.array([0, 1.0, 0])), [0, 0, 1], atol=1e-12)


def test_dcm_is_orthonormal_and_product_composes() -> None:
    p = quat_from_euler(0.3, -0.2, 1.0)
    q = quat_from_euler(-0.1, 0.4, -2.0)
    r = dcm_from_quat(quat_multiply(p, q))
    np.testing.assert_allclose(r, dcm_from_quat(p) @ dcm_from_quat(q), atol=1e-12)
    np.testing.assert_allclose(r @ r.T, np.eye(3), atol=1e-12)
    np.testing.assert_allclose(quat_multiply(p, quat_conjugate(p)), [1, 0, 0, 0], atol=1e-12)


@pytest.mark.parametrize("ned", [(0.0, 0.0, 0.0), (120.0, -40.0, -35.0), (-2500.0, 1800.0, -400.0)])
def test_local_frame_matches_pymap3d(ned: tuple[float, float, float]) -> None:
    home = GeoPoint(30.2635, 120.1233, 12.0)
    frame = LocalNedFrame(home)
    p = frame.geodetic_from_ned(*ned)
    lat, lon, alt = pymap3d.ned2geodetic(*ned, home.lat_deg, home.lon_deg, home.alt_amsl_m)
    assert p.lat_deg == pytest.approx(lat, abs=1e-9)
    assert p.lon_deg == pytest.approx(lon, abs=1e-9)
    assert p.alt_amsl_m == pytest.approx(alt, abs=1e-4)
    np.testing.assert_allclose(frame.ned_from_geodetic(p.lat_deg, p.lon_deg, p.alt_amsl_m), ned, atol=1e-4)
