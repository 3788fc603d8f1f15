"""The lockstep protocol, both ends (SPEC §4; PX4 simulator_mavlink compatible).

Sim side (``LockstepServer``, binds ``udpin:127.0.0.1:14560`` by default): waits for a
HEARTBEAT, then for each control step sends ONE datagram holding HIL_GPS (when due),
HIL_STATE_QUATERNION, OBSTACLE_DISTANCE_3D (per detection) and HIL_SENSOR last, and
waits for the HIL_ACTUATOR_CONTROLS whose ``time_usec`` equals the frame's sim time.
A lost datagram (either direction) is recovered by re-sending the same frame after an adaptive
timeout (``ResendTimer``: a few smoothed exchange times, sub-millisecond on loopback, capped at
``resend_timeout_s``); stale or duplicate answers are ignored; after ``peer_lost_timeout_s``
without the answer ``AutopilotLost`` is raised instead of waiting forever.

Autopilot side (``LockstepClient``, sends to the sim): announces itself with HEARTBEATs
while it has no frames, returns each new frame once, and answers a re-sent frame it has
already answered from its cache without bothering the caller.

Each end hears only its peer (the sim: the autopilot whose HEARTBEAT started the lockstep; the
autopilot: the sim it sends to). Datagrams from anyone else, garbage, frames out of time order or
with non-finite or absurd values, and answers with motors outside [0, 1] are counted in the
``stats`` and dropped at the edge: never applied, never fatal.
"""

from __future__ import annotations

import argparse
import math
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


#: Frames further ahead of the last one than this are refused (a lockstep moves one control period at a time;
#: 1 s covers any control rate >= 1 Hz). A frame an hour ahead would otherwise make every later frame "stale".
MAX_FRAME_STEP_US = 1_000_000
#: Largest frame time accepted at all (~11.6 days of sim time): beyond it integer conversions downstream (e.g.
#: MAVLink ``time_boot_ms`` uint32 fields) would overflow; a 2^63 µs stamp is a stranger's, not a simulator's.
MAX_FRAME_TIME_US = 10**12
#: Floor and initial value of the adaptive resend timeout (s); the ceiling is ``resend_timeout_s``.
MIN_RESEND_TIMEOUT_S = 0.00025
INITIAL_RESEND_TIMEOUT_S = 0.005
#: HEARTBEAT senders the sim sends its first frame to before one of them answers it (see ``LockstepServer``).
MAX_CANDIDATES = 8


@dataclass(frozen=True, slots=True)
class LockstepServerStats:
    """Counters of a ``LockstepServer``."""

    frames: int  # frames exchanged (answered)
    resends: int  # frames sent again after the resend timeout without the matching answer
    stale_answers: int  # actuator messages for an older frame: ignored
    malformed: int  # datagram content that was not valid MAVLink
    ignored: int  # valid MAVLink the lockstep does not use
    foreign: int  # datagrams from anyone but the autopilot that started the lockstep: dropped unread
    invalid_answers: int  # answers from the peer stamped ahead of the frame, or with motors non-finite/outside [0, 1]
    resend_timeout_us: float  # the adaptive resend timeout now (smoothed exchange time based)
    exchange_us: float  # smoothed exchange time (send to answer, frames not re-sent)

    def as_dict(self) -> dict[str, float]:
        """The counters by name (for summaries)."""
        return {name: getattr(self, name) for name in self.__slots__}


@dataclass(frozen=True, slots=True)
class LockstepClientStats:
    """Counters of a ``LockstepClient``."""

    frames: int  # new frames returned to the caller
    reanswered: int  # re-sent frames answered again from the cache
    duplicates: int  # copies of the frame being worked on (ignored)
    stale_frames: int  # frames older than the last answered one (ignored)
    incomplete_frames: int  # HIL_SENSOR without the HIL_STATE_QUATERNION of its time (dropped)
    heartbeats: int  # HEARTBEATs sent to announce the autopilot
    malformed: int
    ignored: int
    foreign: int  # datagrams from anyone but the simulator this client sends to: dropped unread
    future_frames: int  # frames more than MAX_FRAME_STEP_US ahead of the last one, or beyond MAX_FRAME_TIME_US
    invalid_frames: int  # frames with non-finite or absurd values (NaN attitude, latitude > 90°, …): dropped

    def as_dict(self) -> dict[str, int]:
        """The counters by name (for ``autopilot_summary.json``)."""
        return {name: getattr(self, name) for name in self.__slots__}


class ResendTimer:
    """The lockstep's retransmission timeout from measured exchange times (RFC 6298's RTO, sub-ms bounds).

    ``sample(rtt_s)`` for each exchange answered without a resend (Karn's rule); ``timeout_s`` is
    ``srtt + 2 * rttvar`` clamped to [``min_s``, ``max_s``]. Each resend of the same frame doubles the wait
    (``backoff``) up to ``max_s``. On loopback an exchange takes ~0.1-0.3 ms, so a lost datagram costs about
    that much again instead of a fixed 20 ms. TCP's 4 * rttvar guards a shared network against spurious
    retransmissions; here one costs the autopilot a cached re-answer (~20 µs), far less than a late resend.
    """

    __slots__ = ("max_s", "min_s", "rttvar_s", "srtt_s", "timeout_s")

    def __init__(self, min_s: float = MIN_RESEND_TIMEOUT_S, max_s: float = 0.02) -> None:
        if not 0.0 < min_s <= max_s:
            raise ValueError(f"resend timeout bounds: expected 0 < min <= max, got {min_s} and {max_s}")
        self.min_s = min_s
        self.max_s = max_s
        self.srtt_s = -1.0  # no sample yet
        self.rttvar_s = 0.0
        self.timeout_s = min(max(INITIAL_RESEND_TIMEOUT_S, min_s), max_s)

    def sample(self, rtt_s: float) -> None:
        """One measured exchange time (s) of a frame that was not re-sent."""
        srtt = self.srtt_s
        if srtt < 0.0:
            srtt, var = rtt_s, 0.5 * rtt_s
        else:
            var = 0.75 * self.rttvar_s + 0.25 * abs(srtt - rtt_s)
            srtt = 0.875 * srtt + 0.125 * rtt_s
        self.srtt_s, self.rttvar_s = srtt, var
        self.timeout_s = min(max(srtt + 2.0 * var, self.min_s), self.max_s)

    def backoff(self, wait_s: float) -> float:
        """The next wait after a resend that followed a wait of ``wait_s``."""
        return min(2.0 * wait_s, self.max_s)


def encode_frame(encoder: Encoder, frame: LockstepFrame) -> bytes:
    """One datagram for a frame: HIL_GPS?, HIL_STATE_QUATERNION, OBSTACLE_DISTANCE_3D*, HIL_SENSOR last."""
    parts = [] if frame.gps is None else [encoder.gps(frame.gps)]
    parts.append(encoder.truth(frame.truth))
    parts.extend(encoder.detection(d) for d in frame.detections)
    parts.append(encoder.sensor(frame.sensor))
    return b"".join(parts)


class LockstepServer:
    """Sim end of the lockstep: one ``exchange`` per control step (SPEC §4).

    The lockstep starts with the first valid answer: until then every address that sent a HEARTBEAT (up to
    ``MAX_CANDIDATES``) is sent the first frame, and the one whose answer comes first (time echoed, motors finite
    and in [0, 1]) is the peer for the rest of the run (so a stranger's early HEARTBEAT cannot take the place of
    the autopilot). From then on datagrams from any other address are counted (``foreign``) and dropped unread;
    the run ends (``AutopilotLost``) before another could take over.
    """

    def __init__(
        self,
        listen_url: str = DEFAULT_LISTEN_URL,
        *,
        resend_timeout_s: float = 0.02,
        peer_lost_timeout_s: float = 3.0,
        spin_s: float = DEFAULT_SPIN_S,
        min_resend_timeout_s: float = MIN_RESEND_TIMEOUT_S,
    ) -> None:
        """``resend_timeout_s`` is the ceiling of the adaptive resend timeout, ``min_resend_timeout_s`` its floor."""
        url = LinkUrl.parse(listen_url)
        if url.mode is not LinkMode.LISTEN:
            raise LinkUrlError(f"the simulator listens: use udpin:HOST:PORT or udp:HOST:PORT, got {listen_url!r}")
        self.resend_timeout_s = resend_timeout_s
        self.peer_lost_timeout_s = peer_lost_timeout_s
        self.resend_timer = ResendTimer(min(min_resend_timeout_s, resend_timeout_s), resend_timeout_s)
        self._link = UdpLink(url, follow_sender=False, spin_s=spin_s)
        self._encoder = Encoder(SIM_SYSTEM_ID, SIM_COMPONENT_ID)
        self._decoder = Decoder()
        self._frames = 0
        self._resends = 0
        self._stale = 0
        self._foreign = 0
        self._invalid = 0
        self._interrupted = False
        self._candidates: list[tuple[str, int]] = []  # HEARTBEAT senders before the first valid answer
        self._locked = False  # the peer answered a frame: nobody else is heard from now on
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
    def peer(self) -> tuple[str, int] | None:
        """The autopilot's address once it answered the first frame (None before)."""
        return self._link.peer if self._locked else None

    @property
    def stats(self) -> LockstepServerStats:
        """A snapshot of the counters."""
        d, timer = self._decoder.stats, self.resend_timer
        return LockstepServerStats(
            self._frames,
            self._resends,
            self._stale,
            d.malformed,
            d.ignored,
            self._foreign,
            self._invalid,
            timer.timeout_s * 1e6,
            max(timer.srtt_s, 0.0) * 1e6,
        )

    def wait_for_autopilot(self, timeout_s: float | None) -> bool:
        """Block until a HEARTBEAT arrives (True) or ``timeout_s`` passes (False; None = forever).

        Its sender is sent the first frame (see the class docstring for who becomes the peer).
        """
        deadline = None if timeout_s is None else time.monotonic() + timeout_s
        link = self._link
        while True:
            remaining = 1.0 if deadline is None else deadline - time.monotonic()
            if remaining <= 0.0 or self._interrupted:
                return False
            data = link.recv(min(remaining, self.resend_timeout_s))
            if data is not None and self._heard_heartbeat(data, link.last_sender):
                link.set_peer(link.last_sender)
                return True

    def _heard_heartbeat(self, data: bytes, sender: tuple[str, int] | None) -> bool:
        """Before the lockstep starts: True when ``data`` holds a HEARTBEAT (its sender becomes a candidate)."""
        if sender is None or not any(type(msg) is Heartbeat for msg in self._decoder.decode(data)):
            return False
        if sender not in self._candidates and len(self._candidates) < MAX_CANDIDATES:
            self._candidates.append(sender)
        return True

    def exchange(self, frame: LockstepFrame) -> ActuatorCommand:
        """Send ``frame`` and return the HIL_ACTUATOR_CONTROLS answering it (``time_us`` echoed).

        Re-sends after the adaptive resend timeout without the answer; raises ``AutopilotLost``
        after ``peer_lost_timeout_s`` (wall) without the answer, and ``LockstepInterrupted`` after ``interrupt``.
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

        ``AutopilotLost`` once ``peer_lost_timeout_s`` passed since that ``send`` (the sim may have been busy
        before it) without a valid answer: HEARTBEATs, stale or invalid answers do not count as one.
        """
        frame_time_us, datagram = self._frame_time_us, self._datagram
        link, decoder, timer = self._link, self._decoder, self.resend_timer
        peer = link.peer
        sent_at = self._sent_at_s
        wait_s = timer.timeout_s
        resend_at = sent_at + wait_s
        resent = False
        now = time.monotonic()
        while True:
            data = link.recv(resend_at - now)
            now = time.monotonic()
            if data is not None and link.last_sender != peer and (self._locked or not self._candidate(data, now)):
                self._foreign += 1  # a stranger: unread (and no reason to skip the resend check below)
            elif data is not None:
                for msg in decoder.decode(data):
                    if type(msg) is ActuatorCommand:
                        t = msg.time_us
                        if t == frame_time_us:
                            u = msg.motor_cmd
                            if 0.0 <= u[0] <= 1.0 and 0.0 <= u[1] <= 1.0 and 0.0 <= u[2] <= 1.0 and 0.0 <= u[3] <= 1.0:
                                if not self._locked:
                                    self._lock(link.last_sender)
                                self._frames += 1
                                if not resent:
                                    timer.sample(now - sent_at)
                                return msg
                            self._invalid += 1  # NaN or out of range: never applied
                        elif t > frame_time_us:
                            self._invalid += 1  # an answer to a frame not sent yet
                        else:
                            self._stale += 1
            if now >= resend_at:
                if self._interrupted:
                    raise LockstepInterrupted(f"interrupted while waiting for the answer to t={frame_time_us} us")
                if now - sent_at >= self.peer_lost_timeout_s:
                    raise AutopilotLost(
                        f"no answer from the autopilot for {now - sent_at:.1f} s "
                        f"(frame t={frame_time_us} us, peer {peer})"
                    )
                link.send(datagram)
                if not self._locked:
                    for candidate in self._candidates:
                        if candidate != peer:
                            link.send_to(datagram, candidate)
                self._resends += 1
                resent = True
                wait_s = timer.backoff(wait_s)
                resend_at = now + wait_s

    def _candidate(self, data: bytes, now: float) -> bool:
        """Before the lockstep starts, a datagram from another address: True when it is from a candidate (read it
        like the peer's); a new HEARTBEAT sender becomes one and is sent the current frame."""
        sender = self._link.last_sender
        if sender in self._candidates:
            return True
        if self._heard_heartbeat(data, sender) and sender in self._candidates:
            self._link.send_to(self._datagram, sender)
        return False

    def _lock(self, sender: tuple[str, int] | None) -> None:
        """``sender`` answered first: it is the peer for the rest of the run."""
        self._link.set_peer(sender)
        self._locked = True
        self._candidates.clear()

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


def frame_values_ok(sensor: SensorSample, truth: GroundTruth, gps: GpsSample | None) -> bool:
    """True when a frame's values are usable: all finite, a unit attitude quaternion, latitude/longitude in range,
    truth and GPS stamped with the frame's time. One sum per message: a NaN or infinity anywhere makes it
    non-finite (float32 values cannot overflow a double sum)."""
    a, g, m = sensor.accel_frd_m_s2, sensor.gyro_frd_rad_s, sensor.mag_frd_gauss
    q, w = truth.q_ned_frd, truth.rate_frd_rad_s
    total = a[0] + a[1] + a[2] + g[0] + g[1] + g[2] + m[0] + m[1] + m[2] + w[0] + w[1] + w[2]
    total += sensor.abs_pressure_hpa + sensor.pressure_alt_m + sensor.temperature_degc
    norm2 = q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]
    t = sensor.time_us
    if not (
        math.isfinite(total)
        and 0.5 <= norm2 <= 1.5
        and truth.time_us == t
        and -90.0 <= truth.lat_deg <= 90.0
        and -180.0 <= truth.lon_deg <= 180.0
    ):
        return False
    return gps is None or (gps.time_us == t and -90.0 <= gps.lat_deg <= 90.0 and -180.0 <= gps.lon_deg <= 180.0)


def detection_ok(d: ObstacleDetection) -> bool:
    """A detection with a finite position and a finite, non-negative radius."""
    p = d.pos_frd_m
    return math.isfinite(p[0] + p[1] + p[2]) and 0.0 <= d.radius_m < math.inf


class LockstepClient:
    """Autopilot end of the lockstep: ``next_frame`` then ``answer`` for each control step.

    Only the simulator it sends to is heard: datagrams from any other address are counted (``foreign``) and
    dropped unread. A frame is returned only when its time moves on from the last one by at most
    ``MAX_FRAME_STEP_US`` (any time up to ``MAX_FRAME_TIME_US`` for the first frame, or after the sim was lost)
    and its values pass ``frame_values_ok``; anything else is counted and dropped (the sim re-sends).
    """

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
        self._foreign = 0
        self._future = 0
        self._invalid = 0

    @property
    def connected(self) -> bool:
        """True once anything valid came from the sim."""
        return self._last_heard_s is not None

    @property
    def sim_lost(self) -> bool:
        """True when the sim was heard once and then silent for ``sim_lost_timeout_s``."""
        return self._last_heard_s is not None and time.monotonic() - self._last_heard_s > self.sim_lost_timeout_s

    @property
    def local_address(self) -> tuple[str, int]:
        """The (host, port) this client sends from (where the sim's frames arrive)."""
        return self._link.local_address

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
            self._foreign,
            self._future,
            self._invalid,
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
                if link.last_sender != link.peer:
                    self._foreign += 1
                else:
                    frame = self._absorb(data, now)
                    if frame is not None:
                        self._last_frame_s = now
                        return frame
            if now >= deadline:
                return None

    def _absorb(self, data: bytes, now: float) -> LockstepFrame | None:
        """Collect the messages of one datagram from the sim; a HIL_SENSOR completes a frame."""
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
                gps, truth = self._gps, self._truth
                self._gps = None
                if t == self._answered_time_us:
                    self._link.send(self._answer_bytes)
                    self._reanswered += 1
                elif t == self._pending_time_us:
                    self._duplicates += 1
                elif t < self._answered_time_us or t < self._pending_time_us:
                    self._stale += 1
                elif t > MAX_FRAME_TIME_US or (
                    t > max(self._answered_time_us, self._pending_time_us) + MAX_FRAME_STEP_US
                    and (self._answered_time_us >= 0 or self._pending_time_us >= 0)
                ):
                    self._future += 1
                elif truth is None or truth.time_us != t:
                    self._incomplete += 1
                elif not frame_values_ok(msg, truth, gps) or (
                    self._detections and not all(map(detection_ok, self._detections))
                ):
                    self._invalid += 1
                else:
                    frame = LockstepFrame(msg, gps, truth, tuple(self._detections))
                    self._pending_time_us = t
                    self._frames += 1
                self._detections.clear()
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
