"""Log ANY MAVLink vehicle's standard telemetry to Rerun: nothing here is quadsitl-specific.

Usage: ``python -m tools.monitor [--connect udpin:127.0.0.1:14550] [--rerun save:PATH|connect:URL]
[--duration-s S]``. HEARTBEAT (mode, armed), ATTITUDE, LOCAL_POSITION_NED, GLOBAL_POSITION_INT,
MISSION_CURRENT, MISSION_ITEM_REACHED and STATUSTEXT go to the recording; the timeline
``vehicle_time`` is the vehicle's ``time_boot_ms`` (sim time for a SITL vehicle), and events
without a timestamp (heartbeat, statustext, mission) take the latest one seen. Stops after
``--duration-s`` wall seconds or on SIGINT/SIGTERM; exit 0, 2 on bad options.
"""

from __future__ import annotations

import argparse
import math
import signal
import sys
import time
from collections.abc import Callable
from datetime import datetime
from types import FrameType

import numpy as np
import rerun as rr

from autopilot.telemetry import entities as ent
from autopilot.telemetry.blueprint import monitor_blueprint
from autopilot.telemetry.sinks import RerunSpecError, open_recording, parse_rerun_spec
from mavlink_bridge.contract.frames import quat_from_euler
from mavlink_bridge.gcs_client.telemetry_listener import (
    Attitude,
    GlobalPosition,
    LocalPosition,
    MissionCurrent,
    MissionItemReached,
    StatusTextEvent,
    TelemetryEvent,
    TelemetryListener,
    VehicleHeartbeat,
)
from mavlink_bridge.wire.link import LinkUrlError

TIMELINE = "vehicle_time"
DEFAULT_CONNECT = "udpin:127.0.0.1:14550"
_TRAIL_POINTS = 4000
_TRAIL_PERIOD_MS = 1000
_LEVELS = ("CRITICAL", "CRITICAL", "CRITICAL", "ERROR", "WARN", "INFO", "INFO", "DEBUG")


class MonitorRecorder:
    """Turns typed telemetry events into Rerun entities (one vehicle; others are logged by system id)."""

    def __init__(self, rec: rr.RecordingStream) -> None:
        self.rec = rec
        self.t_ms = 0
        self.counts: dict[str, int] = {}
        self._mode: dict[int, tuple[str, bool]] = {}
        self._seq: dict[int, int] = {}
        self._att_q = (1.0, 0.0, 0.0, 0.0)
        self._trail = np.zeros((_TRAIL_POINTS, 3))
        self._trail_n = 0
        self._trail_next_ms = 0
        rec.log(ent.WORLD, rr.ViewCoordinates.FRD, static=True)
        rec.log(ent.MON_VEHICLE, rr.TransformAxes3D(axis_length=1.0), static=True)
        rec.log(ent.MON_ATT, rr.SeriesLines(names=list(ent.RPY)), static=True)
        rec.log(ent.MON_POS, rr.SeriesLines(names=list(ent.XYZ)), static=True)

    def _time(self, time_boot_ms: int | None = None) -> None:
        if time_boot_ms is not None and time_boot_ms >= self.t_ms:
            self.t_ms = int(time_boot_ms)
        self.rec.set_time(TIMELINE, duration=np.timedelta64(self.t_ms, "ms"))

    def _text(self, text: str, level: str = "INFO") -> None:
        self.rec.log(ent.LOG, rr.TextLog(text, level=level))

    def handle(self, event: TelemetryEvent) -> None:
        """Log one event."""
        name = type(event).__name__
        self.counts[name] = self.counts.get(name, 0) + 1
        rec = self.rec
        if isinstance(event, Attitude):
            self._time(event.time_boot_ms)
            rec.log(ent.MON_ATT, rr.Scalars(np.degrees([event.roll_rad, event.pitch_rad, event.yaw_rad])))
            q = quat_from_euler(event.roll_rad, event.pitch_rad, event.yaw_rad)
            self._att_q = (float(q[0]), float(q[1]), float(q[2]), float(q[3]))
        elif isinstance(event, LocalPosition):
            self._time(event.time_boot_ms)
            rec.log(ent.MON_POS, rr.Scalars(event.pos_ned_m))
            w, x, y, z = self._att_q
            rec.log(
                ent.MON_VEHICLE,
                rr.Transform3D(translation=event.pos_ned_m, quaternion=rr.Quaternion(xyzw=(x, y, z, w))),
            )
            self._add_trail(event.pos_ned_m)
        elif isinstance(event, GlobalPosition):
            self._time(event.time_boot_ms)
            rec.log(ent.MON_ALT, rr.Scalars(event.alt_rel_m))
            rec.log(
                "monitor/geo", rr.GeoPoints(lat_lon=[[event.lat_deg, event.lon_deg]], radii=rr.Radius.ui_points(4.0))
            )
        elif isinstance(event, VehicleHeartbeat):
            self._time()
            state = (event.mode, event.armed)
            if self._mode.get(event.system_id) != state:
                old = self._mode.get(event.system_id)
                self._mode[event.system_id] = state
                if old is None or old[0] != event.mode:
                    self._text(f"sys {event.system_id}: mode {event.mode}")
                if old is None or old[1] != event.armed:
                    self._text(f"sys {event.system_id}: {'armed' if event.armed else 'disarmed'}")
        elif isinstance(event, StatusTextEvent):
            self._time()
            self._text(event.text, _LEVELS[event.severity] if 0 <= event.severity < len(_LEVELS) else "INFO")
        elif isinstance(event, MissionCurrent):
            self._time()
            rec.log(ent.MON_MISSION, rr.Scalars(float(event.seq)))
            if self._seq.get(event.system_id) != event.seq:
                self._seq[event.system_id] = event.seq
                self._text(f"sys {event.system_id}: mission item {event.seq} current")
        elif isinstance(event, MissionItemReached):
            self._time()
            self._text(f"sys {event.system_id}: mission item {event.seq} reached")

    def _add_trail(self, pos_ned_m: tuple[float, float, float]) -> None:
        if not all(math.isfinite(c) for c in pos_ned_m):
            return
        n = self._trail_n
        if n == _TRAIL_POINTS:  # keep the newest half
            self._trail[: n // 2] = self._trail[n - n // 2 :]
            n = n // 2
        self._trail[n] = pos_ned_m
        self._trail_n = n + 1
        if self.t_ms >= self._trail_next_ms:
            self._trail_next_ms = self.t_ms + _TRAIL_PERIOD_MS
            self.rec.log(ent.MON_TRAIL, rr.LineStrips3D([self._trail[: self._trail_n]], radii=0.05))

    def close(self) -> None:
        if self._trail_n >= 2:
            self._time()
            self.rec.log(ent.MON_TRAIL, rr.LineStrips3D([self._trail[: self._trail_n]], radii=0.05))
        self.rec.flush()
        self.rec.disconnect()


def run_monitor(
    listener: TelemetryListener,
    recorder: MonitorRecorder,
    should_stop: Callable[[], bool],
    *,
    poll_s: float = 0.05,
) -> None:
    """Poll the listener and log every event until ``should_stop()``."""
    while not should_stop():
        for event in listener.poll(poll_s):
            recorder.handle(event)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m tools.monitor",
        description="Record any MAVLink vehicle's standard telemetry to Rerun (nothing here is quadsitl-specific).",
    )
    parser.add_argument("--connect", default=DEFAULT_CONNECT, metavar="URL", help=f"default {DEFAULT_CONNECT}")
    parser.add_argument(
        "--rerun", default=None, metavar="save:PATH|connect:URL", help="default save:runs/monitor-*.rrd"
    )
    parser.add_argument("--duration-s", type=float, default=0.0, help="stop after this many wall seconds (0: never)")
    args = parser.parse_args(argv)
    spec = args.rerun or f"save:runs/monitor-{datetime.now():%Y%m%d-%H%M%S}.rrd"
    try:
        sink = parse_rerun_spec(spec)
        listener = TelemetryListener(args.connect)
    except (RerunSpecError, LinkUrlError, OSError) as exc:
        print(f"monitor: {exc}", file=sys.stderr)
        return 2
    rec = open_recording(sink, monitor_blueprint())
    if rec is None:
        print("monitor: --rerun off records nothing", file=sys.stderr)
        listener.close()
        return 2
    recorder = MonitorRecorder(rec)
    stop = {"requested": False}

    def _stop(signum: int, _frame: FrameType | None) -> None:
        stop["requested"] = True

    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, _stop)
    deadline = time.monotonic() + args.duration_s if args.duration_s > 0.0 else math.inf
    try:
        run_monitor(listener, recorder, lambda: stop["requested"] or time.monotonic() >= deadline)
    finally:
        recorder.close()
        listener.close()
    counts = ", ".join(f"{k} {v}" for k, v in sorted(recorder.counts.items())) or "nothing received"
    print(f"monitor: {counts}; recording {sink}", file=sys.stderr)
    if sink.target.endswith(".rrd"):
        print(f"open it with: rerun {sink.target}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
