"""The autopilot's end of the lockstep (SPEC §4): ``LockstepClient``. Import it from ``mavlink_bridge.lockstep``.

It sends to the sim, announces itself with HEARTBEATs while it has no frames, returns each new frame once, and
answers a re-sent frame it has already answered from its cache without bothering the caller.
"""

from __future__ import annotations

import time

from mavlink_bridge.contract.wire import ActuatorCommand, GpsSample, GroundTruth, ObstacleDetection, SensorSample
from mavlink_bridge.lockstep.answer_kernel import AnswerWriter
from mavlink_bridge.lockstep.edge import (
    DEFAULT_SIM_URL,
    DEFAULT_SPIN_S,
    MAX_FRAME_STEP_US,
    MAX_FRAME_TIME_US,
    LockstepClientStats,
    LockstepFrame,
    detection_ok,
    frame_values_ok,
)
from mavlink_bridge.wire.codec import AUTOPILOT_COMPONENT_ID, AUTOPILOT_SYSTEM_ID, Decoder, Encoder, Heartbeat
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
        self._answers = AnswerWriter(AUTOPILOT_SYSTEM_ID, AUTOPILOT_COMPONENT_ID)  # in place, own sequence
        self._answers.write(0, (0.0, 0.0, 0.0, 0.0), False, False, True)  # load the compiled writer now
        self._answers.seq = 0
        self._answer_len = 0
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
                    self._link.send(self._answers.view[: self._answer_len])
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
        """Send the HIL_ACTUATOR_CONTROLS for the frame with ``cmd.time_us``, written in place by one compiled
        call (kept for re-sends of that frame)."""
        answers = self._answers
        self._answer_len = n = answers.write(cmd.time_us, cmd.motor_cmd, cmd.armed, cmd.gripper_release, cmd.lockstep)
        self._answered_time_us = cmd.time_us
        if self._pending_time_us == cmd.time_us:
            self._pending_time_us = -1
        self._link.send(answers.view[:n])

    def close(self) -> None:
        """Release the socket."""
        self._link.close()

    def __enter__(self) -> LockstepClient:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
