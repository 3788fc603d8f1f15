"""One Rerun recording for a fleet run: its id and the file each part of it writes.

Every autopilot of a fleet and the simulator's world part write with one recording id (from the world file and the
seed), each to its own file beside the others, so the viewer opens them as one recording.
"""

from __future__ import annotations

import hashlib
import uuid
from pathlib import Path

_RECORDING_NAMESPACE = uuid.UUID("6f1d2c3a-9b4e-4f5a-8c7d-0e1f2a3b4c5d")


def fleet_recording_id(world_path: str | Path, seed: int) -> str:
    """The Rerun recording id shared by every part of one fleet run: a UUID of the world file's bytes and the seed."""
    digest = hashlib.sha256(Path(world_path).read_bytes()).hexdigest()
    return str(uuid.uuid5(_RECORDING_NAMESPACE, f"{digest}:{int(seed)}"))


def world_rerun_path(spec: str) -> str | None:
    """The simulator's part of a fleet recording, beside the autopilots': ``save:PATH.rrd`` -> ``PATH_world.rrd``."""
    return vehicle_rerun_spec(spec, "world").removeprefix("save:") if spec.startswith("save:") else None


def vehicle_rerun_spec(spec: str, name: str) -> str:
    """A vehicle's ``--rerun``: ``save:PATH.rrd`` becomes ``save:PATH_<name>.rrd`` (one file per autopilot)."""
    if not spec.startswith("save:"):
        return spec
    path = Path(spec.removeprefix("save:"))
    suffix = path.suffix or ".rrd"
    return f"save:{path.with_name(f'{path.stem}_{name}{suffix}')}"
