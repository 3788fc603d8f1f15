"""Where a Rerun recording goes: ``--rerun off|save:PATH|connect:URL`` (SPEC §9, §12).

``save:PATH`` writes an ``.rrd`` file (parent directories are created); ``connect:URL``
streams to a running viewer over gRPC (``rerun+http://127.0.0.1:9876/proxy`` when URL is
empty or ``default``). Parsing is pure; :func:`open_recording` is the only place that
opens a sink.
"""

from __future__ import annotations

import uuid
from dataclasses import dataclass
from datetime import timedelta
from enum import Enum
from pathlib import Path

import rerun as rr
import rerun.blueprint as rrb

#: The application id every quadsitl recording carries (the viewer groups blueprints by it).
APPLICATION_ID = "quadsitl"
#: The application id of a fleet's recording parts (the simulator's world part too): the viewer keeps one layout per
#: application id, so a fleet's layout never replaces a single-vehicle recording's open in the same viewer.
FLEET_APPLICATION_ID = "quadsitl_fleet"
DEFAULT_CONNECT_URL = "rerun+http://127.0.0.1:9876/proxy"
_URL_SCHEMES = ("rerun://", "rerun+http://", "rerun+https://")


class RerunSpecError(ValueError):
    """A ``--rerun`` value that is not ``off``, ``save:PATH`` or ``connect:URL``."""


class SinkKind(Enum):
    """What a recording is attached to."""

    OFF = "off"
    SAVE = "save"
    CONNECT = "connect"


@dataclass(frozen=True, slots=True)
class RerunSink:
    """A parsed ``--rerun`` option: ``target`` is the file path (SAVE) or the gRPC URL (CONNECT)."""

    kind: SinkKind
    target: str = ""

    def __str__(self) -> str:
        return self.kind.value if self.kind is SinkKind.OFF else f"{self.kind.value}:{self.target}"


#: Chunk batching of a saved recording: flush every 60 s of wall time or 8 MiB (default: 200 ms, 2 MiB).
SAVE_BATCHER = rr.ChunkBatcherConfig(flush_tick=timedelta(seconds=60), flush_num_bytes=8 * 1024 * 1024)


def parse_rerun_spec(text: str) -> RerunSink:
    """Parse ``off``, ``save:PATH`` or ``connect:URL`` (``connect`` alone: the default viewer)."""
    spec = text.strip()
    if spec == "off":
        return RerunSink(SinkKind.OFF)
    kind, sep, target = spec.partition(":")
    if kind == "save":
        if not sep or not target:
            raise RerunSpecError(f"--rerun {text!r}: save needs a file path, e.g. save:runs/flight.rrd")
        if Path(target).suffix != ".rrd":
            raise RerunSpecError(f"--rerun {text!r}: the recording path must end in .rrd")
        return RerunSink(SinkKind.SAVE, target)
    if kind == "connect":
        url = target if target and target != "default" else DEFAULT_CONNECT_URL
        if not url.startswith(_URL_SCHEMES):
            raise RerunSpecError(
                f"--rerun {text!r}: the viewer URL must start with one of {', '.join(_URL_SCHEMES)} "
                f"(e.g. {DEFAULT_CONNECT_URL})"
            )
        return RerunSink(SinkKind.CONNECT, url)
    raise RerunSpecError(f"--rerun {text!r}: expected off, save:PATH or connect:URL")


def open_recording(
    sink: RerunSink,
    blueprint: rrb.Blueprint | None = None,
    *,
    recording_id: str | None = None,
    application_id: str = APPLICATION_ID,
) -> rr.RecordingStream | None:
    """A recording stream attached to ``sink`` (None for OFF); wall-clock timelines are disabled.

    Only ``sim_time`` (and whatever timeline the caller sets) indexes the data: ``log_time``
    and ``log_tick`` are turned off so a recording is a function of the flight alone.
    """
    if sink.kind is SinkKind.OFF:
        return None
    # A file gathers the rare logs (events, obstacles, detours) into few large chunks; a viewer wants them now.
    batcher = SAVE_BATCHER if sink.kind is SinkKind.SAVE else None
    rec = rr.RecordingStream(application_id, recording_id=recording_id or str(uuid.uuid4()), batcher_config=batcher)
    rec.set_log_time_enabled(False)
    rec.set_log_tick_enabled(False)
    if sink.kind is SinkKind.SAVE:
        path = Path(sink.target)
        path.parent.mkdir(parents=True, exist_ok=True)
        rec.save(path, default_blueprint=blueprint)
    else:
        rec.connect_grpc(sink.target, default_blueprint=blueprint)
    return rec
