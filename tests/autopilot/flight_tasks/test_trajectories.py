"""Reference trajectories (SPEC §6.5): consistent derivatives, shapes, route features, waypoints, validation."""

from __future__ import annotations

import numpy as np
import pytest

from autopilot.flight_tasks.trajectories import TRAJECTORY_TYPES, make_trajectory

CONTINUOUS = ["storm", "lissajous", "square", "figure8", "scenic_spiral"]


@pytest.mark.parametrize("kind", CONTINUOUS)
def test_velocity_and_acceleration_are_derivatives_of_position(kind: str) -> None:
    traj = make_trajectory(kind)
    h = 1e-4
    t = np.linspace(0.3, traj.duration_s - 0.3, 301)
    ref, plus, minus = traj.sample(t), traj.sample(t + h), traj.sample(t - h)
    vel_fd = (plus.pos_ned - minus.pos_ned) / (2 * h)
    acc_fd = (plus.vel_ned - minus.vel_ned) / (2 * h)
    scale_v = max(1.0, np.abs(ref.vel_ned).max())
    scale_a = max(1.0, np.abs(ref.acc_ned).max())
    np.testing.assert_allclose(ref.vel_ned, vel_fd, atol=1e-5 * scale_v)
    np.testing.assert_allclose(ref.acc_ned, acc_fd, atol=2e-3 * scale_a)


@pytest.mark.parametrize("kind", CONTINUOUS)
def test_routes_start_at_rest_at_home_and_stay_finite(kind: str) -> None:
    traj = make_trajectory(kind)
    first = traj.sample(0.0)
    np.testing.assert_allclose(first.pos_ned[:2], 0.0, atol=1e-9)
    np.testing.assert_allclose(first.vel_ned, 0.0, atol=1e-9)
    t = np.linspace(0, traj.duration_s, 2001)
    ref = traj.sample(t)
    for arr in (ref.pos_ned, ref.vel_ned, ref.acc_ned, ref.yaw_rad):
        assert np.all(np.isfinite(arr))
    assert np.all(ref.pos_ned[:, 2] <= 1e-9)  # never below ground (down <= 0)


def test_sample_accepts_arrays_of_any_shape() -> None:
    ref = make_trajectory("lissajous").sample(np.ones((2, 5)))
    assert ref.pos_ned.shape == (2, 5, 3) and ref.yaw_rad.shape == (2, 5)


def test_storm_holds_until_takeoff_then_spirals_out_and_up() -> None:
    storm = make_trajectory("storm")
    assert storm.duration_s == 140.0
    pre = storm.sample(np.linspace(0, 19.99, 50))
    np.testing.assert_allclose(pre.pos_ned, 0.0, atol=1e-12)
    np.testing.assert_allclose(pre.vel_ned, 0.0, atol=1e-12)
    t = np.linspace(25.0, 140.0, 500)
    ref = storm.sample(t)
    centre = np.array([-storm.r_start_m, 0.0])
    radius = np.linalg.norm(ref.pos_ned[:, :2] - centre, axis=1)
    alt = -ref.pos_ned[:, 2]
    assert np.all(np.diff(radius) > 0) and np.all(np.diff(alt) > 0)
    assert alt[-1] == pytest.approx(storm.alt_end_m) and radius[-1] == pytest.approx(storm.r_end_m)


def test_lissajous_height_varies() -> None:
    liss = make_trajectory("lissajous", amp_alt_m=2.0, alt_m=10.0)
    alt = -liss.sample(np.linspace(0, liss.duration_s, 4001)).pos_ned[:, 2]
    assert alt.max() - alt.min() > 3.5


def test_square_visits_four_corners_and_rests_there() -> None:
    sq = make_trajectory("square", side_m=10.0, speed_m_s=2.0)
    ts = 1.875 * 10.0 / 2.0
    ref = sq.sample(np.arange(5) * ts)
    np.testing.assert_allclose(ref.pos_ned[:, :2], [[0, 0], [10, 0], [10, 10], [0, 10], [0, 0]], atol=1e-9)
    np.testing.assert_allclose(ref.vel_ned, 0.0, atol=1e-9)
    peak = np.linalg.norm(sq.sample(np.linspace(0, sq.duration_s, 4001)).vel_ned, axis=1).max()
    assert peak == pytest.approx(2.0, rel=1e-3)


def test_tangent_yaw_follows_velocity() -> None:
    f8 = make_trajectory("figure8", yaw_mode="tangent")
    ref = f8.sample(np.array([10.0]))
    assert ref.yaw_rad[0] == pytest.approx(np.arctan2(ref.vel_ned[0, 1], ref.vel_ned[0, 0]))


@pytest.mark.parametrize("kind", CONTINUOUS)
def test_waypoints_are_spaced_along_the_route(kind: str) -> None:
    traj = make_trajectory(kind)
    wps = np.array(traj.waypoints(2.0, min_alt_m=0.0))
    end = traj.sample(traj.duration_s).pos_ned
    np.testing.assert_allclose(wps[0], [0.0, 0.0, -traj.sample(0.0).pos_ned[2]], atol=1e-9)
    np.testing.assert_allclose(wps[-1], [end[0], end[1], -end[2]], atol=1e-9)
    gaps = np.linalg.norm(np.diff(wps, axis=0), axis=1)
    assert np.all(gaps[:-1] <= 2.0 + 0.1) and np.all(gaps[:-1] > 1.0)  # chord <= arc spacing
    assert np.all(wps[:, 2] >= 0.0)


def test_waypoints_leave_out_the_part_below_min_alt() -> None:
    storm = make_trajectory("storm")  # starts on the ground at home
    wps = np.array(storm.waypoints(2.0))
    assert wps[:, 2].min() >= 1.0
    assert wps[-1, 2] == pytest.approx(storm.alt_end_m)
    with pytest.raises(ValueError, match="min_alt_m"):
        storm.waypoints(2.0, min_alt_m=50.0)


def test_steps_reference_and_waypoints() -> None:
    st = make_trajectory("steps", steps=[[0, 0, 0, 10], [2, 1, 0, 10], [4, 1, 1, 11]], duration_s=6.0)
    ref = st.sample(np.array([1.0, 3.0, 5.0]))
    np.testing.assert_allclose(ref.pos_ned, [[0, 0, -10], [1, 0, -10], [1, 1, -11]])
    np.testing.assert_allclose(ref.vel_ned, 0.0)
    assert st.waypoints(1.0) == [(0.0, 0.0, 10.0), (1.0, 0.0, 10.0), (1.0, 1.0, 11.0)]


def test_registry_validates_names_and_values() -> None:
    assert set(TRAJECTORY_TYPES) == {"storm", "lissajous", "square", "figure8", "scenic_spiral", "steps"}
    with pytest.raises(ValueError, match="type"):
        make_trajectory("hexagon")
    with pytest.raises(ValueError, match="radius_m"):
        make_trajectory("lissajous", radius_m=3.0)
    with pytest.raises(ValueError, match="period_s"):
        make_trajectory("lissajous", period_s=-1.0)
    with pytest.raises(ValueError, match="speed_m_s"):
        make_trajectory("square", speed_m_s=float("nan"))
    with pytest.raises(ValueError, match="steps"):
        make_trajectory("steps", steps=[[1, 0, 0, 10]])
    with pytest.raises(ValueError, match="yaw_mode"):
        make_trajectory("storm", yaw_mode="spin")
