"""The lockstep's transport limit (issue 16): a bare UDP ping-pong between two Python processes.

One process sends a datagram of the lockstep frame's size and waits in a blocking ``recvfrom`` for a datagram
of the answer's size, which the other process sends back as soon as its own blocking ``recvfrom`` returns. No
MAVLink, no decoding, no work: what any Python lockstep over loopback UDP on this machine can reach at most.
``lockstep_flight`` measures it in each round next to the messaging floor and the whole flight.
"""

from __future__ import annotations

import multiprocessing as mp
import socket
import time
from dataclasses import dataclass
from multiprocessing.connection import Connection

from tools.benchmarks import BenchResult

CONTROL_HZ = 250


def datagram_sizes() -> tuple[int, int]:
    """(frame, answer) bytes of a typical lockstep step: the sim's frame without GPS or detections, the answer."""
    from mavlink_bridge.contract.wire import ActuatorCommand
    from mavlink_bridge.wire.codec import Encoder
    from tools.benchmarks.lockstep_floor import NullSimFrames

    frame = NullSimFrames().datagram(1)[1]
    answer = Encoder().actuators(ActuatorCommand(4000, (0.5, 0.5, 0.5, 0.5), True))
    return len(frame), len(answer)


def _pong(port_tx: Connection, answer_len: int) -> None:
    """Echo an ``answer_len`` datagram to each datagram received; stop on an empty one."""
    answer = bytes(answer_len)
    buf = bytearray(65535)
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
        sock.bind(("127.0.0.1", 0))
        port_tx.send(sock.getsockname()[1])
        while True:
            n, address = sock.recvfrom_into(buf)
            if n == 0:
                return
            sock.sendto(answer, address)


@dataclass(frozen=True, slots=True)
class TransportRun:
    """One ping-pong measurement."""

    rtf: float  # exchanges per wall second / CONTROL_HZ
    exchange_us: float


def measure_transport_run(n: int, warmup: int = 500, sizes: tuple[int, int] | None = None) -> TransportRun:
    """``n`` blocking ping-pong exchanges (after ``warmup``) with a spawned process, datagrams of ``sizes``."""
    frame_len, answer_len = sizes or datagram_sizes()
    ctx = mp.get_context("spawn")
    rx, tx = ctx.Pipe(duplex=False)
    proc = ctx.Process(target=_pong, args=(tx, answer_len), daemon=True)
    proc.start()
    frame = bytes(frame_len)
    buf = bytearray(65535)
    try:
        if not rx.poll(60.0):
            raise RuntimeError("ping-pong peer did not start")
        peer = ("127.0.0.1", rx.recv())
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
            sock.bind(("127.0.0.1", 0))
            sock.settimeout(5.0)
            send, recv = sock.sendto, sock.recvfrom_into
            for _ in range(warmup):
                send(frame, peer)
                recv(buf)
            t0 = time.perf_counter()
            for _ in range(n):
                send(frame, peer)
                recv(buf)
            wall_s = time.perf_counter() - t0
            send(b"", peer)
    finally:
        proc.join(5.0)
        if proc.is_alive():
            proc.terminate()
    return TransportRun(n / CONTROL_HZ / wall_s, wall_s / n * 1e6)


def run(quick: bool) -> list[BenchResult]:
    """Only the transport limit (``lockstep_flight`` reports it with the floor and the flight, same rounds)."""
    n = 5000 if quick else 20000
    runs = sorted((measure_transport_run(n) for _ in range(3)), key=lambda r: r.rtf)
    frame_len, answer_len = datagram_sizes()
    note = f"bare UDP ping-pong, 2 processes, {frame_len} B / {answer_len} B, blocking recvfrom, median of 3"
    return [
        BenchResult("transport_limit_rtf", runs[1].rtf, note=note),
        BenchResult("transport_exchange_us", runs[1].exchange_us, note="wall per ping-pong exchange (median run)"),
    ]
