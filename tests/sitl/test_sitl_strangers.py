"""A stranger on both lockstep ports of a real SITL pair: well-formed frames with future and 2^63 µs stamps, NaN
attitude, spoofed actuator answers (NaN, out of range, right time stamps) and HEARTBEATs. The flight is
bit-identical to an undisturbed one (same truth hashes in both processes) and both summaries count the strangers."""

from __future__ import annotations

import math
import os
import re
import socket
import threading
import time
from pathlib import Path

import pytest
from sitl_procs import Ports, logs, read_json, start_autopilot, start_sim, stop

from mavlink_bridge.contract.wire import ActuatorCommand, GroundTruth, SensorSample
from mavlink_bridge.lockstep import LockstepFrame, encode_frame
from mavlink_bridge.wire.codec import SIM_COMPONENT_ID, SIM_SYSTEM_ID, Encoder, Heartbeat

pytestmark = [pytest.mark.sitl, pytest.mark.slow]

#: The EKF is healthy 1.5 s after start: the script arms at 2 s.
SCRIPT = """
- {at_s: 2.0, cmd: arm}
- {at_s: 2.1, cmd: takeoff, alt_m: 5}
- {at_s: 3.5, cmd: goto, north_m: 3, east_m: 1, alt_m: 6}
"""
DURATION_S = 5.0


def _udp_ports_of(pid: int) -> set[int]:
    """The local ports of the UDP sockets process ``pid`` holds (Linux /proc)."""
    inodes = set()
    for fd in Path(f"/proc/{pid}/fd").iterdir():
        try:
            match = re.fullmatch(r"socket:\[(\d+)\]", os.readlink(fd))
        except OSError:
            continue
        if match:
            inodes.add(match.group(1))
    ports = set()
    for line in Path("/proc/net/udp").read_text().splitlines()[1:]:
        cols = line.split()
        if cols[9] in inodes:
            ports.add(int(cols[1].split(":")[1], 16))
    return ports


def _hostile_frames() -> list[bytes]:
    """Well-formed lockstep frames a simulator would never send."""
    enc = Encoder(SIM_SYSTEM_ID, SIM_COMPONENT_ID)
    out = []
    for t_us, q in ((3_600_000_000, (1.0, 0.0, 0.0, 0.0)), (2**63, (1.0, 0.0, 0.0, 0.0)), (4000, (math.nan,) * 4)):
        sensor = SensorSample(t_us, (0.0, 0.0, -9.8), (0.0, 0.0, 0.0), (0.2, 0.0, 0.4), 1013.0, 1.0, 20.0)
        truth = GroundTruth(t_us, q, (0.0, 0.0, 0.0), 47.0, 8.0, 400.0, (0.0, 0.0, 0.0), (0.0, 0.0, -9.8))
        out.append(encode_frame(enc, LockstepFrame(sensor, None, truth)))
    return out


def _spoofed_answers(enc: Encoder, k: int) -> list[bytes]:
    """Actuator answers for the frames around step ``k`` (the right time stamps), NaN and full throttle."""
    t = k * 4000
    return [
        enc.actuators(ActuatorCommand(t, (math.nan,) * 4, True)),
        enc.actuators(ActuatorCommand(t, (1.0, 0.0, 1.0, 0.0), True)),
        enc.actuators(ActuatorCommand(t + 4000, (2.0, 2.0, 2.0, 2.0), True, True)),
        enc.heartbeat(Heartbeat()),
    ]


def _attack(sim_port: int, ap_pid: int, known: set[int], stop_event: threading.Event, sent: list[int]) -> None:
    """Find the autopilot's lockstep socket, then send hostile datagrams to both ends until told to stop."""
    enc = Encoder()
    frames = _hostile_frames()
    ap_port = None
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
        sock.bind(("127.0.0.1", 0))
        k = 0
        while not stop_event.is_set():
            if ap_port is None:
                ports = _udp_ports_of(ap_pid) - known
                ap_port = min(ports) if ports else None
            for datagram in _spoofed_answers(enc, k):
                sock.sendto(datagram, ("127.0.0.1", sim_port))
                sent[0] += 1
            if ap_port is not None:
                for datagram in frames:
                    sock.sendto(datagram, ("127.0.0.1", ap_port))
                    sent[1] += 1
            k += 1
            time.sleep(0.002)


def _fly(log_dir: Path, script: Path, hostile: bool) -> tuple[dict, dict, list[int]]:  # type: ignore[type-arg]
    port = Ports.free().sim
    extra = ("--seed", "11", "--duration-s", str(DURATION_S), "--start-timeout-s", "120")
    if hostile:  # paced, so the attack lasts seconds of wall time whatever the machine (same flight at any speed)
        extra += ("--speed", "2")
    sim = start_sim(log_dir, port, *extra, "--autopilot-timeout-s", "30")
    ap = start_autopilot(log_dir, port, None, "--script", str(script))
    stop_event, sent = threading.Event(), [0, 0]
    attacker = None
    if hostile:
        attacker = threading.Thread(target=_attack, args=(port, ap.pid, {port}, stop_event, sent), daemon=True)
        attacker.start()
    try:
        sim.wait(timeout=240)
    finally:
        stop_event.set()
        if attacker is not None:
            attacker.join(5.0)
        stop(ap)
        sim_rc = stop(sim)
    assert sim_rc == 0, logs(log_dir)
    return read_json(log_dir / "sim_summary.json"), read_json(log_dir / "autopilot_summary.json"), sent


@pytest.mark.skipif(not Path("/proc/net/udp").exists(), reason="finds the autopilot's lockstep port in /proc")
def test_strangers_on_both_lockstep_ports_leave_the_flight_unchanged(tmp_path: Path) -> None:
    script = tmp_path / "flight.yaml"
    script.write_text(SCRIPT)
    clean_sim, clean_ap, _ = _fly(tmp_path / "clean", script, hostile=False)
    sim, ap, sent = _fly(tmp_path / "hostile", script, hostile=True)
    assert sent[0] > 100 and sent[1] > 100, sent  # both ends were under fire during the flight
    assert sim["end_reason"] == clean_sim["end_reason"] == "COMPLETED"
    assert ap["flying_steps"] == clean_ap["flying_steps"] > 0  # it did fly
    assert sim["truth_sha256"] == clean_sim["truth_sha256"]
    assert ap["truth_sha256"] == clean_ap["truth_sha256"]
    assert sim["max_tilt_deg"] == clean_sim["max_tilt_deg"]
    assert sim["foreign_datagrams"] > 100  # strangers are dropped before reading
    assert ap["lockstep"]["foreign"] > 100
    assert clean_sim["foreign_datagrams"] == 0 and clean_ap["lockstep"]["foreign"] == 0
