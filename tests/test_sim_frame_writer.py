"""The fused frame path (sim.frame_kernel + mavlink_bridge.frame_writer) equals the reference byte for byte.

Reference: ``encode_frame(Encoder(SIM_SYSTEM_ID, SIM_COMPONENT_ID), LockstepFrame(SensorModel.imu_baro_mag,
SensorModel.gps, VehicleSim.ground_truth, detections))`` on a twin vehicle and sensor model (same seed).
"""

from __future__ import annotations

import math
import struct

import numpy as np
import pytest

from mavlink_bridge.codec import SIM_COMPONENT_ID, SIM_SYSTEM_ID, Decoder, Encoder
from mavlink_bridge.contract.frames import GeoPoint, LocalNedFrame
from mavlink_bridge.contract.wire import GpsSample, ObstacleDetection
from mavlink_bridge.frame_writer import python_hypot
from mavlink_bridge.lockstep import LockstepFrame, encode_frame
from sim.frame_kernel import (
    C_TRUTH_FRAME,
    DEPENDENCIES_SHA256,
    FusedFrame,
    _geodetic,
    dependencies_sha256,
    frame_constants,
    python_round3,
)
from sim.obstacle_sensor import ObstacleSensor
from sim.sensors import SensorModel
from sim.vehicle import VehicleSim
from sim.vehicle_config import load_vehicle
from sim.world import World, load_world

X500 = load_vehicle("x500")
OBSTACLE_WORLD = load_world(
    {
        "world": {
            "home": {"lat_deg": 47.397742, "lon_deg": 8.545594, "alt_m": 488.0},
            "obstacles": [
                {"cylinder": {"north_m": 3, "east_m": 0, "radius_m": 1, "height_m": 30}},
                {"sphere": {"north_m": 0, "east_m": -4, "alt_m": 2, "radius_m": 1}},
                {"box": {"north_m": -5, "east_m": 3, "size_m": [2, 2, 10], "yaw_deg": 20}},
            ],
            "wind": {"north_m_s": 2.0, "east_m_s": -1.0, "down_m_s": 0.0, "gust_m_s": 1.0, "seed": 3},
        }
    }
)


class Twins:
    """A reference vehicle + sensor model + encoder, and an identical pair behind ``FusedFrame``."""

    def __init__(self, world: World = OBSTACLE_WORLD, noise: bool = True, seed: int = 5) -> None:
        self.ref_sim = VehicleSim(X500, world=world, seed=seed)
        self.ref_sensors = SensorModel(X500, world.home, seed, noise=noise)
        self.encoder = Encoder(SIM_SYSTEM_ID, SIM_COMPONENT_ID)
        self.sim = VehicleSim(X500, world=world, seed=seed)
        self.sensors = SensorModel(X500, world.home, seed, noise=noise)
        self.fused = FusedFrame(self.sim, self.sensors)

    def set_state(self, state: np.ndarray, specific_force_frd: np.ndarray | None = None) -> None:
        for sim in (self.ref_sim, self.sim):
            sim.batch.state[0] = state
            if specific_force_frd is not None:
                sim.batch.specific_force_frd[0] = specific_force_frd

    def step(self, motor_cmd: list[float]) -> None:
        self.ref_sim.step(motor_cmd)
        self.sim.step(motor_cmd)

    def frames(self, detections: tuple[ObstacleDetection, ...] = ()) -> tuple[bytes, bytes, LockstepFrame]:
        s, v = self.ref_sensors, self.ref_sim
        frame = LockstepFrame(s.imu_baro_mag(v), s.gps(v), v.ground_truth(), detections)
        return encode_frame(self.encoder, frame), self.fused.datagram(detections), frame

    def assert_same_sensor_state(self) -> None:
        """Same next GPS time and GPS error; the same noise stream from here on (the buffers may be refilled
        at different steps: the fused path reserves a whole step's noise at once)."""
        a, b = self.ref_sensors, self.sensors
        assert a._counters[1] == b._counters[1]
        assert a._gps_error_ned_m.tolist() == b._gps_error_ned_m.tolist()
        assert a._take_noise(5000) == b._take_noise(5000)


def _state(**fields: object) -> np.ndarray:
    """A 17-state row: hover at 10 m, level, with overrides by slice name."""
    x = np.zeros(17)
    x[2] = -10.0
    x[6] = 1.0
    slices = {"pos": slice(0, 3), "vel": slice(3, 6), "q": slice(6, 10), "rate": slice(10, 13)}
    for name, value in fields.items():
        x[slices[name]] = value
    return x


def test_flight_with_noise_gps_and_detections_is_byte_identical() -> None:
    twins = Twins()
    twins.set_state(_state(pos=[0.0, 0.0, -2.0]))
    obstacle_sensor = ObstacleSensor(OBSTACLE_WORLD, seed=5)
    hover = twins.sim.hover_omega_rad_s() / X500.omega_max_rad_s
    gps_frames = detection_frames = 0
    for k in range(400):
        v = twins.ref_sim
        detections = tuple(obstacle_sensor.detect(v.pos_ned, v.q_ned_frd, v.t_us)) if k % 25 == 0 else ()
        ref, fused, frame = twins.frames(detections)
        assert fused == ref, f"step {k}"
        gps_frames += frame.gps is not None
        detection_frames += bool(detections)
        phase = 0.3 * math.sin(k / 15.0)
        twins.step([hover * (1.02 + 0.02 * phase), hover * (1.0 - 0.02 * phase), hover * 1.01, hover * 1.0])
    twins.assert_same_sensor_state()
    assert gps_frames == 16 and detection_frames >= 5
    assert twins.fused.writer.seq == twins.encoder._seq
    assert np.array_equal(twins.ref_sim.batch.state, twins.sim.batch.state)


def test_fused_datagram_decodes_to_the_reference_messages() -> None:
    twins = Twins()
    ref, fused, frame = twins.frames()
    assert fused == ref
    gps, _truth, sensor = Decoder().decode(fused)
    assert isinstance(gps, GpsSample) and sensor.time_us == frame.sensor.time_us == 0


@pytest.mark.parametrize(
    ("name", "state", "specific_force"),
    [
        ("nan position", _state(pos=[math.nan, 1.0, -5.0]), None),
        ("nan everything", np.full(17, math.nan), np.full(3, math.nan)),
        ("inf velocity", _state(vel=[math.inf, -math.inf, math.inf]), [math.inf, -math.inf, 0.0]),
        ("saturated velocity and accel", _state(vel=[400.0, -400.0, 1e6]), [1e4, -1e4, 5e5]),
        ("far away (lat/lon/alt saturate)", _state(pos=[3e6, -4e6, -3e4]), None),
        ("below the ellipsoid", _state(pos=[0.0, 0.0, 2e3]), None),
        ("west-bound (negative course)", _state(vel=[-3.0, -0.5, 0.0]), None),
        ("exactly south", _state(vel=[-2.0, 0.0, 0.0]), None),
        ("zero velocity, zero force (cog unknown, truncation)", _state(), [0.0, 0.0, 0.0]),
        ("negative zeros", _state(vel=[-0.0, -0.0, -0.0], rate=[-0.0, 0.0, -0.0]), [-0.0, -0.0, -0.0]),
        ("tiny values", _state(vel=[1e-310, -5e-324, 1e-300], rate=[1e-45, 1e-50, 0.0]), [1e-40, 0.0, 0.0]),
    ],
)
@pytest.mark.parametrize("noise", [False, True])
def test_edge_states_are_byte_identical(
    name: str, state: np.ndarray, specific_force: list[float] | None, noise: bool
) -> None:
    twins = Twins(noise=noise)
    for k in range(3):  # a GPS fix (the first, due at t = 0) and two frames without, from the same edge state
        twins.set_state(state, None if specific_force is None else np.asarray(specific_force, dtype=float))
        ref, fused, _ = twins.frames()
        assert fused == ref, f"{name}, frame {k}"
    twins.assert_same_sensor_state()


def test_truncation_drops_trailing_zeros_like_the_codec() -> None:
    twins = Twins(noise=False)
    twins.set_state(_state(pos=[0.0, 0.0, 0.0]), np.zeros(3))
    ref, fused, _ = twins.frames()
    assert fused == ref
    # the truth message ends with three zero accelerations and two equal speeds of 0: truncated
    assert len(fused) < 3 * 12 + 39 + 64 + 65


def test_float32_overflow_raises_like_struct_pack() -> None:
    twins = Twins()
    twins.set_state(_state(rate=[1e39, 0.0, 0.0]))
    s, v = twins.ref_sensors, twins.ref_sim
    frame = LockstepFrame(s.imu_baro_mag(v), s.gps(v), v.ground_truth())
    with pytest.raises(OverflowError):
        encode_frame(twins.encoder, frame)
    with pytest.raises(OverflowError):
        twins.fused.datagram()


def test_baro_beyond_the_isa_model_raises_like_the_reference() -> None:
    twins = Twins(noise=False)
    twins.set_state(_state(pos=[0.0, 0.0, -5e4]))
    s, v = twins.ref_sensors, twins.ref_sim
    frame = LockstepFrame(s.imu_baro_mag(v), s.gps(v), v.ground_truth())
    with pytest.raises(struct.error):  # the reference's pressure is complex: struct refuses it
        encode_frame(twins.encoder, frame)
    with pytest.raises(ValueError):
        twins.fused.datagram()


def test_python_hypot_matches_math_hypot_to_the_bit() -> None:
    rng = np.random.default_rng(0)
    for scale in (1e-3, 1.0, 4e6, 1e300):
        xs = rng.standard_normal(2000) * scale
        ys = rng.standard_normal(2000) * scale * rng.choice([1.0, 1e-4, 1e-9, 0.0], 2000)
        for x, y in zip(xs.tolist(), ys.tolist(), strict=True):
            assert python_hypot(x, y) == math.hypot(x, y), (x, y)
    for x, y in [(math.nan, 1.0), (math.inf, math.nan), (0.0, -0.0), (5e-324, 0.0), (3.0, 4.0)]:
        assert repr(python_hypot(x, y)) == repr(math.hypot(x, y))


def test_python_round3_matches_round_to_the_bit() -> None:
    rng = np.random.default_rng(1)
    values = (rng.standard_normal(5000) * 600.0).tolist()
    values += [k / 1000.0 + 0.0005 for k in range(-3000, 3000)]  # near-ties both ways
    values += [0.0005, -0.0005, 0.0015, 2.5e-4, 488.0005, -0.0, math.inf, -math.inf, 1e11 + 0.0005]
    for x in values:
        assert repr(python_round3(x)) == repr(round(x, 3)), x
    assert math.isnan(python_round3(math.nan))


def test_geodetic_kernel_matches_local_ned_frame_to_the_bit() -> None:
    rng = np.random.default_rng(2)
    for home in (GeoPoint(47.397742, 8.545594, 488.0), GeoPoint(-33.9, 151.2, 5.0), GeoPoint(89.0, -170.0, 3000.0)):
        frame = LocalNedFrame(home)
        c = np.zeros(C_TRUTH_FRAME + 12)
        c[C_TRUTH_FRAME:] = frame_constants(frame)
        for n, e, d in (rng.standard_normal((1500, 3)) * [2000.0, 2000.0, 300.0]).tolist():
            geo = frame.geodetic_from_ned(n, e, d)
            assert _geodetic(c, C_TRUTH_FRAME, n, e, d) == (geo.lat_deg, geo.lon_deg, geo.alt_amsl_m)


def test_kernel_cache_is_keyed_to_the_files_it_mirrors() -> None:
    assert dependencies_sha256() == DEPENDENCIES_SHA256, (
        "mavlink_bridge/frame_writer.py or sim/sensors.py changed: check that sim/frame_kernel.py still mirrors "
        f"them, then set DEPENDENCIES_SHA256 = {dependencies_sha256()!r} there (it also refreshes numba's cache)"
    )
