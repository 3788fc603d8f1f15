"""The sim's compiled frame path (``sim.frame_kernel.SensorValues`` + ``mavlink_bridge.wire.frame_writer.FrameWriter``)
against independent oracles: pymavlink decodes every datagram (framing, CRC, layouts) and its fields are
compared with the sensor model's Python methods on a twin vehicle (same seed); pymap3d checks the geodetic
conversion. Edge states (NaN, inf, saturation, truncation, float32 overflow, baro beyond the ISA model)
must encode or fail the way the codec does.
"""

from __future__ import annotations

import math

import numpy as np
import pymap3d
import pytest

from mavlink_bridge.contract.frames import DEG_E7, GRAVITY_M_S2, GeoPoint, LocalNedFrame
from mavlink_bridge.contract.geodetic import geodetic_from_ned
from mavlink_bridge.contract.wire import ObstacleDetection
from mavlink_bridge.lockstep import LockstepFrame
from mavlink_bridge.wire.codec import make_mavlink
from mavlink_bridge.wire.frame_writer import FrameWriter
from sim.frame_kernel import C_TRUTH_FRAME, SensorValues, frame_constants
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
    """A reference vehicle + sensor model (Python methods), and an identical pair behind the compiled path."""

    def __init__(self, world: World = OBSTACLE_WORLD, noise: bool = True, seed: int = 5) -> None:
        self.ref_sim = VehicleSim(X500, world=world, seed=seed)
        self.ref_sensors = SensorModel(X500, world.home, seed, noise=noise)
        self.sim = VehicleSim(X500, world=world, seed=seed)
        self.sensors = SensorModel(X500, world.home, seed, noise=noise)
        self.values = SensorValues(self.sim, self.sensors)
        self.writer = FrameWriter()

    def set_state(self, state: np.ndarray, specific_force_frd: np.ndarray | None = None) -> None:
        for sim in (self.ref_sim, self.sim):
            sim.batch.state[0] = state
            if specific_force_frd is not None:
                sim.batch.specific_force_frd[0] = specific_force_frd

    def step(self, motor_cmd: list[float]) -> None:
        self.ref_sim.step(motor_cmd)
        self.sim.step(motor_cmd)

    def datagram(self, detections: tuple[ObstacleDetection, ...] = ()) -> bytes:
        return self.writer.write(self.values.values, self.sim.t_us, self.values.fill(), detections)

    def frames(self, detections: tuple[ObstacleDetection, ...] = ()) -> tuple[LockstepFrame, bytes]:
        s, v = self.ref_sensors, self.ref_sim
        frame = LockstepFrame(s.imu_baro_mag(v), s.gps(v), v.ground_truth(), detections)
        return frame, self.datagram(detections)

    def assert_same_sensor_state(self) -> None:
        """Same next GPS time and GPS error; the same noise stream from here on."""
        a, b = self.ref_sensors, self.sensors
        assert a._counters[1] == b._counters[1]
        assert a._gps_error_ned_m.tolist() == b._gps_error_ned_m.tolist()
        assert a._take_noise(5000) == b._take_noise(5000)


def parse(datagram: bytes) -> list:  # type: ignore[type-arg]
    """pymavlink's messages of one datagram (it checks each CRC; anything it rejects fails the test)."""
    mav = make_mavlink(255, 0)
    messages = mav.parse_buffer(datagram) or []
    assert all(m.get_type() != "BAD_DATA" for m in messages), messages
    assert mav.total_receive_errors == 0
    return messages


def f32(x: float) -> float:
    return float(np.float32(x))


def degE7(x: float) -> int:
    return round(x * DEG_E7)


def assert_matches(frame: LockstepFrame, messages: list) -> None:  # type: ignore[type-arg]
    """The pymavlink-decoded datagram carries the reference frame's values (float32 exact, integers ±1)."""
    kinds = [m.get_type() for m in messages]
    expected = (["HIL_GPS"] if frame.gps is not None else []) + ["HIL_STATE_QUATERNION"]
    expected += ["OBSTACLE_DISTANCE_3D"] * len(frame.detections) + ["HIL_SENSOR"]
    assert kinds == expected
    by_kind = {m.get_type(): m for m in messages}
    s, t = frame.sensor, frame.truth
    hs = by_kind["HIL_SENSOR"]
    assert hs.time_usec == s.time_us and hs.fields_updated == 0x1BFF
    got = [hs.xacc, hs.yacc, hs.zacc, hs.xgyro, hs.ygyro, hs.zgyro, hs.xmag, hs.ymag, hs.zmag]
    assert got == [f32(x) for x in (*s.accel_frd_m_s2, *s.gyro_frd_rad_s, *s.mag_frd_gauss)]
    assert [hs.abs_pressure, hs.pressure_alt, hs.temperature] == [
        f32(s.abs_pressure_hpa),
        f32(s.pressure_alt_m),
        f32(s.temperature_degc),
    ]
    hq = by_kind["HIL_STATE_QUATERNION"]
    assert hq.time_usec == t.time_us
    assert list(hq.attitude_quaternion) == [f32(x) for x in t.q_ned_frd]
    assert [hq.rollspeed, hq.pitchspeed, hq.yawspeed] == [f32(x) for x in t.rate_frd_rad_s]
    assert abs(hq.lat - degE7(t.lat_deg)) <= 1 and abs(hq.lon - degE7(t.lon_deg)) <= 1
    assert abs(hq.alt - round(t.alt_amsl_m * 1000.0)) <= 1
    assert [hq.vx, hq.vy, hq.vz] == [round(x * 100.0) for x in t.vel_ned_m_s]
    mg = 1000.0 / GRAVITY_M_S2
    assert [hq.xacc, hq.yacc, hq.zacc] == [round(x * mg) for x in t.accel_frd_m_s2]
    if frame.gps is not None:
        g, hg = frame.gps, by_kind["HIL_GPS"]
        assert hg.time_usec == g.time_us and hg.fix_type == g.fix_type
        assert hg.satellites_visible == g.satellites_visible
        assert abs(hg.lat - degE7(g.lat_deg)) <= 1 and abs(hg.lon - degE7(g.lon_deg)) <= 1
        assert abs(hg.alt - round(g.alt_amsl_m * 1000.0)) <= 1
        assert [hg.vn, hg.ve, hg.vd] == [round(x * 100.0) for x in g.vel_ned_m_s]
        assert hg.eph == round(g.eph_m * 100.0) and hg.epv == round(g.epv_m * 100.0)
        vn, ve = g.vel_ned_m_s[0], g.vel_ned_m_s[1]
        assert abs(hg.vel - round(math.hypot(vn, ve) * 100.0)) <= 1
        if math.hypot(vn, ve) > 0.05:
            cog = round(math.degrees(math.atan2(ve, vn)) * 100.0) % 36000
            assert min(abs(hg.cog - cog), 36000 - abs(hg.cog - cog)) <= 1
    for d, m in zip(frame.detections, [m for m in messages if m.get_type() == "OBSTACLE_DISTANCE_3D"], strict=True):
        assert m.time_boot_ms == d.time_us // 1000 and m.obstacle_id == d.obstacle_id
        assert [m.x, m.y, m.z] == [f32(x) for x in d.pos_frd_m] and m.max_distance == f32(d.radius_m)
        assert m.sensor_type == int(d.shape) and m.frame == 12


def _state(**fields: object) -> np.ndarray:
    """A 17-state row: hover at 10 m, level, with overrides by slice name."""
    x = np.zeros(17)
    x[2] = -10.0
    x[6] = 1.0
    slices = {"pos": slice(0, 3), "vel": slice(3, 6), "q": slice(6, 10), "rate": slice(10, 13)}
    for name, value in fields.items():
        x[slices[name]] = value
    return x


def test_flight_with_noise_gps_and_detections_matches_the_sensor_model() -> None:
    twins = Twins()
    twins.set_state(_state(pos=[0.0, 0.0, -2.0]))
    obstacle_sensor = ObstacleSensor(OBSTACLE_WORLD, seed=5)
    hover = twins.sim.hover_omega_rad_s() / X500.omega_max_rad_s
    gps_frames = detection_frames = 0
    seqs = []
    for k in range(400):
        v = twins.ref_sim
        detections = tuple(obstacle_sensor.detect(v.pos_ned, v.q_ned_frd, v.t_us)) if k % 25 == 0 else ()
        frame, datagram = twins.frames(detections)
        messages = parse(datagram)
        assert_matches(frame, messages)
        seqs += [m.get_seq() for m in messages]
        gps_frames += frame.gps is not None
        detection_frames += bool(detections)
        phase = 0.3 * math.sin(k / 15.0)
        twins.step([hover * (1.02 + 0.02 * phase), hover * (1.0 - 0.02 * phase), hover * 1.01, hover * 1.0])
    twins.assert_same_sensor_state()
    assert gps_frames == 16 and detection_frames >= 5
    assert seqs == [k % 256 for k in range(len(seqs))]  # one sequence counter over all messages
    assert np.array_equal(twins.ref_sim.batch.state, twins.sim.batch.state)


@pytest.mark.parametrize(
    ("name", "state", "specific_force"),
    [
        ("nan position", _state(pos=[math.nan, 1.0, -5.0]), None),
        ("inf velocity", _state(vel=[math.inf, -math.inf, math.inf]), [math.inf, -math.inf, 0.0]),
        ("saturated velocity and accel", _state(vel=[400.0, -400.0, 1e6]), [1e4, -1e4, 5e5]),
        ("far away (lat/lon/alt saturate)", _state(pos=[3e6, -4e6, -3e4]), None),
        ("zero velocity, zero force (cog unknown, truncation)", _state(), [0.0, 0.0, 0.0]),
    ],
)
def test_edge_states_encode_like_the_codec(name: str, state: np.ndarray, specific_force: list[float] | None) -> None:
    twins = Twins(noise=False)
    twins.set_state(state, None if specific_force is None else np.asarray(specific_force, dtype=float))
    hq, hg = None, None
    for m in parse(twins.datagram()):  # the first frame has the GPS fix due at t = 0
        hq = m if m.get_type() == "HIL_STATE_QUATERNION" else hq
        hg = m if m.get_type() == "HIL_GPS" else hg
    assert hq is not None and hg is not None, name
    ints = [hq.lat, hq.lon, hq.alt, hq.vx, hq.vy, hq.vz, hq.xacc, hq.yacc, hq.zacc, hg.lat, hg.lon, hg.alt]
    assert all(isinstance(x, int) for x in ints)
    for x in (hq.vx, hq.vy, hq.vz, hq.xacc, hq.yacc, hq.zacc, hg.vn, hg.ve, hg.vd):
        assert -32768 <= x <= 32767  # saturated, never wrapped
    if not all(math.isfinite(x) for x in state[3:6]):
        assert [hq.vx, hq.vy, hq.vz][2] in (0, 32767)  # NaN -> 0, inf -> the wire maximum
    if not np.any(state[3:5]):
        assert hg.cog == 0xFFFF  # course unknown at rest


def test_truncation_drops_trailing_zeros_like_the_codec() -> None:
    twins = Twins(noise=False)
    twins.set_state(_state(pos=[0.0, 0.0, 0.0]), np.zeros(3))
    datagram = twins.datagram()
    parse(datagram)
    # the truth message ends with three zero accelerations and two equal speeds of 0: truncated
    assert len(datagram) < 3 * 12 + 39 + 64 + 65


def test_float32_overflow_raises_like_struct_pack() -> None:
    twins = Twins()
    twins.set_state(_state(rate=[1e39, 0.0, 0.0]))
    with pytest.raises(OverflowError):
        twins.datagram()


def test_baro_beyond_the_isa_model_raises() -> None:
    twins = Twins(noise=False)
    twins.set_state(_state(pos=[0.0, 0.0, -5e4]))
    with pytest.raises(ValueError):
        twins.datagram()


def test_geodetic_kernel_matches_pymap3d() -> None:
    rng = np.random.default_rng(2)
    for home in (GeoPoint(47.397742, 8.545594, 488.0), GeoPoint(-33.9, 151.2, 5.0), GeoPoint(89.0, -170.0, 3000.0)):
        frame = LocalNedFrame(home)
        c = np.zeros(C_TRUTH_FRAME + 12)
        c[C_TRUTH_FRAME:] = frame_constants(frame)
        for n, e, d in (rng.standard_normal((500, 3)) * [2000.0, 2000.0, 300.0]).tolist():
            lat, lon, alt = geodetic_from_ned(c, C_TRUTH_FRAME, n, e, d)
            ref_lat, ref_lon, ref_alt = pymap3d.ned2geodetic(n, e, d, home.lat_deg, home.lon_deg, home.alt_amsl_m)
            assert lat == pytest.approx(ref_lat, abs=1e-9) and alt == pytest.approx(ref_alt, abs=1e-4)
            assert (lon - ref_lon + 180.0) % 360.0 - 180.0 == pytest.approx(0.0, abs=1e-9)
