"""SimServer in-process (thread) against the project's LockstepClient: commands, payload, detections, stop, logs."""

from __future__ import annotations

import threading
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from mavlink_bridge.contract.wire import ActuatorCommand, ObstacleShape
from mavlink_bridge.lockstep import DEFAULT_SPIN_S, LockstepClient, LockstepFrame
from mavlink_bridge.wire.link import LinkUrlError
from mavlink_bridge.wire.lossy import LossProfile, LossyUdpProxy
from sim.cli import (
    EXIT_AUTOPILOT_LOST,
    EXIT_OK,
    EXIT_USAGE,
    EXIT_VEHICLE_ENDED,
    build_parser,
    config_from_args,
    exit_code,
    main,
)
from sim.fleet import tilt_deg
from sim.server import SimConfig, SimServer, SimSetupError
from sim.summary_file import SimSummary

Law = Callable[[LockstepFrame], ActuatorCommand]


def fly(config: SimConfig, law: Law, loss: LossProfile | None = None) -> tuple[SimSummary, list[LockstepFrame]]:
    """Run the sim in a thread; answer every frame with ``law`` until the sim stops (optionally via a lossy relay)."""
    server = SimServer(config)
    host, port = server.local_address
    proxy = LossyUdpProxy((host, port), loss).start() if loss else None
    if proxy:
        host, port = proxy.listen_address
    result: list[SimSummary] = []
    thread = threading.Thread(target=lambda: result.append(server.run()), daemon=True)  # type: ignore[arg-type]
    thread.start()
    frames: list[LockstepFrame] = []
    with LockstepClient(f"udpout:{host}:{port}", heartbeat_period_s=0.02) as client:
        while thread.is_alive():
            frame = client.next_frame(0.05)
            if frame is not None:
                frames.append(frame)
                client.answer(law(frame))
    thread.join()
    if proxy:
        proxy.stop()
    return result[0], frames


def config(tmp_path: Path, world_yaml: str | None = None, **kw: object) -> SimConfig:
    world = None
    if world_yaml is not None:
        world = tmp_path / "world.yaml"
        world.write_text(world_yaml)
    base = {"listen_url": "udpin:127.0.0.1:0", "duration_s": 0.5, "world_path": world, "sensor_noise": False}
    return SimConfig(**{**base, **kw})  # type: ignore[arg-type]


def full_throttle(armed: bool, gripper_at_s: float = np.inf) -> Law:
    return lambda f: ActuatorCommand(f.time_us, (1.0, 1.0, 1.0, 1.0), armed, f.time_us >= gripper_at_s * 1e6)


def test_armed_full_throttle_climbs_and_disarmed_stays_on_the_ground(tmp_path: Path) -> None:
    armed, frames = fly(config(tmp_path), full_throttle(True))
    disarmed, _ = fly(config(tmp_path), full_throttle(False))
    assert armed.end_reason == disarmed.end_reason == "COMPLETED"
    assert armed.sim_time_s == 0.5 and armed.frames == 125 == len(frames)
    assert armed.final_pos_ned_m[2] < -0.5  # climbing (NED z up is negative)
    assert disarmed.final_pos_ned_m == (0.0, 0.0, 0.0)
    assert [f.time_us for f in frames] == [k * 4000 for k in range(125)]
    assert [f.gps is not None for f in frames] == [k % 25 == 0 for k in range(125)]  # 10 Hz GPS
    assert frames[0].truth.q_ned_frd == (1.0, 0.0, 0.0, 0.0)


def test_non_finite_or_out_of_range_commands_are_never_applied(tmp_path: Path) -> None:
    for motors in ((np.nan, np.inf, -np.inf, np.nan), (1.5, 1.0, 1.0, 1.0), (1.0, 1.0, 1.0, -0.1)):
        law: Law = lambda f, u=motors: ActuatorCommand(f.time_us, u, True)  # type: ignore[misc]  # noqa: E731
        summary, frames = fly(config(tmp_path, autopilot_timeout_s=0.3), law)
        # the answer is dropped at the edge and the frame re-sent until the autopilot counts as lost: no crash,
        # no step integrated with the bad command
        assert summary.end_reason == "AUTOPILOT_LOST" and summary.final_pos_ned_m == (0.0, 0.0, 0.0)
        assert summary.frames == 0 and summary.invalid_answers > 0 and len(frames) == 1


def test_gripper_release_drops_the_payload_once(tmp_path: Path) -> None:
    world = "home: {lat_deg: 30.0, lon_deg: 120.0, alt_m: 5.0}\nworld: {payload_kg: 0.5}\n"
    summary, _ = fly(config(tmp_path, world, duration_s=0.4), full_throttle(True, gripper_at_s=0.2))
    assert summary.payload_released_at_s == pytest.approx(0.2)
    kept, _ = fly(config(tmp_path, world, duration_s=0.4), full_throttle(True))
    assert kept.payload_released_at_s is None
    assert summary.final_pos_ned_m[2] < kept.final_pos_ned_m[2]  # lighter after the drop: climbs faster


def test_obstacle_detections_reach_the_autopilot_at_the_sensor_rate(tmp_path: Path) -> None:
    world = "world:\n  obstacles:\n    - cylinder: {north_m: 8, east_m: 0, radius_m: 1, height_m: 20}\n"
    summary, frames = fly(config(tmp_path, world, duration_s=0.3), full_throttle(False))
    with_detections = [k for k, f in enumerate(frames) if f.detections]
    assert with_detections == [0, 25, 50]  # 10 Hz at 250 Hz frames
    d = frames[0].detections[0]
    assert d.obstacle_id == 0 and d.shape is ObstacleShape.CYLINDER
    assert d.pos_frd_m[0] == pytest.approx(7.0, abs=0.3) and d.radius_m == pytest.approx(1.0, abs=0.1)
    assert summary.min_clearance_m == pytest.approx(7.0, abs=0.4)


def test_stop_while_waiting_for_the_heartbeat_does_not_advance_time(tmp_path: Path) -> None:
    server = SimServer(config(tmp_path, duration_s=None))
    result: list[SimSummary] = []
    thread = threading.Thread(target=lambda: result.append(server.run()), daemon=True)
    thread.start()
    server.request_stop()
    thread.join(10.0)
    assert not thread.is_alive()
    assert result[0].end_reason == "STOPPED" and result[0].sim_time_s == 0.0
    assert result[0].autopilot_connected is False and result[0].frames == 0


def test_truth_log_and_summary_file(tmp_path: Path) -> None:
    log = tmp_path / "truth.npz"
    summary, _ = fly(config(tmp_path, truth_log=log), full_throttle(True))
    data = np.load(log)
    assert data["state"].shape == (125, 17) and data["t_s"][-1] == pytest.approx(0.5)
    assert tuple(data["state"][-1, 0:3]) == summary.final_pos_ned_m
    path = summary.write(tmp_path / "logs")
    text = path.read_text()
    for key in ("end_reason", "sim_time_s", "wall_time_s", "real_time_factor", "collisions", "min_clearance_m"):
        assert f'"{key}"' in text
    assert '"payload_released_at_s": null' in text and '"max_tilt_deg"' in text
    # where the wall time went: the sim's own work plus the answer waits is all of it (no pacing at max speed)
    assert summary.frames == 125 and summary.answer_wait_us > 0.0 and summary.sim_cpu_us_per_step > 0.0
    assert (summary.sim_step_us + summary.answer_wait_us) * summary.frames == pytest.approx(summary.wall_time_s * 1e6)


def test_tilt_from_quaternion() -> None:
    assert tilt_deg(np.array([1.0, 0.0, 0.0, 0.0])) == 0.0
    half = np.radians(30.0) / 2
    assert tilt_deg(np.array([np.cos(half), np.sin(half), 0.0, 0.0])) == pytest.approx(30.0)
    assert tilt_deg(np.array([np.cos(half), 0.0, 0.0, np.sin(half)])) == pytest.approx(0.0, abs=1e-6)  # pure yaw


def test_cli_options_instance_offset_and_errors(tmp_path: Path) -> None:
    parser = build_parser()
    cfg = config_from_args(parser.parse_args(["--instance", "3", "--speed", "2.5", "--seed", "9"]))
    assert cfg.listen_url == "udpin:127.0.0.1:14563" and cfg.speed == 2.5 and cfg.seed == 9
    cfg = config_from_args(parser.parse_args(["--listen", "udp:127.0.0.1:15000", "--speed", "max"]))
    assert cfg.listen_url == "udpin:127.0.0.1:15000" and cfg.speed is None
    with pytest.raises(LinkUrlError):
        config_from_args(parser.parse_args(["--listen", "udpout:127.0.0.1:15000"]))
    with pytest.raises(SystemExit):
        parser.parse_args(["--speed", "0"])
    assert config_from_args(parser.parse_args([])).lockstep_spin_s == pytest.approx(DEFAULT_SPIN_S)
    assert config_from_args(parser.parse_args(["--lockstep-spin-us", "0"])).lockstep_spin_s == 0.0
    with pytest.raises(SystemExit):
        parser.parse_args(["--lockstep-spin-us", "-5"])
    assert main(["--world", str(tmp_path / "missing.yaml"), "--listen", "udp:127.0.0.1:0"]) == EXIT_USAGE
    assert main(["--vehicle", "no_such_vehicle", "--listen", "udp:127.0.0.1:0"]) == EXIT_USAGE
    with pytest.raises(SimSetupError):
        SimServer(SimConfig(listen_url="udpin:127.0.0.1:0", speed=-1.0))
    assert exit_code("COMPLETED") == exit_code("STOPPED") == EXIT_OK
    assert exit_code("AUTOPILOT_LOST") == EXIT_AUTOPILOT_LOST
    assert exit_code("COLLISION") == exit_code("GROUND_IMPACT") == EXIT_VEHICLE_ENDED


class VzHold:
    """A stateful PI law on the true vertical speed: any lost or doubled answer would change the flight."""

    def __init__(self) -> None:
        self.integral = 0.0

    def __call__(self, f: LockstepFrame) -> ActuatorCommand:
        err = f.truth.vel_ned_m_s[2] + 1.0  # climb at 1 m/s
        self.integral += 0.5 * err / 250.0
        u = min(1.0, max(0.0, 0.75 + 0.25 * err + self.integral))
        return ActuatorCommand(f.time_us, (u, u, u, u), True)


def test_lossy_link_flight_is_identical_in_sim_time(tmp_path: Path) -> None:
    world = "world:\n  wind: {north_m_s: 2.0, gust_m_s: 1.0, seed: 3}\n"
    clean, _ = fly(config(tmp_path, world, duration_s=1.0, seed=4), VzHold())
    loss = LossProfile(drop_p=0.1, duplicate_p=0.05, reorder_p=0.05, hold_s=0.01, seed=1)
    lossy, frames = fly(config(tmp_path, world, duration_s=1.0, seed=4, resend_timeout_s=0.01), VzHold(), loss)
    assert lossy.resends > 0 and len(frames) == 250  # each frame reached the law exactly once
    assert lossy.truth_sha256 == clean.truth_sha256
    assert lossy.final_pos_ned_m == clean.final_pos_ned_m and clean.final_pos_ned_m[2] < -0.2
