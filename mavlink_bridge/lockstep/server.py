"""The simulator's end of the lockstep (SPEC §4): ``LockstepServer``. Import it from ``mavlink_bridge.lockstep``."""

from __future__ import annotations

import random
import time

import numpy as np

from mavlink_bridge.contract.traffic import TrafficReport
from mavlink_bridge.contract.wire import ActuatorCommand
from mavlink_bridge.lockstep.answer_kernel import (
    A_ARMED,
    A_GRIPPER_RELEASE,
    A_MOTORS,
    ANSWER_INVALID,
    ANSWER_OK,
    ANSWER_OTHER,
    ANSWER_STALE,
    N_ANSWER,
    read_answer,
)
from mavlink_bridge.lockstep.edge import (
    DEFAULT_LISTEN_URL,
    DEFAULT_SPIN_S,
    MAX_CANDIDATES,
    MIN_RESEND_TIMEOUT_S,
    AutopilotLost,
    LockstepFrame,
    LockstepInterrupted,
    LockstepServerStats,
    ResendTimer,
    encode_frame,
)
from mavlink_bridge.wire.codec import SIM_COMPONENT_ID, SIM_SYSTEM_ID, Decoder, Encoder, Heartbeat
from mavlink_bridge.wire.link import LinkMode, LinkUrl, LinkUrlError, UdpLink


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
        loss_fraction: float = 0.0,
        loss_seed: int = 0,
    ) -> None:
        """``resend_timeout_s`` is the ceiling of the adaptive resend timeout, ``min_resend_timeout_s`` its floor.

        ``loss_fraction`` (``--sim-loss``): once the lockstep runs, this share of the datagrams is dropped each way
        at this end, at random (seeded), as a lossy network would; the flight stays the same flight.
        """
        if not 0.0 <= loss_fraction < 1.0:
            raise ValueError(f"lockstep loss: expected a fraction in [0, 1), got {loss_fraction}")
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
        self.answer = np.zeros(N_ANSWER)  # the last valid answer's values (``answer_kernel.A_*``)
        #: The vehicle's own UTM_GLOBAL_POSITION reports that rode in the datagram of the last valid answer (decoded
        #: as UAV ``TrafficReport`` objects; empty on most steps). Checked by the simulator, not here (SPEC §13).
        self.own_reports: tuple[TrafficReport, ...] = ()
        self._payload = np.zeros(96, dtype=np.uint8)  # read_answer's zero-padded payload scratch
        read_answer(self._link.array, 0, 0, self.answer, self._payload)  # load the compiled reader now
        self._datagram = b""
        self._sent_at_s = 0.0
        self._loss = loss_fraction
        self._loss_rng = random.Random(loss_seed)
        self.dropped = 0  # datagrams the loss injection dropped (both ways)

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
        self._send(datagram)
        self._sent_at_s = time.monotonic()

    def _lost(self) -> bool:
        """Loss injection: True when this datagram is to be dropped (only once the lockstep runs)."""
        if self._loss > 0.0 and self._locked and self._loss_rng.random() < self._loss:
            self.dropped += 1
            return True
        return False

    def _send(self, datagram: bytes) -> None:
        if not self._lost():
            self._link.send(datagram)

    def wait_answer(self) -> ActuatorCommand:
        """Second half of ``exchange``: the answer to the frame of the last ``send`` (re-sending as needed).

        ``AutopilotLost`` once ``peer_lost_timeout_s`` passed since that ``send`` (the sim may have been busy
        before it) without a valid answer: HEARTBEATs, stale or invalid answers do not count as one.
        """
        self.wait_answer_into()
        a = self.answer
        motors = (float(a[A_MOTORS]), float(a[A_MOTORS + 1]), float(a[A_MOTORS + 2]), float(a[A_MOTORS + 3]))
        return ActuatorCommand(self._frame_time_us, motors, bool(a[A_ARMED] == 1.0), bool(a[A_GRIPPER_RELEASE] == 1.0))

    def wait_answer_into(self) -> None:
        """``wait_answer`` without objects: the answer's values land in ``answer`` (``answer_kernel.A_*``).

        Each datagram from the peer is read in place by one compiled call (``read_answer``); only datagrams
        that are not a plain HIL_ACTUATOR_CONTROLS go through the Python decoder.
        """
        frame_time_us, datagram = self._frame_time_us, self._datagram
        link, timer, out, payload = self._link, self.resend_timer, self.answer, self._payload
        self.own_reports = ()
        array = link.array
        peer = link.peer
        sent_at = self._sent_at_s
        wait_s = timer.timeout_s
        resend_at = sent_at + wait_s
        resent = False
        now = time.monotonic()
        while True:
            n = link.recv_into_buffer(resend_at - now)
            now = time.monotonic()
            if n >= 0:
                if link.last_sender != peer and (self._locked or not self._candidate(n, now)):
                    self._foreign += 1  # a stranger: unread (and no reason to skip the resend check below)
                elif self._lost():
                    pass  # lost on the way in (loss injection): as if it never came
                else:
                    result = read_answer(array, n, frame_time_us, out, payload)
                    if result == ANSWER_OTHER:
                        result = self._decode_other(n, frame_time_us)
                    if result == ANSWER_OK:
                        if not self._locked:
                            self._lock(link.last_sender)
                        self._frames += 1
                        if not resent:
                            timer.sample(now - sent_at)
                        return
                    if result == ANSWER_STALE:
                        self._stale += 1
                    elif result == ANSWER_INVALID:
                        self._invalid += 1  # NaN, out of [0, 1] or ahead of the frame: never applied
            if now >= resend_at:
                if self._interrupted:
                    raise LockstepInterrupted(f"interrupted while waiting for the answer to t={frame_time_us} us")
                if now - sent_at >= self.peer_lost_timeout_s:
                    raise AutopilotLost(
                        f"no answer from the autopilot for {now - sent_at:.1f} s "
                        f"(frame t={frame_time_us} us, peer {peer})"
                    )
                self._send(datagram)
                if not self._locked:
                    for candidate in self._candidates:
                        if candidate != peer:
                            link.send_to(datagram, candidate)
                self._resends += 1
                resent = True
                wait_s = timer.backoff(wait_s)
                resend_at = now + wait_s

    def _decode_other(self, n: int, frame_time_us: int) -> int:
        """A datagram ``read_answer`` did not take, through the Python decoder (counted there); the answer it
        holds, if any, as a ``read_answer`` result (values in ``answer``; the own reports with it in
        ``own_reports``)."""
        result = ANSWER_OTHER
        reports = []
        for msg in self._decoder.decode(bytes(self._link.array[:n])):
            if type(msg) is TrafficReport:
                reports.append(msg)
            if type(msg) is not ActuatorCommand:
                continue
            t, u = msg.time_us, msg.motor_cmd
            if t < frame_time_us:
                self._stale += 1
            elif t > frame_time_us or not all(0.0 <= x <= 1.0 for x in u):
                self._invalid += 1
            else:
                self.answer[A_MOTORS : A_MOTORS + 4] = u
                self.answer[A_ARMED] = 1.0 if msg.armed else 0.0
                self.answer[A_GRIPPER_RELEASE] = 1.0 if msg.gripper_release else 0.0
                result = ANSWER_OK
        if result == ANSWER_OK and reports:
            self.own_reports = tuple(reports)
        return result

    def _candidate(self, n: int, now: float) -> bool:
        """Before the lockstep starts, a datagram (``n`` bytes) from another address: True when it is from a
        candidate (read it like the peer's); a new HEARTBEAT sender becomes one and is sent the current frame."""
        sender = self._link.last_sender
        if sender in self._candidates:
            return True
        if self._heard_heartbeat(bytes(self._link.array[:n]), sender) and sender in self._candidates:
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
