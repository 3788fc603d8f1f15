"""A lossy UDP relay for tests: drops, duplicates and reorders datagrams (SPEC §10).

``LossyUdpProxy`` sits between a client and a fixed target (e.g. autopilot → proxy → sim):
the client sends to ``proxy.listen_address``; datagrams are impaired in both directions
with a seeded RNG and relayed; replies from the target go back to the client's last
address (with ``exclusive``: only the first client's; datagrams from others are counted in ``foreign`` and
dropped, as the lockstep ends do). A "reordered" datagram is held back until the next datagram in the same
direction has passed (or ``hold_s`` elapsed), so it arrives after a newer one.
"""

from __future__ import annotations

import argparse
import random
import select
import socket
import threading
import time
from dataclasses import dataclass

from mavlink_bridge.wire.link import bind_exclusive

Address = tuple[str, int]


def loss_fraction(text: str) -> float:
    """``--sim-loss FRACTION``: the share of datagrams dropped each way, in [0, 1)."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a fraction in [0, 1), got {text!r}") from None
    if not 0.0 <= value < 1.0:
        raise argparse.ArgumentTypeError(f"expected a fraction in [0, 1), got {text!r}")
    return value


@dataclass(frozen=True, slots=True)
class LossProfile:
    """Per-datagram probabilities (each direction independently) and the RNG seed."""

    drop_p: float = 0.0
    duplicate_p: float = 0.0
    reorder_p: float = 0.0
    hold_s: float = 0.03
    seed: int = 0

    def __post_init__(self) -> None:
        if min(self.drop_p, self.duplicate_p, self.reorder_p) < 0.0 or (
            self.drop_p + self.duplicate_p + self.reorder_p > 1.0
        ):
            raise ValueError("loss probabilities must be >= 0 and sum to at most 1")


@dataclass(frozen=True, slots=True)
class LossStats:
    """What the proxy did to the datagrams it saw (both directions)."""

    seen: int
    dropped: int
    duplicated: int
    reordered: int
    foreign: int = 0  # datagrams from a second client of an ``exclusive`` proxy (dropped)


class LossyUdpProxy:
    """Relay between whoever sends to ``listen_address`` and ``target``, impairing datagrams."""

    def __init__(
        self,
        target: Address,
        profile: LossProfile,
        *,
        listen_host: str = "127.0.0.1",
        listen_port: int = 0,
        exclusive: bool = False,
    ) -> None:
        self.target = target
        self.profile = profile
        self.exclusive = exclusive
        self._rng = random.Random(profile.seed)
        self._front = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self._back = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        try:
            bind_exclusive(self._front, listen_host, listen_port)
            self._back.bind((listen_host, 0))
        except OSError:
            self._front.close()
            self._back.close()
            raise
        self._client: Address | None = None
        # held datagrams per direction: (release time, payload)
        self._held: dict[str, list[tuple[float, bytes]]] = {"up": [], "down": []}
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="lossy-udp-proxy", daemon=True)
        self._seen = self._dropped = self._duplicated = self._reordered = self._foreign = 0

    @property
    def listen_address(self) -> Address:
        """Where the client should send."""
        host, port = self._front.getsockname()[:2]
        return (host, port)

    @property
    def stats(self) -> LossStats:
        """A snapshot of the counters."""
        return LossStats(self._seen, self._dropped, self._duplicated, self._reordered, self._foreign)

    def start(self) -> LossyUdpProxy:
        """Start relaying in a daemon thread."""
        self._thread.start()
        return self

    def stop(self) -> None:
        """Stop relaying and close both sockets."""
        self._stop.set()
        if self._thread.is_alive():
            self._thread.join(timeout=2.0)
        self._front.close()
        self._back.close()

    def __enter__(self) -> LossyUdpProxy:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()

    def _send(self, direction: str, data: bytes) -> None:
        try:
            if direction == "up":
                self._back.sendto(data, self.target)
            elif self._client is not None:
                self._front.sendto(data, self._client)
        except OSError:
            pass

    def _flush(self, direction: str, now: float, *, force: bool) -> None:
        held = self._held[direction]
        keep = [(t, d) for t, d in held if not force and t > now]
        for t, d in held:
            if force or t <= now:
                self._send(direction, d)
        held[:] = keep

    def _impair(self, direction: str, data: bytes, now: float) -> None:
        p = self.profile
        self._seen += 1
        r = self._rng.random()
        if r < p.drop_p:
            self._dropped += 1
            return
        if r < p.drop_p + p.duplicate_p:
            self._duplicated += 1
            self._send(direction, data)
            self._send(direction, data)
        elif r < p.drop_p + p.duplicate_p + p.reorder_p:
            self._reordered += 1
            self._held[direction].append((now + p.hold_s, data))
            return
        else:
            self._send(direction, data)
        self._flush(direction, now, force=True)

    def _run(self) -> None:
        front, back = self._front, self._back
        while not self._stop.is_set():
            readable, _, _ = select.select([front, back], [], [], 0.005)
            now = time.monotonic()
            for sock in readable:
                try:
                    data, address = sock.recvfrom(65535)
                except OSError:
                    continue
                if sock is front:
                    if self.exclusive and self._client is not None and address != self._client:
                        self._foreign += 1
                        continue
                    self._client = address
                    self._impair("up", data, now)
                elif address == self.target:
                    self._impair("down", data, now)
            self._flush("up", now, force=False)
            self._flush("down", now, force=False)
