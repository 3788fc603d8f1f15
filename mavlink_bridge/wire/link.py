"""UDP datagram links addressed by pymavlink connection strings (SPEC §3, §12).

``UdpLink.from_url`` accepts the pymavlink forms:

- ``udpin:HOST:PORT`` (and ``udp:HOST:PORT``): bind HOST:PORT, reply to the last sender;
- ``udpout:HOST:PORT``: bind an ephemeral port on the matching loopback/any address and send to HOST:PORT;
  replies come back on the same socket.

The link moves whole datagrams only: it knows nothing of MAVLink (framing, signing and
decoding belong to ``mavlink_bridge.wire.codec``). ``recv`` never raises on what a peer sends;
socket errors caused by a vanished peer (ICMP port unreachable) are swallowed and counted.

Ports are exclusive: a listening link never sets ``SO_REUSEADDR``/``SO_REUSEPORT`` (on Linux either lets a
second process bind the same UDP port and steal its traffic), and a taken port raises ``PortInUseError``
naming the port and the fix. ``--instance N`` shifts default ports only (``resolve_url``): an address the
user typed is used as typed, as PX4's and ArduPilot's instance offsets do.
"""

from __future__ import annotations

import errno
import os
import select
import socket
import time
from dataclasses import dataclass
from enum import Enum

import numpy as np

Address = tuple[str, int]

_MAX_DATAGRAM_BYTES = 65535
_SPIN_BACKOFF_MAX = 256
#: A spin's yield that returns later than this (s) ran another process: the CPU is wanted, stop spinning (a yield
#: with nothing else runnable returns in ~1 µs; a peer's lockstep step takes ~50-150 µs).
CONTENDED_YIELD_S = 30e-6
_yield_cpu = getattr(os, "sched_yield", None) or (lambda: None)  # Linux and macOS have it
_TRANSIENT_ERRNOS = frozenset({errno.EAGAIN, errno.EWOULDBLOCK, errno.ECONNREFUSED, errno.EINTR, errno.ENOBUFS})


def spin_allowed() -> bool:
    """True when this process may run on at least two CPUs: spinning on one CPU would starve the peer."""
    try:
        return len(os.sched_getaffinity(0)) >= 2
    except AttributeError:  # not Linux
        return (os.cpu_count() or 1) >= 2


class LinkUrlError(ValueError):
    """A connection string that is not ``udpin:``, ``udpout:`` or ``udp:`` HOST:PORT."""


class PortInUseError(OSError):
    """A UDP port to listen on is taken (another quadsitl instance, or another program); one-line message."""

    def __init__(self, host: str, port: int) -> None:
        super().__init__(
            f"UDP port {port} on {host} is already in use (another quadsitl instance?); "
            "run this one with --instance N to shift every default port by N"
        )
        self.host = host
        self.port = port

    def __str__(self) -> str:
        return str(self.args[0])


class LinkMode(Enum):
    """Which side of a UDP link this is."""

    LISTEN = "udpin"  # bound to a known port, replies to whoever talks to it
    CONNECT = "udpout"  # sends to a known address


@dataclass(frozen=True, slots=True)
class LinkUrl:
    """A parsed pymavlink-style UDP connection string."""

    mode: LinkMode
    host: str
    port: int

    @classmethod
    def parse(cls, url: str) -> LinkUrl:
        """Parse ``udpin:HOST:PORT``, ``udpout:HOST:PORT`` or ``udp:HOST:PORT`` (= udpin)."""
        scheme, sep, rest = url.partition(":")
        host, sep2, port_text = rest.rpartition(":")
        modes = {"udpin": LinkMode.LISTEN, "udp": LinkMode.LISTEN, "udpout": LinkMode.CONNECT}
        if not sep or not sep2 or scheme not in modes or not host:
            raise LinkUrlError(f"expected udpin:HOST:PORT, udpout:HOST:PORT or udp:HOST:PORT, got {url!r}")
        try:
            port = int(port_text)
        except ValueError:
            raise LinkUrlError(f"port of {url!r} is not an integer") from None
        if not 0 <= port <= 65535:
            raise LinkUrlError(f"port of {url!r} is out of range 0..65535")
        return cls(modes[scheme], host, port)

    def with_port_offset(self, offset: int) -> LinkUrl:
        """The same URL with the port shifted by ``offset`` (``--instance N``)."""
        return LinkUrl(self.mode, self.host, self.port + offset)

    def __str__(self) -> str:
        return f"{self.mode.value}:{self.host}:{self.port}"


def bind_exclusive(sock: socket.socket, host: str, port: int) -> None:
    """Bind ``sock`` to (host, port) without address reuse; ``PortInUseError`` when the port is taken."""
    try:
        sock.bind((host, port))
    except OSError as exc:
        if exc.errno == errno.EADDRINUSE:
            raise PortInUseError(host, port) from None
        raise


def check_ports_free(urls: list[str]) -> None:
    """Raise ``PortInUseError`` for the first listening URL of ``urls`` whose port is taken (``udpout:``, ``off``
    skipped).

    For launchers: fail before starting any process rather than leave one running on a half-taken set.
    """
    for text in urls:
        if text == "off":
            continue
        url = LinkUrl.parse(text)
        if url.mode is not LinkMode.LISTEN or url.port == 0:
            continue
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
            bind_exclusive(sock, url.host, url.port)


def resolve_url(given: str | None, default: str, instance: int) -> str:
    """The link URL to use: ``given`` exactly as typed, else ``default`` with its port shifted by ``instance``."""
    if given is not None:
        LinkUrl.parse(given)  # LinkUrlError now, not when the link opens
        return given
    return str(LinkUrl.parse(default).with_port_offset(instance))


class UdpLink:
    """A non-blocking UDP socket that sends and receives whole datagrams.

    In LISTEN mode the reply address (``peer``) follows the last sender when
    ``follow_sender`` is true (pymavlink ``udpin`` behaviour); a protocol layer that
    wants to choose its peer itself (e.g. only after a valid MAVLink frame) passes
    ``follow_sender=False`` and calls ``set_peer``.
    """

    __slots__ = (
        "_buf",
        "_listening",
        "_poll",
        "_sock",
        "_spin_backoff",
        "_spin_skip",
        "_view",
        "array",
        "follow_sender",
        "last_sender",
        "peer",
        "send_errors",
        "spin_contended",
        "spin_s",
        "url",
    )

    def __init__(self, url: LinkUrl, *, follow_sender: bool = True, spin_s: float = 0.0) -> None:
        self.url = url
        self.follow_sender = follow_sender
        self.spin_s = spin_s if spin_s > 0.0 and spin_allowed() else 0.0
        self._spin_backoff = 1  # waits to skip spinning after the next miss (doubles per miss, up to 256)
        self._spin_skip = 0  # waits left to do without spinning
        self.spin_contended = False  # the last spin ended because another process wanted the CPU
        self._listening = url.mode is LinkMode.LISTEN
        self.send_errors = 0
        self.last_sender: Address | None = None
        self.peer: Address | None = None
        sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        try:
            if url.mode is LinkMode.LISTEN:
                bind_exclusive(sock, url.host, url.port)
            else:
                local = "127.0.0.1" if url.host.startswith("127.") or url.host == "localhost" else "0.0.0.0"
                sock.bind((local, 0))
                self.peer = (socket.gethostbyname(url.host), url.port)
            sock.setblocking(False)
        except OSError:
            sock.close()
            raise
        self._sock = sock
        self._poll = select.poll()
        self._poll.register(sock.fileno(), select.POLLIN)
        self._buf = bytearray(_MAX_DATAGRAM_BYTES)
        self._view = memoryview(self._buf)
        self.array = np.frombuffer(self._buf, dtype=np.uint8)  # the receive buffer, for compiled readers

    @classmethod
    def from_url(cls, url: str, *, follow_sender: bool = True, spin_s: float = 0.0) -> UdpLink:
        """Open a link from a pymavlink connection string (see module docstring)."""
        return cls(LinkUrl.parse(url), follow_sender=follow_sender, spin_s=spin_s)

    @property
    def local_address(self) -> Address:
        """The (host, port) this socket is bound to."""
        host, port = self._sock.getsockname()[:2]
        return (host, port)

    def fileno(self) -> int:
        """The socket's file descriptor (for callers that multiplex several links)."""
        return self._sock.fileno()

    def set_peer(self, address: Address | None) -> None:
        """Send future datagrams to ``address``."""
        self.peer = address

    def recv(self, timeout_s: float) -> bytes | None:
        """The next whole datagram (a copy), waiting at most ``timeout_s`` (0 = poll); None on timeout (see
        ``recv_into_buffer``)."""
        n = self.recv_into_buffer(timeout_s)
        return None if n < 0 else bytes(self._view[:n])

    def recv_into_buffer(self, timeout_s: float) -> int:
        """The next whole datagram's length, its bytes in ``array[:length]`` (no copy, valid until the next
        receive), waiting at most ``timeout_s`` (0 = poll); -1 on timeout.

        ``last_sender`` is set to its source; in LISTEN mode with ``follow_sender`` the
        peer follows it. With ``spin_s`` > 0 the socket is first polled without sleeping for up to
        ``spin_s`` (a lockstep peer answers within tens of µs; waking a sleeping process costs about
        as much again), then the process sleeps in ``poll`` for the rest of ``timeout_s``. The spin yields
        the CPU between polls (another runnable process on it goes first) and ends at the first yield that ran
        another process (an oversubscribed host: two lockstep pairs on two cores); a spin that ends
        empty-handed (slow peer, or a machine too busy to give both ends a CPU) is skipped for the next
        1, 2, 4 … 256 waits, so spinning only continues while it pays and no other process wants the CPU.
        """
        if timeout_s > 0.0:
            if self.spin_s > 0.0:
                if self._spin_skip == 0:
                    n = self._spin(min(self.spin_s, timeout_s))
                    if n >= 0 and not self.spin_contended:
                        self._spin_backoff = 1
                        return n
                    # the peer is slower than the spin, or the CPU is wanted by another process: back off
                    self._spin_skip = self._spin_backoff
                    self._spin_backoff = min(2 * self._spin_backoff, _SPIN_BACKOFF_MAX)
                    if n >= 0:
                        return n
                    timeout_s -= self.spin_s
                else:
                    self._spin_skip -= 1
            if timeout_s > 0.0 and not self._poll.poll(timeout_s * 1000.0):
                return -1
        return self._take()

    def _spin(self, spin_s: float) -> int:
        """Busy-poll the socket for up to ``spin_s`` (wall); the datagram's length or -1. Ends early, with
        ``spin_contended`` set, at the first yield that gave the CPU away (it took over ``CONTENDED_YIELD_S``):
        another process wanted this CPU, so the host is oversubscribed and spinning takes the time the peer (or
        another lockstep pair) needs."""
        take, clock, yield_cpu = self._take, time.perf_counter, _yield_cpu
        self.spin_contended = False
        now = clock()
        end = now + spin_s
        while True:
            n = take()
            if n >= 0 or now >= end:
                return n
            yield_cpu()  # polite: another runnable process on this CPU (a peer, another SITL) goes first
            before, now = now, clock()
            if now - before > CONTENDED_YIELD_S:
                self.spin_contended = True
                return take()

    def _take(self) -> int:
        """One datagram into the buffer if the socket has one (never blocks): its length, else -1."""
        try:
            n, address = self._sock.recvfrom_into(self._buf)
        except OSError as exc:
            if exc.errno not in _TRANSIENT_ERRNOS:
                raise
            return -1
        self.last_sender = address
        if self.follow_sender and self._listening:
            self.peer = address
        return n

    def send(self, data: bytes | memoryview) -> bool:
        """Send one datagram to the peer; False when there is no peer yet or the kernel refused it."""
        return self.send_to(data, self.peer)

    def send_to(self, data: bytes | memoryview, address: Address | None) -> bool:
        """Send one datagram to ``address`` (not the peer); False when it is None or the kernel refused it."""
        if address is None:
            return False
        try:
            self._sock.sendto(data, address)
        except OSError:
            self.send_errors += 1
            return False
        return True

    def close(self) -> None:
        """Close the socket (idempotent)."""
        if self._sock.fileno() >= 0:
            self._poll.unregister(self._sock.fileno())
            self._sock.close()

    def __enter__(self) -> UdpLink:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
