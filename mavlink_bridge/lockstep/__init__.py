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
already answered from its cache without bothering the caller. Its datagrams become frames in
``FrameAssembler``, which has no socket: the in-process campaign flights read the simulator's
datagrams with it too.

Each end hears only its peer (the sim: the autopilot whose HEARTBEAT started the lockstep; the
autopilot: the sim it sends to). Datagrams from anyone else, garbage, frames out of time order or
with non-finite or absurd values, and answers with motors outside [0, 1] are counted in the
``stats`` and dropped at the edge: never applied, never fatal.
"""

from __future__ import annotations

from mavlink_bridge.lockstep.client import LockstepClient
from mavlink_bridge.lockstep.edge import (
    DEFAULT_LISTEN_URL,
    DEFAULT_SIM_PORT,
    DEFAULT_SIM_URL,
    DEFAULT_SPIN_S,
    MAX_CANDIDATES,
    MAX_FRAME_STEP_US,
    MAX_FRAME_TIME_US,
    MIN_RESEND_TIMEOUT_S,
    AutopilotLost,
    LockstepClientStats,
    LockstepFrame,
    LockstepInterrupted,
    LockstepServerStats,
    ResendTimer,
    add_spin_option,
    detection_ok,
    encode_frame,
    frame_values_ok,
)
from mavlink_bridge.lockstep.frame_assembler import FrameAssembler
from mavlink_bridge.lockstep.server import LockstepServer

__all__ = [
    "DEFAULT_LISTEN_URL",
    "DEFAULT_SIM_PORT",
    "DEFAULT_SIM_URL",
    "DEFAULT_SPIN_S",
    "MAX_CANDIDATES",
    "MAX_FRAME_STEP_US",
    "MAX_FRAME_TIME_US",
    "MIN_RESEND_TIMEOUT_S",
    "AutopilotLost",
    "FrameAssembler",
    "LockstepClient",
    "LockstepClientStats",
    "LockstepFrame",
    "LockstepInterrupted",
    "LockstepServer",
    "LockstepServerStats",
    "ResendTimer",
    "add_spin_option",
    "detection_ok",
    "encode_frame",
    "frame_values_ok",
]
