"""The autopilot's I/O loop: the lockstep link, the GCS/API links and the telemetry listener (SPEC §3-§4).

Reads frames from the lockstep client and requests from the GCS servers; emits the answer of each frame at
once, then the telemetry snapshot, status texts and the listener's step record. GCS and API links are
polled between frames and never block the lockstep.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field

from autopilot.reporting.report import AutopilotEndReason
from autopilot.runner import Autopilot

#: Publish the telemetry snapshot every this many control steps (62.5 Hz at 250 Hz) and on any event.
SNAPSHOT_EVERY = 4
#: Poll the GCS/API links at most this often (wall seconds).
LINK_POLL_PERIOD_S = 0.004
#: Without GCS/API links, wake this often while waiting for a frame (only to notice a lost sim or a stop): a
#: fleet's autopilots wait for the slowest one every step, and each empty wake-up costs CPU the others need.
IDLE_WAKE_PERIOD_S = 0.1


@dataclass
class Links:
    """The sockets of one autopilot process (SPEC §3); any of the GCS/API servers may be absent."""

    lockstep: object  # mavlink_bridge.lockstep.LockstepClient
    gcs: list[object] = field(default_factory=list)  # mavlink_bridge.gcs_server.server.GcsServer


def run_loop(
    autopilot: Autopilot,
    links: Links,
    should_stop: Callable[[], bool],
    *,
    connect_timeout_s: float = 30.0,
) -> AutopilotEndReason:
    """Serve the lockstep until stopped or the sim is gone; GCS links polled between frames."""
    client = links.lockstep
    servers = links.gcs
    autopilot.links.watch_gcs(servers)  # type: ignore[arg-type]
    t0 = time.monotonic()
    next_poll = 0.0
    steps = 0
    reason = AutopilotEndReason.STOPPED
    wait_s = LINK_POLL_PERIOD_S if servers else IDLE_WAKE_PERIOD_S
    while not should_stop():
        frame = client.next_frame(wait_s)  # type: ignore[attr-defined]
        now = time.monotonic()
        if frame is not None:
            cmd = autopilot.step(frame)
            client.answer(cmd, autopilot.own_reporter.report_for(cmd.time_us))  # type: ignore[attr-defined]
            autopilot.after_answer()  # while the sim integrates the next step
            steps += 1
        elif should_stop():  # asked to stop while waiting: a stop, even if the sim went quiet meanwhile
            break
        elif client.sim_lost:  # type: ignore[attr-defined]
            reason = AutopilotEndReason.SIM_LOST
            break
        elif not client.connected and now - t0 > connect_timeout_s:  # type: ignore[attr-defined]
            reason = AutopilotEndReason.SIM_NEVER_CONNECTED
            break
        texts = autopilot.drain_texts()
        if servers:
            state = autopilot.state
            sim_us = state.time_us if state is not None else 0
            if frame is not None and (steps % SNAPSHOT_EVERY == 0 or texts or autopilot.progress.pending):
                snapshot = autopilot.snapshot()
                if snapshot is not None:
                    for server in servers:
                        server.publish(snapshot)  # type: ignore[attr-defined]
            for text in texts:
                for server in servers:
                    server.statustext(text.severity, text.text)  # type: ignore[attr-defined]
            if frame is None or now >= next_poll:
                next_poll = now + LINK_POLL_PERIOD_S
                for server in servers:
                    server.poll(sim_us, now)  # type: ignore[attr-defined]
        listener = autopilot.listener
        if listener is not None:
            record = autopilot.record(texts) if frame is not None else None
            if record is not None:
                listener.on_step(record)
            else:  # no step carries them: the texts still reach the recording, at the latest sim time
                time_us = autopilot.state.time_us if autopilot.state is not None else 0
                for text in texts:
                    listener.on_event(text.text, text.severity, time_us)
    autopilot.end_reason = reason
    return reason
