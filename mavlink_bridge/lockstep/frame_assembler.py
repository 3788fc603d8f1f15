"""The autopilot's reading of the lockstep (SPEC §4), without a socket: ``FrameAssembler``. Import it from
``mavlink_bridge.lockstep``.

``LockstepClient`` feeds it the datagrams its simulator sends; the in-process campaign flights feed it the
datagrams the simulator's ``FrameWriter`` writes. Either way a frame is built and checked by the same code.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace

from mavlink_bridge.contract.traffic import TrafficReport, TrafficSource
from mavlink_bridge.contract.wire import GpsSample, GroundTruth, ObstacleDetection, SensorSample
from mavlink_bridge.lockstep.edge import (
    MAX_FRAME_STEP_US,
    MAX_FRAME_TIME_US,
    LockstepFrame,
    detection_ok,
    frame_values_ok,
)
from mavlink_bridge.wire.codec import Decoder, Heartbeat
from mavlink_bridge.wire.traffic_codec import MAV_TYPE_ADSB


class _FrameBuilder:
    """Plain twin of :class:`LockstepFrame` (same slots), filled and re-classed: a frozen slotted dataclass costs a
    descriptor call per field, every frame (``autopilot.estimation.truth._StateBuilder`` explains the pattern)."""

    __slots__ = LockstepFrame.__slots__


def _frame(
    sensor: SensorSample,
    gps: GpsSample | None,
    truth: GroundTruth,
    detections: tuple[ObstacleDetection, ...],
    traffic: tuple[TrafficReport, ...],
) -> LockstepFrame:
    """``LockstepFrame(sensor, gps, truth, detections, traffic)`` without the frozen dataclass's ``__init__``."""
    f = _FrameBuilder()
    f.sensor, f.gps, f.truth, f.detections, f.traffic = sensor, gps, truth, detections, traffic
    f.__class__ = LockstepFrame  # type: ignore[assignment]
    return f  # type: ignore[return-value]


class FrameAssembler:
    """Datagrams from the sim in, each new valid frame out once.

    GroundTruth, GpsSample, ObstacleDetection and TrafficReport messages are collected and HIL_SENSOR closes the
    frame: the detections and traffic reports of its datagram ride with it, an ADS-B report without a time is
    stamped with the frame's. A frame is returned only when its time moves on from the last one by at most
    ``MAX_FRAME_STEP_US`` (any time up to ``MAX_FRAME_TIME_US`` for the first frame, or after ``restart``), it
    has the truth of its time and its values pass ``frame_values_ok``/``detection_ok``; anything else is counted
    and dropped. A re-sent frame already answered calls ``resend_answer`` (the caller re-sends its cached answer).
    """

    def __init__(self, resend_answer: Callable[[], None] | None = None) -> None:
        """``resend_answer``: called for each re-sent frame whose answer was already sent (``answered``)."""
        self.decoder = Decoder()
        self._resend_answer = resend_answer
        self._truth: GroundTruth | None = None
        self._gps: GpsSample | None = None
        self._detections: list[ObstacleDetection] = []
        self._traffic: list[TrafficReport] = []
        self._pending_time_us = -1
        self._answered_time_us = -1
        #: Whether the last datagram held any valid message (the sim was heard).
        self.heard = False
        #: Sim time (µs) of the frame with the traffic receiver's last HEARTBEAT (MAV_TYPE_ADSB); -1: never heard.
        self.traffic_receiver_t_us = -1
        self.frames = 0  # new frames returned
        self.reanswered = 0  # re-sent frames already answered
        self.duplicates = 0  # copies of the frame being worked on
        self.stale = 0  # frames older than the last answered or pending one
        self.incomplete = 0  # HIL_SENSOR without the HIL_STATE_QUATERNION of its time
        self.future = 0  # frames too far ahead, or beyond MAX_FRAME_TIME_US
        self.invalid = 0  # frames with non-finite or absurd values

    def restart(self) -> None:
        """Forget the frame times (a restarted sim counts from zero again)."""
        self._answered_time_us = self._pending_time_us = -1

    def answered(self, time_us: int) -> None:
        """The answer for the frame at ``time_us`` was sent: a re-send of that frame calls ``resend_answer``."""
        self._answered_time_us = time_us
        if self._pending_time_us == time_us:
            self._pending_time_us = -1

    def absorb(self, data: bytes) -> LockstepFrame | None:
        """Collect the messages of one datagram; the new frame its HIL_SENSOR completes, else None."""
        frame: LockstepFrame | None = None
        receiver_heard = False
        self.heard = False
        for msg in self.decoder.decode(data):
            self.heard = True
            kind = type(msg)
            if kind is GroundTruth:
                self._truth = msg
            elif kind is GpsSample:
                self._gps = msg
            elif kind is ObstacleDetection:
                self._detections.append(msg)
            elif kind is TrafficReport:
                self._traffic.append(msg)
            elif kind is Heartbeat and msg.mav_type == MAV_TYPE_ADSB:
                receiver_heard = True
            elif kind is SensorSample:
                t = msg.time_us
                gps, truth = self._gps, self._truth
                self._gps = None
                if t == self._answered_time_us:
                    if self._resend_answer is not None:
                        self._resend_answer()
                    self.reanswered += 1
                elif t == self._pending_time_us:
                    self.duplicates += 1
                elif t < self._answered_time_us or t < self._pending_time_us:
                    self.stale += 1
                elif t > MAX_FRAME_TIME_US or (
                    t > max(self._answered_time_us, self._pending_time_us) + MAX_FRAME_STEP_US
                    and (self._answered_time_us >= 0 or self._pending_time_us >= 0)
                ):
                    self.future += 1
                elif truth is None or truth.time_us != t:
                    self.incomplete += 1
                elif not frame_values_ok(msg, truth, gps) or (
                    self._detections and not all(map(detection_ok, self._detections))
                ):
                    self.invalid += 1
                else:
                    traffic = tuple(  # ADS-B carries no time: stamped now (a UTM report at sim time 0 keeps it)
                        replace(r, t_us=t) if r.source is TrafficSource.MANNED else r for r in self._traffic
                    )
                    frame = _frame(msg, gps, truth, tuple(self._detections), traffic)
                    self._pending_time_us = t
                    self.frames += 1
                    if receiver_heard:
                        self.traffic_receiver_t_us = t
                self._detections.clear()
                self._traffic.clear()
        return frame

    def frame(self, data: bytes) -> LockstepFrame:
        """The frame of a datagram that must complete one (the in-process flights: no loss, no re-sends)."""
        frame = self.absorb(data)
        if frame is None:
            counts = {
                "duplicate": self.duplicates,
                "stale": self.stale,
                "incomplete": self.incomplete,
                "future": self.future,
                "invalid": self.invalid,
            }
            why = ", ".join(f"{n} {name}" for name, n in counts.items() if n) or "no HIL_SENSOR"
            raise RuntimeError(f"a lockstep datagram made no frame ({why})")
        return frame
