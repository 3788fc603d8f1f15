"""What both lockstep ends share (SPEC §4): the frame, the errors, the counters, the checks at the edge and
the adaptive resend timer. ``mavlink_bridge.lockstep`` is the public module; import from there.
"""

from __future__ import annotations

import argparse
import math
from dataclasses import dataclass

from mavlink_bridge.contract.wire import GpsSample, GroundTruth, ObstacleDetection, SensorSample
from mavlink_bridge.wire.codec import Encoder

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
MIN_RESEND_TIMEOUT_S = 0.00015  # ~2 exchanges on an idle loopback; a spurious resend costs one cached re-answer
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
