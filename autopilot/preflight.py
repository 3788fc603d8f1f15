"""Input files checked before any process starts: one line naming the file, the line and the fix.

``quadsitl up`` and ``make run`` call :func:`check_autopilot_inputs` (mission or world YAML, QGC ``.plan``
and ``.waypoints``, ``--params``, ``--script``, ``--rerun-world``, the vehicle name) before they start
anything, so a typo is reported at once rather than after the simulator and the autopilot have spent
seconds starting. The simulator's half of a mission file (``world:``) is checked by ``quadsitl sim
--check``, which ``quadsitl up`` runs first (``sim`` and ``autopilot`` never import each other).
"""

from __future__ import annotations

from pathlib import Path

from autopilot.commander.script import ScriptError, load_script
from autopilot.control.airframe import AIRFRAME_DIR, AirframeError, load_airframe
from autopilot.mission.files import MissionFileError, load_mission_file
from autopilot.param_schema import make_param_store
from autopilot.parameters.store import ParamError
from mavlink_bridge.contract.source_lines import YamlSyntaxError, did_you_mean, read_yaml

MISSION_SUFFIXES = (".yaml", ".yml", ".plan", ".waypoints", ".txt")


class InputFileError(ValueError):
    """An input file that would be refused; the message is one line: ``FILE:LINE: problem; fix: ...``."""


def airframe_names() -> list[str]:
    """The airframes the autopilot knows (``autopilot/airframes/*.yaml``)."""
    return sorted(p.stem for p in AIRFRAME_DIR.glob("*.yaml"))


def check_vehicle(name: str, mission: str | Path | None = None) -> None:
    """The airframe ``name`` exists (the mission's ``vehicle:`` line named when it came from there)."""
    if Path(name).suffix in (".yaml", ".yml"):
        try:
            load_airframe(name)
        except (AirframeError, OSError) as exc:
            raise InputFileError(f"{exc}; fix: check the airframe file") from None
        return
    known = airframe_names()
    if name in known:
        return
    where = "--vehicle"
    if mission is not None and Path(mission).suffix in (".yaml", ".yml"):
        try:
            source = read_yaml(mission)
        except (OSError, YamlSyntaxError):
            source = None
        if source is not None and isinstance(source.data, dict) and source.data.get("vehicle") == name:
            where = f"{source.where('vehicle')}: vehicle"
    raise InputFileError(
        f"{where}: unknown vehicle {name!r} (known: {', '.join(known)}); fix: {did_you_mean(name, known)}"
    )


def _bare_world(path: Path) -> bool:
    """A YAML holding only a world (``obstacles``, ``wind``, ``payload_kg``, ``home``), not a mission."""
    if path.suffix.lower() not in (".yaml", ".yml"):
        return False
    try:
        data = read_yaml(path).data
    except (OSError, YamlSyntaxError):
        return False  # load_mission_file reports it
    return isinstance(data, dict) and bool(data) and set(data) <= {"obstacles", "wind", "payload_kg", "home"}


def check_autopilot_inputs(
    *,
    mission: str | Path | None = None,
    params: str | Path | None = None,
    script: str | Path | None = None,
    vehicle: str | None = None,
) -> None:
    """Check every given input file; :class:`InputFileError` (one line) for the first problem found."""
    try:
        if mission is not None:
            path = Path(mission)
            if not path.is_file():
                raise InputFileError(f"{path}: no such file; fix: check the path (missions/ holds the examples)")
            if path.suffix.lower() not in MISSION_SUFFIXES:
                raise InputFileError(
                    f"{path}: not a mission file; fix: use a .yaml, .plan or .waypoints file (see missions/)"
                )
            if _bare_world(path):  # the simulator's world only (checked by quadsitl sim --check)
                if vehicle is not None:
                    check_vehicle(vehicle)
            else:
                plan = load_mission_file(path)
                check_vehicle(vehicle or plan.vehicle, path if vehicle is None else None)
        elif vehicle is not None:
            check_vehicle(vehicle)
        if params is not None:
            make_param_store(params)
        if script is not None:
            load_script(script)
    except (MissionFileError, ParamError, ScriptError) as exc:
        raise InputFileError(str(exc)) from None
