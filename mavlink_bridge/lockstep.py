"""The lockstep protocol, both ends (SPEC §4; PX4 simulator_mavlink compatible).

Sim side (``LockstepServer``, binds ``udpin:127.0.0.1:14560`` by default): waits for a
HEARTBEAT, then for each control step sends ONE datagram holding HIL_GPS (when due),
HIL_STATE_QUATERNION, OBSTACLE_DISTANCE_3D (per detection) and HIL_SENSOR last, and
waits for the HIL_ACTUATOR_CONTROLS whose ``time_usec`` equals the frame's sim time.
A lost datagram (either direction) is recovered by re-sending the same frame after
``resend_timeout_s`` of wall time; stale or duplicate answers are ignored; after
``peer_lost_timeout_s`` of silence ``AutopilotLost`` is raised instead of waiting forever.

Autopilot side (``LockstepClient``, sends to the sim): announces itself with HEARTBEATs
while it has no frames, returns each new frame once, and answers a re-sent frame it has
already answered from its cache without bothering the caller. Both ends drop garbage.
"""

from __future__ import annotations

import argparse
import time
from dataclasses import dataclass

from mavlink_bridge.codec import (
    AUTOPILOT_COMPONENT_ID,
    AUTOPILOT_SYSTEM_ID,
    SIM_COMPONENT_ID,
    SIM_SYSTEM_ID,
    Decoder,
    Encoder,
    Heartbeat,
)
from mavlink_bridge.contract.wire import ActuatorCommand, GpsSample, GroundTruth, ObstacleDetection, SensorSample
from mavlink_bridge.link import LinkMode, LinkUrl, LinkUrlError, UdpLink

DEFAULT_SIM_PORT = 14560
DEFAULT_LISTEN_URL = f"udpin:127.0.0.1:{DEFAULT_SIM_PORT}"
DEFAULT_SIM_URL = f"udpout:127.0.0.1:{DEFAULT_SIM_PORT}"
#: Wall time each end busy-polls for the peer's datagram before it sleeps in ``poll``. Each end of a
#: lockstep waits for the other's step (~50-150 µs here); a sleeping receiver costs the sender ~20 µs more
#: in ``sendto`` and itself ~20-30 µs to wake on a VM. 1 ms covers a slow autopilot step (whole flight
#: 19× vs 16× real time with 100 µs, same machine, interleaved runs); a spin that finds nothing backs
#: off (``UdpLink.recv``), so at ``--speed 1`` the cost is one spin every 256 frames. 0 on one CPU.
DEFAULT_SPIN_S = 0.001
_SPIN_US_MAX = 100_000.0


def _spin_us(text: str) -> float:
    """``--lockstep-spin-us``: 0..100000 µs."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected microseconds, got {text!r}") from None
    if not 0.0 <= value <= _SPIN_US_MAX:
        raise argparse.ArgumentTypeError(f"expected 0..{_SPIN_US_MAX:g} µs, got {text!r}")
    return value


def add_spin_option(parser: argparse.ArgumentParser, waits_for: str) -> None:
    """``--lockstep-spin-us US`` (the ``spin_s`` of ``LockstepServer``/``LockstepClient`` in µs) for a CLI
    whose lockstep end waits for ``waits_for``."""
    default_us = DEFAULT_SPIN_S * 1e6
    parser.add_argument(
        "--lockstep-spin-us",
        type=_spin_us,
        default=default_us,
        metavar="US",
        help=f"busy-poll for {waits_for} this long before sleeping (default {default_us:g}; 0 = never)",
    )


@dataclass(frozen=True, slots=True)
class LockstepFrame:
    """Everything the sim sends for one control step; ``sensor.time_us`` is the frame id."""

    sensor: SensorSample
    gps: GpsSample | None
    truth: GroundTruth
    detections: tuple[ObstacleDetection, ...] = ()

    @property
    def time_us(self) -> int:
        """Sim time of this frame (µs); the answer must echo it."""
        return self.sensor.time_us


class AutopilotLost(RuntimeError):  # noqa: N818 (name fixed by the lockstep contract)
    """The autopilot stopped answering for longer than the server's ``peer_lost_timeout_s``."""


class LockstepInterrupted(RuntimeError):  # noqa: N818 (parallel to AutopilotLost)
    """``LockstepServer.interrupt`` was called (e.g. from a SIGTERM handler) while waiting."""


@dataclass(frozen=True, slots=True)
class LockstepServerStats:
    """Counters of a ``LockstepServer``."""

    frames: int  # frames exchanged (answered)
    resends: int  # frames sent again after resend_timeout_s without the matching answer
    stale_answers: int  # actuator messages for another (older) frame: ignored
    malformed: int  # datagram content that was not valid MAVLink
    ignored: int  # valid MAVLink the lockstep does not use


@dataclass(frozen=True, slots=True)
class LockstepClientStats:
    """Counters of a ``LockstepClient``."""

    frames: int  # new frames returned to the caller
    reanswered: int  # re-sent frames answered again from the cache
    duplicates: int  # copies of the frame being worked on (ignored)
    stale_frames: int  # frames older than the last answered one (ignored)
    incomplete_frames: int  # HIL_SENSOR before any HIL_STATE_QUATERNION (dropped)
    heartbeats: int  # HEARTBEATs sent to announce the autopilot
    malformed: int
    ignored: int


def encode_frame(encoder: Encoder, frame: LockstepFrame) -> bytes:
    """One datagram for a frame: HIL_GPS?, HIL_STATE_QUATERNION, OBSTACLE_DISTANCE_3D*, HIL_SENSOR last."""
    parts = [] if frame.gps is None else [encoder.gps(frame.gps)]
    parts.append(encoder.truth(frame.truth))
    parts.extend(encoder.detection(d) for d in frame.detections)
    parts.append(encoder.sensor(frame.sensor))
    return b"".join(parts)


class LockstepServer:
    """Sim end of the lockstep: one ``exchange`` per control step (SPEC §4)."""

    def __init__(
        self,
        listen_url: str = DEFAULT_LISTEN_URL,
        *,
        resend_timeout_s: float = 0.02,
        peer_lost_timeout_s: float = 3.0,
        spin_s: float = DEFAULT_SPIN_S,
    ) -> None:
        url = LinkUrl.parse(listen_url)
        if url.mode is not LinkMode.LISTEN:
            raise LinkUrlError(f"the simulator listens: use udpin:HOST:PORT or udp:HOST:PORT, got {listen_url!r}")
        self.resend_timeout_s = resend_timeout_s
        self.peer_lost_timeout_s = peer_lost_timeout_s
        self._link = UdpLink(url, follow_sender=False, spin_s=spin_s)
        self._encoder = Encoder(SIM_SYSTEM_ID, SIM_COMPONENT_ID)
        self._decoder = Decoder()
        self._frames = 0
        self._resends = 0
        self._stale = 0
        self._interrupted = False
        self._frame_time_us = -1  # the frame of the last send (what wait_answer waits for)
        self._datagram = b""
        self._sent_at_s = 0.0

    def interrupt(self) -> None:
        """Make a waiting ``exchange`` raise ``LockstepInterrupted`` (and ``wait_for_autopilot`` return
        False) within one ``resend_timeout_s``; safe to call from a signal handler."""
        self._interrupted = True

    @property
    def local_address(self) -> tuple[str, int]:
        """The bound (host, port)."""
        return self._link.local_address

    @property
    def stats(self) -> LockstepServerStats:
        """A snapshot of the counters."""
        d = self._decoder.stats
        return LockstepServerStats(self._frames, self._resends, self._stale, d.malformed, d.ignored)

    def wait_for_autopilot(self, timeout_s: float | None) -> bool:
        """Block until a HEARTBEAT arrives (True) or ``timeout_s`` passes (False; None = forever)."""
        deadline = None if timeout_s is None else time.monotonic() + timeout_s
        while True:
            remaining = 1.0 if deadline is None else deadline - time.monotonic()
            if remaining <= 0.0 or self._interrupted:
                return False
            data = self._link.recv(min(remaining, self.resend_timeout_s))
            if data is None:
                continue
            for msg in self._decoder.decode(data):
                self._heard()
                if type(msg) is Heartbeat:
                    return True

    def _heard(self) -> None:
        """A valid message came from the autopilot: reply to it from now on."""
        self._link.set_peer(self._link.last_sender)

    def exchange(self, frame: LockstepFrame) -> ActuatorCommand:
        """Send ``frame`` and return the HIL_ACTUATOR_CONTROLS answering it (``time_us`` echoed).

        Re-sends after ``resend_timeout_s`` without the answer; raises ``AutopilotLost``
        after ``peer_lost_timeout_s`` (wall) without any valid message from the autopilot
        during this call, and ``LockstepInterrupted`` after ``interrupt``.
        """
        self.send(frame)
        return self.wait_answer()

    def send(self, frame: LockstepFrame) -> None:
        """First half of ``exchange``: encode and send ``frame``.

        The caller may do work that does not change the frame's state (logging, hashing) while
        the autopilot computes, then call ``wait_answer``.
        """
        self.send_datagram(frame.sensor.time_us, encode_frame(self._encoder, frame))

    def send_datagram(self, frame_time_us: int, datagram: bytes) -> None:
        """``send`` for a frame already encoded (HIL_SENSOR with ``time_usec = frame_time_us`` last).

        For a sim that writes its frames with its own encoder; the bytes must be what ``encode_frame``
        would produce for that frame (``wait_answer`` matches answers on ``frame_time_us``).
        """
        self._frame_time_us = frame_time_us
        self._datagram = datagram
        self._link.send(datagram)
        self._sent_at_s = time.monotonic()

    def wait_answer(self) -> ActuatorCommand:
        """Second half of ``exchange``: the answer to the frame of the last ``send`` (re-sending as needed).

        Silence is counted from that ``send`` (the sim may have been busy before it).
        """
        frame_time_us, datagram = self._frame_time_us, self._datagram
        link, decoder = self._link, self._decoder
        silent_since = self._sent_at_s
        resend_at = silent_since + self.resend_timeout_s
        now = time.monotonic()
        while True:
            data = link.recv(resend_at - now)
            now = time.monotonic()
            if data is not None:
                for msg in decoder.decode(data):
                    silent_since = now
                    link.peer = link.last_sender  # a valid message: reply to its sender (see _heard)
                    if type(msg) is ActuatorCommand:
                        if msg.time_us == frame_time_us:
                            self._frames += 1
                            return msg
                        self._stale += 1
            if now >= resend_at:
                if self._interrupted:
                    raise LockstepInterrupted(f"interrupted while waiting for the answer to t={frame_time_us} us")
                if now - silent_since >= self.peer_lost_timeout_s:
                    raise AutopilotLost(
                        f"no answer from the autopilot for {now - silent_since:.1f} s "
                        f"(frame t={frame_time_us} us, peer {link.peer})"
                    )
                link.send(datagram)
                self._resends += 1
                resend_at = now + self.resend_timeout_s

    def close(self) -> None:
        """Release the socket."""
        self._link.close()

    def __enter__(self) -> LockstepServer:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def _client_url(sim_url: str) -> LinkUrl:
    """The autopilot always sends to the sim: ``udp:`` and ``udpout:`` both mean "send to HOST:PORT"."""
    url = LinkUrl.parse(sim_url)
    if sim_url.startswith("udpin:"):
        raise LinkUrlError(
            f"the autopilot sends to the simulator: use udpout:HOST:PORT or udp:HOST:PORT, got {sim_url!r}"
        )
    return LinkUrl(LinkMode.CONNECT, url.host, url.port)


class LockstepClient:
    """Autopilot end of the lockstep: ``next_frame`` then ``answer`` for each control step."""

    def __init__(
        self,
        sim_url: str = DEFAULT_SIM_URL,
        *,
        heartbeat_period_s: float = 0.5,
        sim_lost_timeout_s: float = 3.0,
        heartbeat: Heartbeat | None = None,
        spin_s: float = DEFAULT_SPIN_S,
    ) -> None:
        self.heartbeat_period_s = heartbeat_period_s
        self.sim_lost_timeout_s = sim_lost_timeout_s
        self._link = UdpLink(_client_url(sim_url), spin_s=spin_s)
        self._encoder = Encoder(AUTOPILOT_SYSTEM_ID, AUTOPILOT_COMPONENT_ID)
        self._decoder = Decoder()
        self._heartbeat_bytes = self._encoder.heartbeat(heartbeat or Heartbeat())
        self._last_heard_s: float | None = None
        self._last_frame_s = -1.0e9
        self._next_heartbeat_s = 0.0
        self._truth: GroundTruth | None = None
        self._gps: GpsSample | None = None
        self._detections: list[ObstacleDetection] = []
        self._pending_time_us = -1
        self._answered_time_us = -1
        self._answer_bytes = b""
        self._frames = 0
        self._reanswered = 0
        self._duplicates = 0
        self._stale = 0
        self._incomplete = 0
        self._heartbeats = 0

    @property
    def connected(self) -> bool:
        """True once anything valid came from the sim."""
        return self._last_heard_s is not None

    @property
    def sim_lost(self) -> bool:
        """True when the sim was heard once and then silent for ``sim_lost_timeout_s``."""
        return self._last_heard_s is not None and time.monotonic() - self._last_heard_s > self.sim_lost_timeout_s

    @property
    def stats(self) -> LockstepClientStats:
        """A snapshot of the counters."""
        d = self._decoder.stats
        return LockstepClientStats(
            self._frames,
            self._reanswered,
            self._duplicates,
            self._stale,
            self._incomplete,
            self._heartbeats,
            d.malformed,
            d.ignored,
        )

    def set_heartbeat(self, heartbeat: Heartbeat) -> None:
        """What the announcing HEARTBEATs carry from now on (e.g. the current mode)."""
        self._heartbeat_bytes = self._encoder.heartbeat(heartbeat)

    def next_frame(self, timeout_s: float) -> LockstepFrame | None:
        """The next new frame, or None after ``timeout_s`` (wall) without one.

        While no frame has come for ``heartbeat_period_s`` a HEARTBEAT is sent every
        ``heartbeat_period_s`` (start-up, or a restarted sim). Re-sent frames already
        answered are answered again from the cache and not returned.
        """
        now = time.monotonic()
        deadline = now + timeout_s
        link = self._link
        while True:
            if now - self._last_frame_s >= self.heartbeat_period_s and now >= self._next_heartbeat_s:
                link.send(self._heartbeat_bytes)
                self._heartbeats += 1
                self._next_heartbeat_s = now + self.heartbeat_period_s
            wait_s = deadline - now
            if now - self._last_frame_s >= self.heartbeat_period_s:
                wait_s = min(wait_s, self._next_heartbeat_s - now)
            data = link.recv(max(wait_s, 0.0))
            now = time.monotonic()
            if data is not None:
                frame = self._absorb(data, now)
                if frame is not None:
                    self._last_frame_s = now
                    return frame
            if now >= deadline:
                return None

    def _absorb(self, data: bytes, now: float) -> LockstepFrame | None:
        """Collect the messages of one datagram; a HIL_SENSOR completes a frame."""
        frame: LockstepFrame | None = None
        last = self._last_heard_s
        if last is not None and now - last > self.sim_lost_timeout_s:  # a restarted sim counts from zero again
            self._answered_time_us = self._pending_time_us = -1
        for msg in self._decoder.decode(data):
            self._last_heard_s = now
            kind = type(msg)
            if kind is GroundTruth:
                self._truth = msg
            elif kind is GpsSample:
                self._gps = msg
            elif kind is ObstacleDetection:
                self._detections.append(msg)
            elif kind is SensorSample:
                t = msg.time_us
                gps, detections = self._gps, tuple(self._detections)
                self._gps = None
                self._detections.clear()
                if t == self._answered_time_us:
                    self._link.send(self._answer_bytes)
                    self._reanswered += 1
                elif t == self._pending_time_us:
                    self._duplicates += 1
                elif t < self._answered_time_us or t < self._pending_time_us:
                    self._stale += 1
                elif self._truth is None:
                    self._incomplete += 1
                else:
                    frame = LockstepFrame(msg, gps, self._truth, detections)
                    self._pending_time_us = t
                    self._frames += 1
        return frame

    def answer(self, cmd: ActuatorCommand) -> None:
        """Send the HIL_ACTUATOR_CONTROLS for the frame with ``cmd.time_us`` (and cache it for re-sends)."""
        self._answer_bytes = self._encoder.actuators(cmd)
        self._answered_time_us = cmd.time_us
        if self._pending_time_us == cmd.time_us:
            self._pending_time_us = -1
        self._link.send(self._answer_bytes)

    def close(self) -> None:
        """Release the socket."""
        self._link.close()

    def __enter__(self) -> LockstepClient:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
