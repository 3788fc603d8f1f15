"""Obstacle-sensor detections of tracked vehicles (SPEC §13): gated onto their tracks as fixes (an alpha-beta
filter that gives the track a fresh position and velocity), and no longer obstacles to the planner."""

from __future__ import annotations

import math

import numpy as np
import pytest
from autopilot_fakes import make_state
from traffic_kinematic import HOME, report

from autopilot.navigation.home_frame import HomeFrame
from autopilot.navigation.traffic_link import TrafficLink
from autopilot.param_schema import make_param_store
from autopilot.traffic.rules import PARKED_SPEED_M_S, owns_column, parked
from autopilot.traffic.sensor_fusion import GATE_M, associate, gate_m
from autopilot.traffic.tracks import FIX_HOLD_US, TrackTable, TrafficTrack
from mavlink_bridge.contract.traffic import TrafficSource
from mavlink_bridge.contract.wire import ObstacleDetection
from sim.obstacle_sensor import ObstacleSensor
from sim.world import Sphere, WindConfig, World

UAV2 = (TrafficSource.UAV, 2)


def _track(target_id: int, pos: tuple[float, float, float], vel=(0.0, 0.0, 0.0), t_us: int = 0) -> TrafficTrack:  # type: ignore[no-untyped-def]
    return TrafficTrack(TrafficSource.UAV, target_id, "", pos, vel, t_us, h_acc_m=0.5, v_acc_m=0.5)


def test_detections_are_gated_onto_the_nearest_track_one_to_one() -> None:
    """Two tracks 6 m apart, three detections: each track takes its nearest, the one far from both stays an
    obstacle, a column (None) is never a vehicle, nor a sphere larger than a small UAS; the gate widens with the
    report's age (an unreported manoeuvre) and for a sensor id held before."""
    a, b = _track(2, (20.0, 0.0, -10.0)), _track(3, (20.0, 6.0, -10.0))
    centers = [(20.5, 5.0, -10.0), (19.0, 0.5, -10.0), (40.0, 0.0, -10.0), None]
    out = associate((a, b), 0, centers, [0.4] * 4, [11, 12, 13, 14], {})
    assert out == {0: b.key, 1: a.key}
    big = associate((a, b), 0, centers, [2.0, 0.4, 0.4, 0.4], [11, 12, 13, 14], {})
    assert big == {1: a.key}  # a 2 m sphere where UAV 3 is predicted is an obstacle, not a small UAS
    assert gate_m(a, 0) == pytest.approx(GATE_M + 1.0)
    assert gate_m(a, 2_000_000) > gate_m(a, 0) + 5.0
    off = [(20.0, 4.5, -10.0)]  # 4.5 m from a's prediction: outside its gate, inside the held one
    assert associate((a,), 0, off, [0.4], [12], {}) == {}
    assert associate((a,), 0, off, [0.4], [12], {12: a.key}) == {0: a.key}


def test_fixes_give_the_track_a_fresh_position_and_the_velocity_it_flies() -> None:
    """A UAV reported hovering (a second-old report) flies east at 4 m/s: ten fixes at 10 Hz and the track has
    the fix's time, a position within 0.2 m and a velocity within 0.5 m/s; without fixes for FIX_HOLD_US the
    report is the track again."""
    table = TrackTable(own_system_id=1)
    table.set_home(HOME)
    table.update(0, [report(TrafficSource.UAV, 2, np.array((30.0, 0.0, -10.0)), np.zeros(3), 0)], 5.0)
    assert table.observe((TrafficSource.UAV, 9), 100_000, (0.0, 0.0, 0.0), 0.3) is False  # no such track
    for k in range(1, 11):
        t_us = 1_000_000 + k * 100_000
        assert table.observe(UAV2, t_us, (30.0, 4.0 * (t_us * 1e-6 - 1.0), -10.0), 0.3)
    assert table.observe(UAV2, t_us, (0.0, 0.0, 0.0), 0.3) is False  # not newer: ignored
    (track,) = table.tracks
    assert track.t_us == 2_000_000 and track.h_acc_m == 0.3
    assert track.pos_home_ned_m == pytest.approx((30.0, 4.0, -10.0), abs=0.2)
    assert track.vel_ned_m_s == pytest.approx((0.0, 4.0, 0.0), abs=0.5)
    assert track.flight_state is table.tracks[0].flight_state  # the report still says who and what it is
    assert track.steady_vel_ned_m_s == (0.0, 0.0, 0.0)  # what it says it does: the report's, for the rules
    table.update(2_000_000 + FIX_HOLD_US + 1, [], 5.0)
    (track,) = table.tracks
    assert track.t_us == 0 and track.vel_ned_m_s == (0.0, 0.0, 0.0) and track.reported_vel_ned_m_s is None


def test_a_vehicle_on_its_pad_seen_by_a_noisy_camera_stays_parked() -> None:
    """Encounter case 625: a UAV standing on its pad 24 m off, its fixes 0.85 m (1-sigma) noisy at 10 Hz: the
    filter's velocity swings by about a metre a second, yet it stays parked (its report says it stands still) and
    never holds a neighbour's take-off."""
    rng = np.random.default_rng(625)
    table = TrackTable(own_system_id=1)
    table.set_home(HOME)
    table.update(0, [report(TrafficSource.UAV, 2, np.array((24.0, 0.0, 0.0)), np.zeros(3), 0)], 5.0)
    swings = []
    for k in range(1, 51):
        t_us = k * 100_000
        table.observe(UAV2, t_us, tuple(np.array((24.0, 0.0, 0.0)) + rng.normal(0.0, 0.85, 3) * (1, 1, 0.05)), 0.85)
        (track,) = table.tracks
        swings.append(math.hypot(*track.vel_ned_m_s[:2]))
        assert parked(track, t_us) and owns_column(track)
    assert max(swings) > PARKED_SPEED_M_S  # the filter's velocity alone would call it moving


def _seen(other_ned: tuple[float, float, float]) -> tuple[ObstacleDetection, ...]:
    """What this vehicle's camera (at 10 m, nose north) reports of a vehicle at ``other_ned`` and a world sphere."""
    world = World(HOME, (Sphere(25.0, -8.0, 10.0, 1.5),), WindConfig(), 0.0)
    sensor = ObstacleSensor(world, seed=3)
    others = np.array([[*other_ned, 0.6, len(world.obstacles) + 1]])
    dets = sensor.detect(np.array((0.0, 0.0, -10.0)), np.array((1.0, 0.0, 0.0, 0.0)), 0, others)
    assert sorted(d.obstacle_id for d in dets) == [0, 2]  # the sphere, the vehicle (its id after the world's)
    return dets


@pytest.mark.parametrize(("avoid", "kept"), [(5, [0]), (1, [0, 2])])
def test_a_tracked_vehicle_seen_by_the_camera_is_traffic_not_an_obstacle(avoid: int, kept: list[int]) -> None:
    """The camera sees a neighbour 15 m ahead (reported 1.5 m off where it is now) and a sphere: with
    NAV_TRAFF_AVOID avoiding, the neighbour's detection is its track's fix and leaves the obstacles; warn-only it
    stays an obstacle too (nothing else would steer around it), the fix is taken either way."""
    params = make_param_store()
    params.set("NAV_TRAFF_AVOID", avoid)
    link = TrafficLink(params, 1)
    frame = HomeFrame(HOME)
    link.avoidance.set_home(HOME)
    link.avoidance.table.update(0, [report(TrafficSource.UAV, 2, np.array((15.0, 1.5, -10.0)), np.zeros(3), 0)], 5.0)
    dets = _seen((15.0, 0.0, -10.0))
    state = make_state((0.0, 0.0, -10.0), time_us=0)
    obstacles, vehicles = link.fuse(state, frame, dets)
    assert sorted(d.obstacle_id for d in obstacles) == kept
    assert vehicles == (frozenset({2}) if avoid == 5 else frozenset())
    (track,) = link.avoidance.table.tracks
    assert math.dist(track.pos_home_ned_m, (15.0, 0.0, -10.0)) < 1.0  # the fix, not the report
