"""Lockstep server and client over loopback: lossless, lossy (drops, duplicates, reordering), garbage, lost peers."""

from __future__ import annotations

import dataclasses
import math
import socket
import threading

import numpy as np
import pytest

from mavlink_bridge.contract.wire import (
    ActuatorCommand,
    GpsSample,
    GroundTruth,
    ObstacleDetection,
    ObstacleShape,
    SensorSample,
)
from mavlink_bridge.lockstep import (
    AutopilotLost,
    LockstepClient,
    LockstepFrame,
    LockstepServer,
    ResendTimer,
    encode_frame,
)
from mavlink_bridge.wire.codec import SIM_COMPONENT_ID, SIM_SYSTEM_ID, Encoder
from mavlink_bridge.wire.link import UdpLink
from mavlink_bridge.wire.lossy import LossProfile, LossyUdpProxy

FRAME_PERIOD_US = 4000


def make_frame(k: int) -> LockstepFrame:
    t = k * FRAME_PERIOD_US
    sensor = SensorSample(t, (0.0, 0.0, -9.8 + k * 1e-3), (0.0, 0.0, 0.0), (0.2, 0.0, 0.4), 1013.0, 1.0 + k, 20.0)
    truth = GroundTruth(
        t, (1.0, 0.0, 0.0, 0.0), (0.0, 0.0, 0.0), 30.0, 120.0, 10.0 + k * 0.01, (0.0, 0.0, 0.0), (0, 0, 0)
    )
    gps = GpsSample(t, 30.0, 120.0, 10.0, (0.0, 0.0, 0.0), 0.5, 0.8, 3, 10) if k % 25 == 0 else None
    detections = (ObstacleDetection(t, k % 3, (5.0, 0.0, 0.0), 1.0, ObstacleShape.SPHERE),) if k % 7 == 0 else ()
    return LockstepFrame(sensor, gps, truth, detections)


def autopilot_law(frame: LockstepFrame) -> ActuatorCommand:
    """A deterministic function of the frame, so any lost/duplicated answer would show."""
    base = (frame.sensor.pressure_alt_m % 10.0) / 10.0
    gripper = frame.gps is not None
    return ActuatorCommand(frame.time_us, (base, base + 0.01, 0.5, float(len(frame.detections))), True, gripper)


def run_client(client: LockstepClient, n_frames: int, seen: list[LockstepFrame], stop: threading.Event) -> None:
    while len(seen) < n_frames and not stop.is_set():
        frame = client.next_frame(0.1)
        if frame is None:
            continue
        seen.append(frame)
        client.answer(autopilot_law(frame))
    # keep answering re-sends of the last frame until the server is done with it
    while not stop.is_set():
        client.next_frame(0.05)


def run_lockstep(n_frames: int, profile: LossProfile | None) -> tuple[list[ActuatorCommand], list[LockstepFrame], dict]:
    server = LockstepServer("udpin:127.0.0.1:0", resend_timeout_s=0.01, peer_lost_timeout_s=5.0)
    host, port = server.local_address
    proxy = LossyUdpProxy((host, port), profile).start() if profile else None
    target = proxy.listen_address if proxy else (host, port)
    client = LockstepClient(f"udpout:{target[0]}:{target[1]}", heartbeat_period_s=0.02)
    seen: list[LockstepFrame] = []
    stop = threading.Event()
    thread = threading.Thread(target=run_client, args=(client, n_frames, seen, stop), daemon=True)
    thread.start()
    try:
        assert server.wait_for_autopilot(5.0)
        answers = [server.exchange(make_frame(k)) for k in range(n_frames)]
    finally:
        stop.set()
        thread.join(5.0)
        info = {"server": server.stats, "client": client.stats, "proxy": proxy.stats if proxy else None}
        client.close()
        server.close()
        if proxy:
            proxy.stop()
    return answers, seen, info


def test_lossless_lockstep_delivers_frames_in_order() -> None:
    answers, seen, info = run_lockstep(120, None)
    assert [f.time_us for f in seen] == [k * FRAME_PERIOD_US for k in range(120)]
    assert [f.detections for f in seen] == [make_frame(k).detections for k in range(120)]  # exact in float32
    assert [a.time_us for a in answers] == [k * FRAME_PERIOD_US for k in range(120)]
    assert info["server"].frames == 120
    assert [f.gps is not None for f in seen] == [k % 25 == 0 for k in range(120)]


def test_lossy_link_recovers_with_identical_answers() -> None:
    n = 300
    reference, _, _ = run_lockstep(n, None)
    profile = LossProfile(drop_p=0.10, duplicate_p=0.10, reorder_p=0.10, hold_s=0.015, seed=7)
    answers, seen, info = run_lockstep(n, profile)
    assert answers == reference  # same answers, same order, nothing skipped or doubled
    assert [f.time_us for f in seen] == [k * FRAME_PERIOD_US for k in range(n)]  # each frame reached the caller once
    proxy, server, client = info["proxy"], info["server"], info["client"]
    assert proxy.dropped > 20 and proxy.duplicated > 20 and proxy.reordered > 20
    assert server.resends > 0 and server.frames == n
    assert client.reanswered + client.duplicates > 0
    assert server.stale_answers + client.stale_frames + client.duplicates > 0


def test_both_ends_survive_garbage_datagrams() -> None:
    server = LockstepServer("udpin:127.0.0.1:0", resend_timeout_s=0.01, peer_lost_timeout_s=5.0)
    host, port = server.local_address
    client = LockstepClient(f"udp:{host}:{port}", heartbeat_period_s=0.02)
    rng = np.random.default_rng(3)
    junk = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    junk.bind(("127.0.0.1", 0))
    seen: list[LockstepFrame] = []
    stop = threading.Event()
    thread = threading.Thread(target=run_client, args=(client, 60, seen, stop), daemon=True)
    try:
        for _ in range(20):  # garbage before the heartbeat must not become the peer
            junk.sendto(rng.integers(0, 256, rng.integers(1, 200)).astype(np.uint8).tobytes(), (host, port))
        thread.start()
        assert server.wait_for_autopilot(5.0)
        client_port = client._link.local_address[1]
        answers = []
        for k in range(60):
            for _ in range(2):  # garbage to both ends, every frame
                junk.sendto(rng.integers(0, 256, rng.integers(1, 300)).astype(np.uint8).tobytes(), (host, port))
                junk.sendto(b"\xfd" + rng.integers(0, 256, 40).astype(np.uint8).tobytes(), ("127.0.0.1", client_port))
            answers.append(server.exchange(make_frame(k)))
        assert [a.time_us for a in answers] == [k * FRAME_PERIOD_US for k in range(60)]
        assert server.stats.malformed > 0  # garbage before the heartbeat: read (no peer yet), counted
        assert server.stats.foreign > 0 and client.stats.foreign > 0  # after it: a stranger's, dropped unread
    finally:
        stop.set()
        thread.join(5.0)
        junk.close()
        client.close()
        server.close()


def test_server_raises_autopilot_lost_instead_of_hanging() -> None:
    server = LockstepServer("udpin:127.0.0.1:0", resend_timeout_s=0.01, peer_lost_timeout_s=0.3)
    host, port = server.local_address
    client = LockstepClient(f"udpout:{host}:{port}", heartbeat_period_s=0.02)
    try:
        assert client.next_frame(0.05) is None  # sends the heartbeat
        assert server.wait_for_autopilot(2.0)
        client.close()  # the autopilot vanishes
        with pytest.raises(AutopilotLost, match="no answer"):
            server.exchange(make_frame(0))
        assert server.stats.resends >= 5
    finally:
        server.close()


def test_wait_for_autopilot_times_out_without_heartbeat() -> None:
    with LockstepServer("udpin:127.0.0.1:0") as server:
        assert server.wait_for_autopilot(0.05) is False


def test_client_reports_sim_lost_and_accepts_a_restarted_sim() -> None:
    server = LockstepServer("udpin:127.0.0.1:0", resend_timeout_s=0.01)
    host, port = server.local_address
    client = LockstepClient(f"udpout:{host}:{port}", heartbeat_period_s=0.02, sim_lost_timeout_s=0.2)
    seen: list[LockstepFrame] = []
    stop = threading.Event()
    thread = threading.Thread(target=run_client, args=(client, 10, seen, stop), daemon=True)
    thread.start()
    try:
        assert not client.connected and not client.sim_lost
        assert server.wait_for_autopilot(5.0)
        for k in range(10):
            server.exchange(make_frame(k))
        stop.set()
        thread.join(5.0)
        assert client.connected
        assert client.next_frame(0.3) is None and client.sim_lost
        server.close()
        server = LockstepServer(f"udpin:{host}:{port}", resend_timeout_s=0.01)  # the sim restarts at t = 0
        results: list[ActuatorCommand] = []
        restarted = threading.Thread(
            target=lambda: results.append(server.exchange(make_frame(0))) if server.wait_for_autopilot(5.0) else None
        )
        restarted.start()
        frame = None
        for _ in range(50):
            frame = client.next_frame(0.1)
            if frame is not None:
                break
        assert frame is not None and frame.time_us == 0
        client.answer(autopilot_law(frame))
        restarted.join(5.0)
        assert results and results[0].time_us == 0
    finally:
        stop.set()
        client.close()
        server.close()


def _frame_datagram(encoder: Encoder, k: int, *, t_us: int | None = None, q: tuple = (1.0, 0.0, 0.0, 0.0)) -> bytes:
    frame = make_frame(k)
    t = frame.time_us if t_us is None else t_us
    sensor = dataclasses.replace(frame.sensor, time_us=t)
    truth = dataclasses.replace(frame.truth, time_us=t, q_ned_frd=q)
    return encode_frame(encoder, LockstepFrame(sensor, None, truth, frame.detections))


def test_client_drops_frames_out_of_time_order_or_with_absurd_values_from_its_sim() -> None:
    with UdpLink.from_url("udpin:127.0.0.1:0") as sim, socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as stranger:
        host, port = sim.local_address
        client = LockstepClient(f"udpout:{host}:{port}", heartbeat_period_s=0.02)
        enc = Encoder(SIM_SYSTEM_ID, SIM_COMPONENT_ID)
        try:
            assert client.next_frame(0.05) is None and sim.recv(1.0) is not None  # the HEARTBEAT: sim knows its peer
            sim.send(_frame_datagram(enc, 0))
            first = client.next_frame(1.0)
            assert first is not None and first.time_us == 0
            client.answer(autopilot_law(first))
            bad = [
                _frame_datagram(enc, 1, t_us=3_600_000_000),  # an hour ahead
                _frame_datagram(enc, 1, t_us=2**63),  # beyond any sim time (would overflow downstream)
                _frame_datagram(enc, 1, q=(math.nan, 0.0, 0.0, 0.0)),  # NaN attitude
                _frame_datagram(enc, 1, q=(5.0, 0.0, 0.0, 0.0)),  # not a rotation
            ]
            for datagram in bad:
                sim.send(datagram)
                assert client.next_frame(0.05) is None
            stranger.sendto(_frame_datagram(enc, 1), client.local_address)  # right frame, wrong sender
            assert client.next_frame(0.05) is None
            sim.send(_frame_datagram(enc, 1))
            good = client.next_frame(1.0)
            assert good is not None and good.time_us == FRAME_PERIOD_US
            stats = client.stats
            assert (stats.future_frames, stats.invalid_frames, stats.foreign, stats.frames) == (2, 2, 1, 2)
            assert stats.as_dict()["foreign"] == 1
        finally:
            client.close()


def test_server_hears_only_the_autopilot_that_started_the_lockstep() -> None:
    server = LockstepServer("udpin:127.0.0.1:0", resend_timeout_s=0.01, peer_lost_timeout_s=5.0)
    host, port = server.local_address
    client = LockstepClient(f"udpout:{host}:{port}", heartbeat_period_s=0.02)
    squatter = LockstepClient(f"udpout:{host}:{port}", heartbeat_period_s=0.02)
    stranger = LockstepClient(f"udpout:{host}:{port}", heartbeat_period_s=0.02)
    enc = Encoder()
    try:
        # a stranger's HEARTBEAT first: it gets the first frame but answers it with NaN; the autopilot's valid
        # answer starts the lockstep
        assert squatter.next_frame(0.05) is None and server.wait_for_autopilot(2.0)
        server.send(make_frame(0))
        squatted = squatter.next_frame(1.0)
        assert squatted is not None
        squatter.answer(ActuatorCommand(0, (math.nan,) * 4, True))
        first: list[ActuatorCommand] = []
        waiting = threading.Thread(target=lambda: first.append(server.wait_answer()), daemon=True)
        waiting.start()
        frame = client.next_frame(1.0)  # its HEARTBEAT makes it a candidate: it is sent frame 0 as well
        assert frame is not None and frame.time_us == 0
        client.answer(ActuatorCommand(0, (0.25, 0.25, 0.25, 0.25), True))
        waiting.join(5.0)
        assert first and first[0].motor_cmd == (0.25, 0.25, 0.25, 0.25)
        assert server.peer == client.local_address
        # once started, nobody else is heard: HEARTBEATs and spoofed answers with the right frame time
        server.send(make_frame(1))
        assert stranger.next_frame(0.05) is None
        for motors in ((math.nan, 0.5, 0.5, 0.5), (1.0, 1.0, 1.0, 1.0)):
            stranger._link.send(enc.actuators(ActuatorCommand(FRAME_PERIOD_US, motors, True)))
        client._link.send(enc.actuators(ActuatorCommand(FRAME_PERIOD_US * 9, (0.5,) * 4, True)))  # ahead: invalid
        client._link.send(enc.actuators(ActuatorCommand(FRAME_PERIOD_US, (math.nan,) * 4, True)))  # NaN: invalid
        frame = client.next_frame(1.0)
        assert frame is not None
        client.answer(ActuatorCommand(FRAME_PERIOD_US, (0.5,) * 4, True))
        assert server.wait_answer().motor_cmd == (0.5,) * 4
        stats = server.stats
        assert stats.foreign >= 3 and stats.invalid_answers == 3 and stats.frames == 2
    finally:
        for end in (stranger, squatter, client):
            end.close()
        server.close()


def test_resend_timer_follows_the_exchange_time_within_its_bounds() -> None:
    timer = ResendTimer(0.00025, 0.02)
    for _ in range(50):
        timer.sample(0.0001)
    assert 0.00025 <= timer.timeout_s < 0.0005  # sub-millisecond on a fast link
    for _ in range(50):
        timer.sample(0.004)
    assert 0.004 < timer.timeout_s < 0.01
    assert timer.backoff(0.015) == 0.02  # doubling is capped
    with pytest.raises(ValueError):
        ResendTimer(0.0, 0.02)
