"""World part of the mission YAML (issue 2): shapes, signed distances, validation, payload, batch collisions."""

from __future__ import annotations

import math

import numpy as np
import pytest
import yaml

from sim.batch import BatchSim
from sim.end_reason import EndReason
from sim.vehicle_config import load_vehicle
from sim.world import DEFAULT_HOME, Box, Cylinder, Sphere, WorldConfigError, empty_world, load_world

SPEC_MISSION = """
name: city_block_delivery
home: {lat_deg: 30.2635, lon_deg: 120.1233, alt_m: 12.0}
vehicle: x500
mission:
  - takeoff: {alt_m: 10}
  - land: {}
fence:
  - exclusion_circle: {north_m: 60, east_m: 10, radius_m: 8}
world:
  obstacles:
    - cylinder: {north_m: 20, east_m: 1, radius_m: 3, height_m: 25}
    - box: {north_m: 50, east_m: -2, size_m: [6, 8, 30], yaw_deg: 15}
    - sphere: {north_m: 70, east_m: 0, alt_m: 10, radius_m: 2.5}
  wind: {north_m_s: 2.0, east_m_s: -1.0, down_m_s: 0.0, gust_m_s: 1.0, seed: 7}
  payload_kg: 1.0
"""


def test_sim_world_loads_spec_mission(tmp_path) -> None:
    path = tmp_path / "m.yaml"
    path.write_text(SPEC_MISSION)
    for source in (path, str(path), SPEC_MISSION, yaml.safe_load(SPEC_MISSION)):
        world = load_world(source)
        assert world.home.lat_deg == 30.2635 and world.home.alt_amsl_m == 12.0
        assert [type(o) for o in world.obstacles] == [Cylinder, Box, Sphere]
        assert world.wind.mean_ned_m_s == (2.0, -1.0, 0.0) and world.wind.gust_m_s == 1.0 and world.wind.seed == 7
        assert world.payload_kg == 1.0
    bare = load_world({"obstacles": [{"sphere": {"north_m": 1, "east_m": 2, "alt_m": 3, "radius_m": 1}}]})
    assert bare.home == DEFAULT_HOME and len(bare.obstacles) == 1
    assert load_world({"name": "m", "mission": []}) == empty_world()


def test_sim_obstacle_signed_distances() -> None:
    cyl = Cylinder(20.0, 1.0, 3.0, 25.0)
    pts = np.array([[20.0, 1.0, -10.0], [20.0, 6.0, -10.0], [20.0, 1.0, -30.0], [20.0, 8.0, -29.0]])
    assert np.allclose(cyl.distance_m(pts), [-3.0, 2.0, 5.0, math.hypot(4.0, 4.0)])
    box = Box(0.0, 0.0, (6.0, 8.0, 30.0), yaw_deg=90.0)  # length along east after yaw
    assert np.allclose(
        box.distance_m(np.array([[0.0, 5.0, -1.0], [6.0, 0.0, -1.0], [0.0, 0.0, -40.0]])), [2.0, 2.0, 10.0]
    )
    assert box.distance_m(np.array([0.0, 0.0, -15.0]))[0] == pytest.approx(-3.0)
    sphere = Sphere(70.0, 0.0, 10.0, 2.5)
    assert np.allclose(sphere.distance_m(np.array([[70.0, 0.0, -10.0], [70.0, 0.0, -15.0]])), [-2.5, 2.5])
    world = load_world(SPEC_MISSION)
    clearance = world.clearance_m(np.array([[0.0, 0.0, -10.0], [70.0, 0.0, -10.0]]))
    assert clearance[0] == pytest.approx(math.hypot(20.0, 1.0) - 3.0)
    assert clearance[1] == pytest.approx(-2.5)
    assert np.all(np.isinf(empty_world().clearance_m(np.zeros((2, 3)))))


@pytest.mark.parametrize(
    ("world", "fragments"),
    [
        (
            {"obstacles": [{"cylinder": {"north_m": 0, "east_m": 0, "radius_m": -1, "height_m": 5}}]},
            ["world.obstacles[0].cylinder.radius_m", "[0.01, 10000]"],
        ),
        ({"obstacles": [{"cone": {"north_m": 0}}]}, ["world.obstacles[0]", "unknown shape 'cone'"]),
        ({"obstacles": [{"sphere": {"north_m": 0, "east_m": 0, "radius_m": 1}}]}, ["sphere", "missing", "alt_m"]),
        ({"obstacles": [{"box": {"north_m": 0, "east_m": 0, "size_m": [1, 2]}}]}, ["box.size_m", "[length"]),
        ({"obstacles": [{"sphere": {"north_m": "x", "east_m": 0, "alt_m": 1, "radius_m": 1}}]}, ["north_m", "finite"]),
        ({"wind": {"north_m_s": 99}}, ["world.wind.north_m_s", "[-50, 50]"]),
        ({"wind": {"gust_m_s": 1, "seed": -3}}, ["world.wind.seed"]),
        ({"wind": {"speed": 3}}, ["world.wind", "unknown field", "speed"]),
        ({"payload_kg": float("nan")}, ["world.payload_kg"]),
        ({"obstacles": {"sphere": {}}}, ["world.obstacles", "list"]),
    ],
)
def test_sim_world_validation_names_entry_and_range(world, fragments) -> None:
    with pytest.raises(WorldConfigError) as exc:
        load_world({"home": {"lat_deg": 30.0, "lon_deg": 120.0}, "world": world})
    for fragment in fragments:
        assert fragment in str(exc.value)


def test_sim_world_home_validated() -> None:
    with pytest.raises(WorldConfigError, match="no such file"):
        load_world("/nonexistent/mission.yaml")
    assert load_world("{obstacles: []}").obstacles == ()
    with pytest.raises(WorldConfigError, match=r"home.lat_deg.*\[-90, 90\]"):
        load_world({"home": {"lat_deg": 95.0, "lon_deg": 0.0}, "world": {}})


def test_sim_batch_uses_world_payload_wind_and_obstacles() -> None:
    world = load_world(SPEC_MISSION)
    vehicle = load_vehicle("delivery650")
    sim = BatchSim(vehicle, 3, world=world, seed=1)
    assert np.all(sim.payload_kg == 1.0)
    with pytest.raises(ValueError, match="payload_max_kg"):
        BatchSim(load_vehicle("quad250"), 1, world=world)
    # three vehicles flying north at 6 m/s, 10 m up: through the cylinder, beside it, and clear of everything
    sim.reset(pos_ned=np.array([[10.0, 1.0, -10.0], [10.0, -6.0, -10.0], [10.0, 30.0, -10.0]]))
    sim.omega_rad_s[:] = sim.hover_omega_rad_s()[:, None]
    sim.vel_ned[:, 0] = 6.0
    cmd = np.repeat((sim.hover_omega_rad_s() / vehicle.omega_max_rad_s)[:, None], 4, axis=1)
    for _ in range(250 * 2):
        sim.step(cmd)
    assert sim.end_reason.tolist() == [EndReason.COLLISION, EndReason.RUNNING, EndReason.RUNNING]
    assert 0.0 < sim.min_clearance_m[1] < 5.0 and sim.min_clearance_m[2] > 15.0
    assert np.all(np.abs(sim.wind_ned_m_s[1] - [2.0, -1.0, 0.0]) < 5.0)
