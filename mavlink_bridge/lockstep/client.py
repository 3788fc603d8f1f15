"""The autopilot's end of the lockstep (SPEC §4): ``LockstepClient``. Import it from ``mavlink_bridge.lockstep``.

It sends to the sim, announces itself with HEARTBEATs while it has no frames, returns each new frame once, and
answers a re-sent frame it has already answered from its cache without bothering the caller. Once the simulator's
traffic receiver was heard, the vehicle's own UTM_GLOBAL_POSITION (an ``OwnPositionReport``) rides in the datagram
of the answer it is given with, so the simulator takes it at that step, at any speed (SPEC §13).
"""

from __future__ import annotations

import time

from mavlink_bridge.contract.traffic import OwnPositionReport
from mavlink_bridge.contract.wire import ActuatorCommand
from mavlink_bridge.lockstep.answer_kernel import AnswerWriter
from mavlink_bridge.lockstep.edge import DEFAULT_SIM_URL, DEFAULT_SPIN_S, LockstepClientStats, LockstepFrame
from mavlink_bridge.lockstep.frame_assembler import FrameAssembler
from mavlink_bridge.wire.codec import AUTOPILOT_COMPONENT_ID, AUTOPILOT_SYSTEM_ID, Encoder, Heartbeat
from mavlink_bridge.wire.link import LinkMode, LinkUrl, LinkUrlError, UdpLink


def _client_url(sim_url: str) -> LinkUrl:
    """The autopilot always sends to the sim: ``udp:`` and ``udpout:`` both mean "send to HOST:PORT"."""
    url = LinkUrl.parse(sim_url)
    if sim_url.startswith("udpin:"):
        raise LinkUrlError(
            f"the autopilot sends to the simulator: use udpout:HOST:PORT or udp:HOST:PORT, got {sim_url!r}"
        )
    return LinkUrl(LinkMode.CONNECT, url.host, url.port)


class LockstepClient:
    """Autopilot end of the lockstep: ``next_frame`` then ``answer`` for each control step.

    Only the simulator it sends to is heard: datagrams from any other address are counted (``foreign``) and
    dropped unread. Its datagrams go through a ``FrameAssembler`` (restarted when the sim was lost): a frame out
    of time order, incomplete or with absurd values is counted and dropped (the sim re-sends), a re-sent frame
    already answered gets the cached answer again.
    """

    def __init__(
        self,
        sim_url: str = DEFAULT_SIM_URL,
        *,
        heartbeat_period_s: float = 0.5,
        sim_lost_timeout_s: float = 3.0,
        heartbeat: Heartbeat | None = None,
        spin_s: float = DEFAULT_SPIN_S,
        system_id: int = AUTOPILOT_SYSTEM_ID,
    ) -> None:
        """``system_id``: the vehicle's MAV_SYS_ID (a fleet's instance i is i + 1, as in PX4 SITL)."""
        self.heartbeat_period_s = heartbeat_period_s
        self.sim_lost_timeout_s = sim_lost_timeout_s
        self._link = UdpLink(_client_url(sim_url), spin_s=spin_s)
        self._encoder = Encoder(system_id, AUTOPILOT_COMPONENT_ID)
        self._assembler = FrameAssembler(self._resend_answer)
        self._heartbeat_bytes = self._encoder.heartbeat(heartbeat or Heartbeat())
        self._last_heard_s: float | None = None
        self._last_frame_s = -1.0e9
        self._next_heartbeat_s = 0.0
        self._answers = AnswerWriter(system_id, AUTOPILOT_COMPONENT_ID)  # in place, own sequence
        self._answers.write(0, (0.0, 0.0, 0.0, 0.0), False, False, True)  # load the compiled writer now
        self._answers.seq = 0
        self._answer_len = 0
        self._answer_with_report: bytes | None = None  # the last answer's datagram when a report rode with it
        self.own_reports_sent = 0
        self._heartbeats = 0
        self._foreign = 0

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
        f = self._assembler
        d = f.decoder.stats
        return LockstepClientStats(
            f.frames,
            f.reanswered,
            f.duplicates,
            f.stale,
            f.incomplete,
            self._heartbeats,
            d.malformed,
            d.ignored,
            self._foreign,
            f.future,
            f.invalid,
        )

    @property
    def traffic_receiver_t_us(self) -> int:
        """Sim time (µs) of the frame with the traffic receiver's last HEARTBEAT (MAV_TYPE_ADSB); -1: never heard."""
        return self._assembler.traffic_receiver_t_us

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
        """One datagram from the sim into the assembler; a sim silent past ``sim_lost_timeout_s`` restarted."""
        last = self._last_heard_s
        if last is not None and now - last > self.sim_lost_timeout_s:  # a restarted sim counts from zero again
            self._assembler.restart()
        frame = self._assembler.absorb(data)
        if self._assembler.heard:
            self._last_heard_s = now
        return frame

    def _resend_answer(self) -> None:
        with_report = self._answer_with_report
        self._link.send(with_report if with_report is not None else self._answers.view[: self._answer_len])

    def answer(self, cmd: ActuatorCommand, own_report: OwnPositionReport | None = None) -> None:
        """Send the HIL_ACTUATOR_CONTROLS for the frame with ``cmd.time_us``, written in place by one compiled
        call (kept for re-sends of that frame); ``own_report``: the vehicle's own UTM_GLOBAL_POSITION, sent ahead
        of the answer in its datagram when a traffic receiver was heard (else dropped: nobody listens)."""
        answers = self._answers
        self._answer_len = n = answers.write(cmd.time_us, cmd.motor_cmd, cmd.armed, cmd.gripper_release, cmd.lockstep)
        self._assembler.answered(cmd.time_us)
        self._answer_with_report = None
        if own_report is not None and self._assembler.traffic_receiver_t_us >= 0:
            self._answer_with_report = self._encoder.own_position(own_report) + bytes(answers.view[:n])
            self.own_reports_sent += 1
            self._link.send(self._answer_with_report)
            return
        self._link.send(answers.view[:n])

    def close(self) -> None:
        """Release the socket."""
        self._link.close()

    def __enter__(self) -> LockstepClient:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
