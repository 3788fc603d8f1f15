"""One Rerun recording for a fleet world (issue 23 item 7): each autopilot logs under its vehicle's name.

A fleet's autopilots all write with one recording id (``autopilot.launch_recording.fleet_recording_id``, from the
world file and the seed), so their ``.rrd`` files, and the simulator's world part, open in the viewer as one recording.
:class:`VehicleRecording` wraps a recording stream and moves a single-vehicle recording's entities
(:mod:`autopilot.telemetry.entities`) under the vehicle's name:

- ``world`` and ``world/...`` (3D: pose, trail, setpoint, route about home) -> ``vehicles/<name>/...``;
- everything else (the time series, the text log) -> ``plots/<name>/...``.

``vehicles/<name>`` carries a static ``Transform3D`` whose translation is the vehicle's home about the
world's home (NED, m), so the vehicle's local NED positions (origin: its own home) are drawn about the
world's home. The single-vehicle layout (blueprint) names ``world/...`` paths, so an autopilot of a fleet sends
none: the simulator's world part carries the fleet's layout (``sim.world_layout``), which names the paths above.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import rerun as rr

VEHICLES = "vehicles"
PLOTS = "plots"


def vehicle_entity(name: str, path: str) -> str:
    """Where a single-vehicle entity ``path`` goes in a fleet recording for vehicle ``name``."""
    if path == "world":
        return f"{VEHICLES}/{name}"
    if path.startswith("world/"):
        return f"{VEHICLES}/{name}/{path.removeprefix('world/')}"
    return f"{PLOTS}/{name}/{path.lstrip('/')}"


class VehicleRecording:
    """A recording stream whose ``log``/``send_columns`` entity paths go under vehicle ``name``.

    ``home_offset_ned_m``: the vehicle's home about the world's home (north, east, down in m).
    Everything else is the wrapped stream's own (``set_time``, ``flush``, ``disconnect`` ...).
    """

    def __init__(self, rec: rr.RecordingStream, name: str, home_offset_ned_m: Sequence[float]) -> None:
        if not name or "/" in name:
            raise ValueError(f"vehicle name {name!r}: must be non-empty without '/'")
        self._rec = rec
        self.name = name
        self.home_offset_ned_m = tuple(float(x) for x in home_offset_ned_m)
        if len(self.home_offset_ned_m) != 3:
            raise ValueError("home_offset_ned_m needs north, east, down")
        rec.log(VEHICLES, rr.ViewCoordinates.FRD, static=True)  # X north, Y east, Z down: NED
        rec.log(f"{VEHICLES}/{name}", rr.Transform3D(translation=self.home_offset_ned_m), static=True)

    def log(self, entity_path: str, *args: Any, **kwargs: Any) -> None:
        self._rec.log(vehicle_entity(self.name, entity_path), *args, **kwargs)

    def send_columns(self, entity_path: str, *args: Any, **kwargs: Any) -> None:
        self._rec.send_columns(vehicle_entity(self.name, entity_path), *args, **kwargs)

    def send_blueprint(self, *_args: Any, **_kwargs: Any) -> None:
        """No blueprint: the single-vehicle layout names ``world/...`` paths (the simulator sends the fleet's)."""

    def __getattr__(self, name: str) -> Any:
        return getattr(self._rec, name)
