"""UdpLink: pymavlink connection strings, udpin replies to the last sender, timeouts, no raise on a vanished peer."""

from __future__ import annotations

import threading
import time

import pytest

from mavlink_bridge.lockstep import LockstepClient, LockstepInterrupted, LockstepServer
from mavlink_bridge.wire.link import LinkMode, LinkUrl, LinkUrlError, UdpLink, spin_allowed
from tests.mavlink_bridge.lockstep.test_bridge_lockstep import make_frame


def test_url_forms() -> None:
    assert LinkUrl.parse("udpin:127.0.0.1:14560") == LinkUrl(LinkMode.LISTEN, "127.0.0.1", 14560)
    assert LinkUrl.parse("udp:0.0.0.0:14550") == LinkUrl(LinkMode.LISTEN, "0.0.0.0", 14550)
    assert LinkUrl.parse("udpout:localhost:14540") == LinkUrl(LinkMode.CONNECT, "localhost", 14540)
    assert str(LinkUrl.parse("udp:127.0.0.1:14560").with_port_offset(2)) == "udpin:127.0.0.1:14562"
    for bad in ("tcp:127.0.0.1:5760", "udpin:127.0.0.1", "udpin::14560", "udpout:host:port", "udp:1.2.3.4:70000", ""):
        with pytest.raises(LinkUrlError):
            LinkUrl.parse(bad)


def test_udpin_replies_to_last_sender_and_udpout_gets_replies() -> None:
    with UdpLink.from_url("udpin:127.0.0.1:0") as server:
        port = server.local_address[1]
        assert server.send(b"nobody yet") is False  # no peer before anyone talked
        with UdpLink.from_url(f"udpout:127.0.0.1:{port}") as a, UdpLink.from_url(f"udpout:127.0.0.1:{port}") as b:
            assert a.send(b"from a")
            assert server.recv(1.0) == b"from a" and server.peer == a.local_address
            assert server.send(b"to a") and a.recv(1.0) == b"to a"
            assert b.send(b"from b") and server.recv(1.0) == b"from b"
            assert server.send(b"to b") and b.recv(1.0) == b"to b"
            assert a.recv(0.0) is None  # nothing else for a


def test_follow_sender_off_keeps_the_chosen_peer() -> None:
    with UdpLink.from_url("udpin:127.0.0.1:0", follow_sender=False) as server:
        port = server.local_address[1]
        with UdpLink.from_url(f"udpout:127.0.0.1:{port}") as a:
            a.send(b"x")
            assert server.recv(1.0) == b"x" and server.peer is None and server.last_sender == a.local_address


def test_recv_times_out_and_a_vanished_peer_does_not_raise() -> None:
    with UdpLink.from_url("udpin:127.0.0.1:0") as server:
        port = server.local_address[1]
        assert server.recv(0.05) is None
        client = UdpLink.from_url(f"udpout:127.0.0.1:{port}")
        client.send(b"hello")
        assert server.recv(1.0) == b"hello"
        client.close()
        client.close()  # idempotent
        server.send(b"into the void")  # ICMP port unreachable must not surface as an exception
        assert server.recv(0.02) is None


def test_interrupt_ends_a_waiting_exchange_promptly() -> None:
    server = LockstepServer("udpin:127.0.0.1:0", resend_timeout_s=0.01, peer_lost_timeout_s=60.0)
    host, port = server.local_address
    client = LockstepClient(f"udpout:{host}:{port}", heartbeat_period_s=0.02)
    try:
        client.next_frame(0.05)
        assert server.wait_for_autopilot(2.0)
        threading.Timer(0.1, server.interrupt).start()
        with pytest.raises(LockstepInterrupted):
            server.exchange(make_frame(0))  # nobody answers; only interrupt() can end this before 60 s
        assert server.wait_for_autopilot(None) is False
    finally:
        client.close()
        server.close()


def test_spinning_recv_gets_datagrams_and_still_times_out() -> None:
    with UdpLink.from_url("udpin:127.0.0.1:0", spin_s=0.002) as server:
        port = server.local_address[1]
        assert server.spin_s == (0.002 if spin_allowed() else 0.0)
        with UdpLink.from_url(f"udpout:127.0.0.1:{port}", spin_s=0.002) as a:
            assert server.recv(0.05) is None  # nothing sent: spins, then sleeps out the rest, then None
            assert a.send(b"ping")
            assert server.recv(1.0) == b"ping"
            threading.Timer(0.01, lambda: server.send(b"pong")).start()  # arrives after the spin: from poll
            assert a.recv(1.0) == b"pong"
            assert a.recv(0.0) is None


def test_no_spin_on_one_cpu(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr("mavlink_bridge.wire.link.os.sched_getaffinity", lambda _pid: {0})
    assert not spin_allowed()
    with UdpLink.from_url("udpin:127.0.0.1:0", spin_s=0.001) as link:
        assert link.spin_s == 0.0


def test_spinning_backs_off_while_the_peer_is_slow(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr("mavlink_bridge.wire.link.spin_allowed", lambda: True)
    with UdpLink.from_url("udpin:127.0.0.1:0", spin_s=0.001) as server:
        spins: list[float] = []
        real_spin = UdpLink._spin
        monkeypatch.setattr(UdpLink, "_spin", lambda link, s: spins.append(s) or real_spin(link, s))
        for _ in range(8):  # nothing arrives: spin, skip 1, spin, skip 2, spin (skip 4 ...)
            assert server.recv(0.002) is None
        assert len(spins) == 3
        with UdpLink.from_url(f"udpout:127.0.0.1:{server.local_address[1]}") as a:
            for _ in range(8):  # data waiting: after the 2 skips left, every wait spins (and hits) again
                a.send(b"x")
                assert server.recv(0.5) == b"x"
        assert len(spins) == 3 + 8 - 2


def test_spinning_stops_when_another_process_wants_the_cpu(monkeypatch: pytest.MonkeyPatch) -> None:
    """A yield that ran another process for longer than CONTENDED_YIELD_S (two lockstep pairs on two cores) ends
    the spin, and the next waits sleep in poll instead of spinning (the backoff), even though the datagram came."""
    monkeypatch.setattr("mavlink_bridge.wire.link.spin_allowed", lambda: True)
    server = UdpLink.from_url("udpin:127.0.0.1:0", spin_s=0.05)
    with server, UdpLink.from_url(f"udpout:127.0.0.1:{server.local_address[1]}") as a:

        def busy_cpu() -> None:  # the yield gave the CPU to another process, which sent the datagram
            a.send(b"x")
            time.sleep(0.001)

        monkeypatch.setattr("mavlink_bridge.wire.link._yield_cpu", busy_cpu)
        spins: list[float] = []
        real_spin = UdpLink._spin
        monkeypatch.setattr(UdpLink, "_spin", lambda link, s: spins.append(s) or real_spin(link, s))
        t0 = time.monotonic()
        assert server.recv(1.0) == b"x" and server.spin_contended
        assert time.monotonic() - t0 < 0.04  # ended at the contended yield, not after the 50 ms spin
        a.send(b"y")
        assert server.recv(1.0) == b"y"
        assert len(spins) == 1  # the second wait did not spin
