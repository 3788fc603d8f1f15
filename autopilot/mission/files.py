"""Mission files: the project YAML (SPEC §8, schema v1), QGC WPL 110 and QGroundControl ``.plan``, read and written.

``load_mission_file(path)`` / ``save_mission_file(plan, path)`` pick the format from the
extension: ``.yaml``/``.yml``, ``.waypoints``/``.txt`` (QGC WPL 110), ``.plan`` (QGC JSON).

YAML v1 extensions made here (the v1 keys keep their meaning):

- ``speed_m_s`` becomes a leading ``DO_CHANGE_SPEED`` item (so any GCS that uploads the
  items honours it); a writer folds that item back into ``speed_m_s``.
- Mission entries ``delay: {seconds}``, ``jump: {to_entry, repeat}`` (``to_entry`` is the
  0-based index in this ``mission:`` list; a pattern entry's index means its first waypoint),
  ``payload_grab: {}``, and ``mav_item: {command, frame, param1..param4, lat_deg, lon_deg, alt_m,
  autocontinue}`` for any item the friendly forms cannot express. Positions in friendly entries
  are ``{north_m, east_m}`` about home or ``{lat_deg, lon_deg}``; ``yaw_deg`` is optional.
- ``pattern: {type, spacing_m, accept_radius_m?, ...}``: the remaining keys go to
  ``autopilot.flight_tasks.trajectories.make_trajectory(type, **rest).waypoints(spacing_m)``, whose
  ``(north_m, east_m, alt_m)`` points become pass-through waypoints.
- Fence polygons also take ``{vertices_lat_lon_deg: [[lat, lon], ...], group: 0}``; circles
  take ``lat_deg``/``lon_deg`` instead of ``north_m``/``east_m``; inclusion zones take ``group``.

Numbering: ``MissionPlan.items[k].seq == k`` (PX4: seq 0 is the first item). QGC WPL line 0
is home, so item k is written on line k + 1 and DO_JUMP targets are written +1; ``.plan``
DO_JUMP targets are ``doJumpId`` values (seq + 1), as QGroundControl writes them.

Round trips: floats are written with their shortest exact representation (``repr``), so
YAML → items → WPL → items and → .plan → items are exact (:func:`items_match` with the
default tolerances). ``.plan`` geoFence stores polygons and circles apart, and QGC WPL has no
fence at all: through ``.plan`` fence items come back polygons first, then circles, and
inclusion groups are lost (all 0).
"""

from __future__ import annotations

import re
from pathlib import Path

from autopilot.mission.file_common import MissionFileError, PatternExpander, expand_pattern
from autopilot.mission.file_qgc_plan import read_plan, write_plan
from autopilot.mission.file_wpl import read_wpl, write_wpl
from autopilot.mission.file_yaml_read import YamlReader
from autopilot.mission.file_yaml_write import write_yaml
from autopilot.mission.plan import MissionPlan
from autopilot.mission.validation import MissionLimits, check_mission
from mavlink_bridge.contract.source_lines import YamlSyntaxError, parse_yaml

__all__ = ["MissionFileError", "PatternExpander", "expand_pattern", "load_mission_file", "save_mission_file"]


def _format(path: Path) -> str:
    suffix = path.suffix.lower()
    if suffix in (".yaml", ".yml"):
        return "yaml"
    if suffix in (".waypoints", ".txt"):
        return "wpl"
    if suffix == ".plan":
        return "plan"
    raise MissionFileError(path, f"unknown mission file extension {suffix!r} (use .yaml, .waypoints, .txt or .plan)")


def load_mission_file(
    path: str | Path, *, limits: MissionLimits | None = None, expander: PatternExpander = expand_pattern
) -> MissionPlan:
    """Read a mission file and validate its items and fence (``limits`` default :class:`MissionLimits`).

    Raises :class:`MissionFileError` naming the file, the item and the field.
    """
    p = Path(path)
    fmt = _format(p)
    reader: YamlReader | None = None
    text = ""
    try:
        text = p.read_text()
        if fmt == "yaml":
            try:
                source = parse_yaml(text, p)
            except YamlSyntaxError as exc:
                raise MissionFileError(p, f"not valid YAML: {exc.detail}", line=exc.line, fix=exc.fix) from None
            reader = YamlReader(p, expander, source)
            plan = reader.read(source.data)
        elif fmt == "wpl":
            plan = read_wpl(p)
        else:
            plan = read_plan(p)
    except OSError as exc:
        fix = "check the path (missions/ holds the examples)" if not p.exists() else "check its permissions"
        raise MissionFileError(p, f"cannot read: {exc.strerror}", fix=fix) from None
    for section, items in (("mission", plan.items), ("fence", plan.fence)):
        issue = check_mission(items, plan.home, limits)
        if issue is not None:
            index = issue.item_index if issue.item_index >= 0 else None
            message = issue.reason.split(": ", 1)[1] if index is not None else issue.reason
            line = _item_line(fmt, text, reader, section, index)
            raise MissionFileError(p, message, section=section, item_index=index, field=issue.field, line=line)
    return plan


def _item_line(fmt: str, text: str, reader: YamlReader | None, section: str, index: int | None) -> int | None:
    """The line of mission/fence item ``index`` in the file's text (None when it cannot be told)."""
    if index is None:
        return None
    if reader is not None:
        if section == "mission":
            entry = reader.entry_of_seq[index] if index < len(reader.entry_of_seq) else None
            return reader.line("mission", entry) if entry is not None else reader.line("speed_m_s")
        return reader.line("fence")
    if fmt == "wpl":  # item k is on the (k + 2)-th non-blank line: header, home, items
        rows = [n for n, ln in enumerate(text.splitlines(), start=1) if ln.strip()]
        return rows[index + 2] if index + 2 < len(rows) else None
    if fmt == "plan" and section == "mission":  # QGC writes doJumpId = seq + 1 on every SimpleItem
        for n, ln in enumerate(text.splitlines(), start=1):
            if re.search(rf'"doJumpId"\s*:\s*{index + 1}\b', ln):
                return n
    return None


def save_mission_file(plan: MissionPlan, path: str | Path, *, allow_drop_fence: bool = False) -> None:
    """Write ``plan`` in the format of ``path``'s extension (QGC WPL refuses a fence unless ``allow_drop_fence``)."""
    p = Path(path)
    fmt = _format(p)
    if fmt == "yaml":
        write_yaml(plan, p)
    elif fmt == "wpl":
        write_wpl(plan, p, allow_drop_fence)
    else:
        write_plan(plan, p)
