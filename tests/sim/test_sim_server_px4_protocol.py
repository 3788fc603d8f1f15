"""Issue 4 must-show: ``python -m sim`` works with any autopilot that speaks PX4's simulator protocol.

The autopilot here is a minimal script in plain pymavlink (no project code), run as its own
process: HEARTBEAT, then one HIL_ACTUATOR_CONTROLS per HIL_SENSOR. It flies a PI loop on the
vertical speed from HIL_STATE_QUATERNION (climb, hover), yaws with differential CCW/CW commands
and cuts the motors (free fall). The sim is stopped with SIGTERM and must write its summary.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
from pathlib import Path

import pytest

from tests.conftest import REPO_ROOT, free_udp_port

MINIMAL_PX4_AUTOPILOT = r'''
import json, math, os, sys, time
os.environ["MAVLINK20"] = "1"
from pymavlink import mavutil

port, mode = int(sys.argv[1]), sys.argv[2]
stop_answering_at_s = float(sys.argv[3]) if len(sys.argv) > 3 else math.inf
conn = mavutil.mavlink_connection(
    f"udpout:127.0.0.1:{port}", source_system=1, source_component=1, dialect="common"
)
mav = conn.mav
home_alt_mm = None
alt_m = vz = yaw = yawspeed = zacc_mg = 0.0
integ = 0.0
samples = {}
last_rx = time.monotonic()
last_hb = 0.0
started = False
t_start = time.monotonic()
last_answered_us = -1
m = (0.0, 0.0, 0.0, 0.0)


def vz_loop(vz_sp, dt):
    """PI on NED vertical speed -> collective motor command (u in [0, 1])."""
    global integ
    err = vz - vz_sp  # sinking faster than wanted -> more thrust
    integ = max(-0.3, min(0.3, integ + 0.5 * err * dt))
    return max(0.0, min(1.0, 0.7 + 0.25 * err + integ))


while True:
    now = time.monotonic()
    if not started and now - t_start > 60.0:
        sys.exit("no HIL_SENSOR from the sim within 60 s")
    if not started and now - last_hb > 0.2:
        mav.heartbeat_send(mavutil.mavlink.MAV_TYPE_QUADROTOR, mavutil.mavlink.MAV_AUTOPILOT_PX4, 0, 0, 0)
        last_hb = now
    msg = conn.recv_match(type=["HIL_STATE_QUATERNION", "HIL_SENSOR"], blocking=True, timeout=0.1)
    if msg is None:
        if started and time.monotonic() - last_rx > 2.0:
            break  # the sim is gone
        continue
    last_rx = time.monotonic()
    if msg.get_type() == "HIL_STATE_QUATERNION":
        if home_alt_mm is None:
            home_alt_mm = msg.alt
        alt_m = (msg.alt - home_alt_mm) / 1000.0
        vz = msg.vz / 100.0
        w, x, y, z = msg.attitude_quaternion
        yaw = math.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))
        yawspeed = msg.yawspeed
        zacc_mg = msg.zacc
        continue
    started = True
    if msg.time_usec <= last_answered_us:  # a re-sent frame (the sim's answer was late or lost): same answer,
        if msg.time_usec == last_answered_us:  # no second controller step (that would break determinism)
            mav.hil_actuator_controls_send(msg.time_usec, list(m) + [0.0] * 12, 128, 1)
        continue
    t = msg.time_usec / 1e6
    if t >= stop_answering_at_s:
        break  # the autopilot vanishes
    dt = 1.0 / 250.0
    if t < 5.0 or mode == "steady":  # climb to 3 m, then hold altitude
        u = vz_loop(-1.5 if alt_m < 2.5 else 1.0 * (alt_m - 3.0), dt)
        m = (u, u, u, u)
        if 4.5 <= t < 5.0:
            samples.setdefault("hover_vz", []).append(vz)
            samples.setdefault("hover_alt", []).append(alt_m)
    elif t < 6.0:  # yaw: CCW rotors (0, 1) faster than CW rotors (2, 3)
        u = vz_loop(0.0, dt)
        m = (u + 0.05, u + 0.05, u - 0.05, u - 0.05)
        samples.setdefault("yaw", []).append((yaw, yawspeed))
    elif t < 7.0:  # and back
        u = vz_loop(0.0, dt)
        m = (u - 0.05, u - 0.05, u + 0.05, u + 0.05)
        samples.setdefault("yaw_back", []).append(yawspeed)
    elif t < 7.5:  # motors cut: free fall
        m = (0.0, 0.0, 0.0, 0.0)
        if t >= 7.15:
            samples.setdefault("fall", []).append((t, vz, zacc_mg))
    else:  # report and stop answering (the test then stops the sim with SIGTERM)
        print(json.dumps(samples), flush=True)
        break
    mav.hil_actuator_controls_send(msg.time_usec, list(m) + [0.0] * 12, 128, 1)
    last_answered_us = msg.time_usec
'''


def start_sim(port: int, log_dir: Path, *extra: str) -> subprocess.Popen[str]:
    cmd = [sys.executable, "-m", "sim", "--listen", f"udp:127.0.0.1:{port}", "--log-dir", str(log_dir), *extra]
    return subprocess.Popen(cmd, cwd=REPO_ROOT, stderr=subprocess.PIPE, text=True)


def start_minimal_autopilot(port: int, mode: str, *extra: str) -> subprocess.Popen[str]:
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}  # plain pymavlink, no project code
    return subprocess.Popen(
        [sys.executable, "-c", MINIMAL_PX4_AUTOPILOT, str(port), mode, *extra],
        cwd="/",
        env=env,
        stdout=subprocess.PIPE,
        text=True,
    )


def read_summary(log_dir: Path) -> dict:
    return json.loads((log_dir / "sim_summary.json").read_text())


@pytest.mark.slow
def test_minimal_pymavlink_autopilot_flies_free_fall_hover_and_yaw(tmp_path: Path) -> None:
    port = free_udp_port()
    sim = start_sim(port, tmp_path, "--speed", "max", "--autopilot-timeout-s", "60", "--seed", "3")
    pilot = start_minimal_autopilot(port, "flight")
    try:
        out, _ = pilot.communicate(timeout=120)  # the pilot stops answering at t = 7.5 s sim time
    finally:
        sim.send_signal(signal.SIGTERM)  # the sim is waiting for an answer: SIGTERM must still end it cleanly
        _, sim_err = sim.communicate(timeout=60)
        if pilot.poll() is None:
            pilot.kill()
    assert pilot.returncode == 0 and out, sim_err
    samples = json.loads(out)
    assert sim.returncode == 0, sim_err
    summary = read_summary(tmp_path)
    assert summary["end_reason"] == "STOPPED" and summary["autopilot_connected"] is True
    assert summary["sim_time_s"] == pytest.approx(7.5) and summary["frames"] == 7.5 * 250
    assert summary["collisions"] == 0 and summary["real_time_factor"] > 0.0

    # hover: a PI loop on vz holds 3 m; the vertical speed stays near zero
    assert max(abs(v) for v in samples["hover_vz"]) < 0.15
    assert min(samples["hover_alt"]) > 2.7 and max(samples["hover_alt"]) < 3.3
    # yaw: CCW rotors faster -> positive (clockwise from above, FRD) yaw rate and growing yaw; then reversed
    yaw, yawspeed = zip(*samples["yaw"], strict=True)
    assert yawspeed[-1] > 0.3 and all(r >= -1e-3 for r in yawspeed)
    assert yaw[-1] - yaw[0] > 0.1
    assert samples["yaw_back"][-1] < yawspeed[-1] - 0.3
    # free fall: motors off -> the accelerometer reads ~0 g (only drag; -1000 mG while hovering) and the
    # vehicle accelerates down at g + specific force (Newton in NED, body level)
    t, vz, zacc_mg = zip(*samples["fall"], strict=True)
    assert max(abs(a) for a in zacc_mg) < 150
    accel_down = (vz[-1] - vz[0]) / (t[-1] - t[0])
    mean_specific_force_z = 9.80665 * sum(zacc_mg) / len(zacc_mg) / 1000.0
    assert accel_down == pytest.approx(9.80665 + mean_specific_force_z, abs=0.25)
    assert accel_down > 9.0
    assert summary["max_tilt_deg"] < 2.0


@pytest.mark.slow
def test_vanished_autopilot_is_reported_not_waited_on(tmp_path: Path) -> None:
    port = free_udp_port()
    sim = start_sim(port, tmp_path, "--speed", "max", "--autopilot-timeout-s", "0.5")
    pilot = start_minimal_autopilot(port, "lost", "0.4")  # answers 0.4 s of sim time, then exits
    try:
        _, sim_err = sim.communicate(timeout=60)
    finally:
        pilot.kill()
        pilot.wait(10)
        if sim.poll() is None:
            sim.kill()
    assert sim.returncode == 3, sim_err
    summary = read_summary(tmp_path)
    assert summary["end_reason"] == "AUTOPILOT_LOST"
    assert summary["sim_time_s"] == pytest.approx(0.4, abs=1e-9)
    assert summary["resends"] > 0


WINDY_WORLD = """
name: gusty_field
home: {lat_deg: 30.2635, lon_deg: 120.1233, alt_m: 12.0}
world:
  wind: {north_m_s: 1.5, east_m_s: -0.5, gust_m_s: 1.0, seed: 7}
"""


def start_steady(tmp_path: Path, name: str, speed: str, seed: int) -> tuple[subprocess.Popen[str], ...]:
    """Start 1 s of climb in gusty wind with the minimal autopilot (sim, pilot)."""
    world = tmp_path / "gusty.yaml"
    world.write_text(WINDY_WORLD)
    port = free_udp_port()
    args = ("--speed", speed, "--seed", str(seed), "--world", str(world), "--duration-s", "1")
    sim = start_sim(port, tmp_path / name, *args)
    return sim, start_minimal_autopilot(port, "steady")


def finish_steady(tmp_path: Path, name: str, sim: subprocess.Popen[str], pilot: subprocess.Popen[str]) -> dict:
    """Wait for the sim to end by itself (--duration-s); its summary."""
    try:
        _, sim_err = sim.communicate(timeout=120)
    finally:
        pilot.kill()
        pilot.wait(10)
        if sim.poll() is None:
            sim.kill()
    assert sim.returncode == 0, sim_err
    summary = read_summary(tmp_path / name)
    assert summary["end_reason"] == "COMPLETED" and summary["sim_time_s"] == 1.0
    return summary


@pytest.mark.slow
def test_same_seed_bit_identical_at_max_speed_and_real_time(tmp_path: Path) -> None:
    runs = {"max": ("max", 11), "rt": ("1", 11), "other": ("max", 12)}
    procs = {name: start_steady(tmp_path, name, speed, seed) for name, (speed, seed) in runs.items()}  # in parallel
    fast, paced, other = (finish_steady(tmp_path, name, *procs[name]) for name in runs)
    assert fast["truth_sha256"] == paced["truth_sha256"]
    assert fast["final_pos_ned_m"] == paced["final_pos_ned_m"]
    assert other["truth_sha256"] != fast["truth_sha256"]  # the seed drives the gusts: the check has teeth
    assert fast["final_pos_ned_m"][2] < -0.05  # it did fly
    assert paced["wall_time_s"] >= 0.99  # --speed 1 paces to the wall clock (a lower bound, not a timing)


def test_sigint_while_waiting_for_the_autopilot_writes_a_summary(tmp_path: Path) -> None:
    sim = start_sim(free_udp_port(), tmp_path, "-v")
    assert sim.stderr is not None
    assert "waiting for the autopilot" in sim.stderr.readline()  # started and listening
    sim.send_signal(signal.SIGINT)
    _, err = sim.communicate(timeout=30)
    assert sim.returncode == 0, err
    summary = read_summary(tmp_path)
    assert summary["end_reason"] == "STOPPED" and summary["sim_time_s"] == 0.0
    assert summary["autopilot_connected"] is False
