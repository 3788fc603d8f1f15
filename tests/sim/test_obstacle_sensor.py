"""Obstacle sensor: field of view, range, occlusion, body-frame reporting, ultrasonic fusion, seeding."""

from __future__ import annotations

import math

import numpy as np
import pytest

from mavlink_bridge.contract.frames import quat_from_euler, rotate_frd_to_ned
from mavlink_bridge.contract.wire import ObstacleShape
from sim.obstacle_sensor import ObstacleSensor, ObstacleSensorConfig
from sim.world import load_world

POS = np.array([0.0, 0.0, -10.0])
LEVEL_NORTH = quat_from_euler(0.0, 0.0, 0.0)


def _world(*obstacles: dict):
    return load_world({"obstacles": list(obstacles)})


def _ids(dets) -> list[int]:
    return sorted(d.obstacle_id for d in dets)


def test_field_of_view_and_range() -> None:
    world = _world(
        {"sphere": {"north_m": 15, "east_m": 0, "alt_m": 10, "radius_m": 1}},  # ahead, in view
        {"sphere": {"north_m": 0, "east_m": 15, "alt_m": 10, "radius_m": 1}},  # 90° right: outside 90° FOV
        {"sphere": {"north_m": 40, "east_m": 5, "alt_m": 10, "radius_m": 1}},  # beyond 25 m
        {"sphere": {"north_m": -15, "east_m": 0, "alt_m": 10, "radius_m": 1}},  # behind
    )
    sensor = ObstacleSensor(world, seed=1)
    assert _ids(sensor.detect(POS, LEVEL_NORTH, 0)) == [0]
    # yawed 90° right (nose east): now the east sphere is ahead and the north one at the FOV edge (90°) is not
    assert _ids(sensor.detect(POS, quat_from_euler(0.0, 0.0, math.pi / 2), 0)) == [1]
    # flying closer brings the far one into range
    assert 2 in _ids(sensor.detect(np.array([20.0, 0.0, -10.0]), LEVEL_NORTH, 0))


def test_occlusion_hides_farther_obstacle_behind_nearer_one() -> None:
    world = _world(
        {"cylinder": {"north_m": 8, "east_m": 0, "radius_m": 3, "height_m": 30}},
        {"sphere": {"north_m": 18, "east_m": 0, "alt_m": 10, "radius_m": 1}},  # right behind the cylinder
        {"sphere": {"north_m": 18, "east_m": 9, "alt_m": 10, "radius_m": 1}},  # visible beside it
    )
    dets = ObstacleSensor(world, seed=2).detect(POS, LEVEL_NORTH, 0)
    assert _ids(dets) == [0, 2]
    assert next(d for d in dets if d.obstacle_id == 0).shape is ObstacleShape.CYLINDER


def test_reports_nearest_point_in_body_frame_with_small_noise() -> None:
    world = _world({"sphere": {"north_m": 3, "east_m": 10, "alt_m": 12, "radius_m": 2}})
    q = quat_from_euler(0.05, -0.1, math.radians(70.0))
    truth_center = np.array([3.0, 10.0, -12.0])
    rel = truth_center - POS
    truth_point = rel * (1 - 2.0 / np.linalg.norm(rel))
    cfg = ObstacleSensorConfig()
    errs = []
    for seed in range(20):
        (det,) = ObstacleSensor(world, seed=seed, config=cfg).detect(POS, q, 5)
        assert det.time_us == 5 and det.shape is ObstacleShape.SPHERE
        p_ned = rotate_frd_to_ned(q, np.array(det.pos_frd_m))
        errs.append(np.linalg.norm(p_ned - truth_point))
        assert det.radius_m == pytest.approx(2.0, rel=0.11)
    rng = np.linalg.norm(truth_point)
    sigma = cfg.depth_noise_m + cfg.depth_noise_per_m2 * rng**2
    assert 0.0 < np.mean(errs) < 3 * sigma
    assert np.std(errs) > 0.0  # noisy, not exact


def test_ultrasonic_fusion_sharpens_close_range() -> None:
    world = _world({"cylinder": {"north_m": 6, "east_m": 0, "radius_m": 1.5, "height_m": 30}})
    wide = ObstacleSensorConfig(depth_noise_m=0.3, depth_noise_per_m2=0.0, ultrasonic_range_m=0.1)
    fused = ObstacleSensorConfig(depth_noise_m=0.3, depth_noise_per_m2=0.0, ultrasonic_range_m=6.0)

    def errors(cfg: ObstacleSensorConfig) -> float:
        out = []
        for seed in range(30):
            (det,) = ObstacleSensor(world, seed=seed, config=cfg).detect(POS, LEVEL_NORTH, 0)
            out.append(abs(det.pos_frd_m[0] - 4.5))
        return float(np.mean(out))

    assert errors(fused) < 0.3 * errors(wide)


def test_box_reports_its_circumscribed_column_and_is_seeded() -> None:
    world = _world({"box": {"north_m": 15, "east_m": 0, "size_m": [6, 8, 30], "yaw_deg": 0}})
    a = ObstacleSensor(world, seed=4).detect(POS, LEVEL_NORTH, 0)
    b = ObstacleSensor(world, seed=4).detect(POS, LEVEL_NORTH, 0)
    assert a == b
    (det,) = a
    assert det.shape is ObstacleShape.BOX and det.radius_m == pytest.approx(5.0, rel=0.11)
    # nearest point of the circumscribed cylinder: 15 - 5 = 10 m ahead
    assert det.pos_frd_m[0] == pytest.approx(10.0, abs=0.5)
