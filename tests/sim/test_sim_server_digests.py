"""The one simulator server flies what the two it replaced flew: fixed truth digests of single-vehicle and fleet
flights over loopback, recorded from the code before ``sim.fleet_server`` was merged into ``sim.server`` (commit
51a0bc0: the single-vehicle ``SimServer`` over ``VehicleSim`` and the fleet's ``FleetServer``).

The single-vehicle law reads the sensors, GPS and obstacle detections as well as the truth, so a changed seed,
sensor stream, detection timing or datagram would change the flight and its digest."""

from __future__ import annotations

import hashlib
import threading
from pathlib import Path

import numpy as np
from test_sim_fleet import FLEET_YAML, _run_fleet

from mavlink_bridge.contract.wire import ActuatorCommand
from mavlink_bridge.lockstep import LockstepClient, LockstepFrame
from sim.server import SimConfig, SimServer
from sim.summary_file import SimSummary

BUSY_WORLD = """\
home: {lat_deg: 30.0, lon_deg: 120.0, alt_m: 5.0}
world:
  payload_kg: 0.5
  wind: {north_m_s: 2.0, gust_m_s: 1.5, seed: 3}
  obstacles:
    - cylinder: {north_m: 8, east_m: 0, radius_m: 1, height_m: 20}
    - box: {north_m: -6, east_m: 3, size_m: [2, 2, 10]}
"""


class SensingLaw:
    """A climb law on the true vertical speed nudged by the accelerometer, GPS and detections."""

    def __init__(self, gripper_at_s: float | None = None) -> None:
        self.integral = 0.0
        self.gripper_at_s = gripper_at_s

    def __call__(self, f: LockstepFrame) -> ActuatorCommand:
        err = f.truth.vel_ned_m_s[2] + 1.0
        self.integral += 0.5 * err / 250.0
        u = 0.75 + 0.25 * err + self.integral + 1e-3 * (f.sensor.accel_frd_m_s2[2] + 9.8) + 1e-3 * len(f.detections)
        if f.gps is not None:
            u += 1e-4 * f.gps.lat_deg % 1e-4
        for d in f.detections:
            u += 1e-4 * d.pos_frd_m[0]
        u = min(1.0, max(0.0, u))
        release = self.gripper_at_s is not None and f.time_us >= self.gripper_at_s * 1e6
        return ActuatorCommand(f.time_us, (u, u, u * 0.999, u), True, release)


def _fly(tmp_path: Path, world_yaml: str | None, law: SensingLaw, **kw: object) -> SimSummary:
    world = None
    if world_yaml is not None:
        world = tmp_path / "world.yaml"
        world.write_text(world_yaml)
    server = SimServer(SimConfig(listen_url="udpin:127.0.0.1:0", world_path=world, **kw))  # type: ignore[arg-type]
    host, port = server.local_address
    result: list = []
    thread = threading.Thread(target=lambda: result.append(server.run()), daemon=True)
    thread.start()
    with LockstepClient(f"udpout:{host}:{port}", heartbeat_period_s=0.02) as client:
        while thread.is_alive():
            frame = client.next_frame(0.05)
            if frame is not None:
                client.answer(law(frame))
    thread.join()
    assert isinstance(result[0], SimSummary)
    return result[0]


def test_an_empty_world_flies_the_old_single_vehicle_digest(tmp_path: Path) -> None:
    s = _fly(tmp_path, None, SensingLaw(), duration_s=1.0, seed=0)
    assert (s.end_reason, s.frames, s.min_clearance_m) == ("COMPLETED", 250, None)
    assert s.truth_sha256 == "0cbf8e004ce539f8f437e5aef4b237ffde2bddcf63278071908aa1f83cbc3cf9"
    assert s.max_tilt_deg == 3.705830447118675
    assert s.final_pos_ned_m == (0.04001060519439567, -0.03995256838700539, -0.9620435797830327)


def test_obstacles_gusts_and_a_payload_fly_the_old_single_vehicle_digest(tmp_path: Path) -> None:
    s = _fly(tmp_path, BUSY_WORLD, SensingLaw(gripper_at_s=0.6), duration_s=1.5, seed=7)
    assert (s.end_reason, s.frames, s.payload_released_at_s) == ("COMPLETED", 375, 0.6)
    assert s.truth_sha256 == "f068a2c18509149cddd7ecd11bc3dd539a82c38808cb3440adb428a755b3427f"
    assert s.min_clearance_m == 5.385164807134504 and s.max_tilt_deg == 9.20953746638949


def test_noiseless_sensors_and_the_truth_log_keep_their_old_digests(tmp_path: Path) -> None:
    log = tmp_path / "truth.npz"
    s = _fly(tmp_path, BUSY_WORLD, SensingLaw(), duration_s=0.5, seed=123456789, sensor_noise=False, truth_log=log)
    assert s.truth_sha256 == "d3f2a226458dcf1a2c0c4b91fae16f26a68a45c96823d6d15b3bb382d01ed7e0"
    data = np.load(log)
    assert data["state"].shape == (125, 17)
    assert hashlib.sha256(data["state"].tobytes()).hexdigest() == s.truth_sha256  # the same rows, hashed alike
    assert hashlib.sha256(data["t_s"].tobytes()).hexdigest() == (
        "67b845e31c70d8e097f3b78dbd234c085686ced24c9f1af0cb737ba088ce4e99"
    )


def test_a_fleet_keeps_its_per_vehicle_digests(tmp_path: Path) -> None:
    """The gusty pair of ``test_sim_fleet`` (seed 3, fixed motors): the old ``FleetServer``'s hashes."""
    path = tmp_path / "fleet.yaml"
    path.write_text(FLEET_YAML + "world: {wind: {gust_m_s: 2.0}}\n")
    summary, _ = _run_fleet(path, [{"motors": 0.75}, {"motors": 0.72}], 1.0, seed=3)
    assert [v.truth_sha256 for v in summary.vehicles] == [
        "5351b51d3146eee87e158c5654a6b8e0b1cfc9a3d7f07a614371bf8417e66fb5",
        "65e09f18d018686b015ee13ad8072fe9b5ccf8e1d9df554c27cd182e64f9ccf3",
    ]
