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
  ``autopilot.trajectories.make_trajectory(type, **rest).waypoints(spacing_m)``, whose
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

import json
import math
import re
from collections.abc import Callable, Mapping, Sequence
from dataclasses import replace
from pathlib import Path
from typing import Any

import yaml

from autopilot.mission.fence import circle_fence_items, polygon_fence_items
from autopilot.mission.plan import DEFAULT_VEHICLE, MissionPlan, items_match
from autopilot.mission.validation import MissionLimits, check_mission
from mavlink_bridge.contract.frames import GeoPoint, LocalNedFrame
from mavlink_bridge.contract.mav_enums import GripperAction, MavCmd, MavFrame
from mavlink_bridge.contract.source_lines import YamlSource, YamlSyntaxError, did_you_mean, parse_yaml
from mavlink_bridge.contract.vehicle_api import MissionItem

#: ``(type, spacing_m, params) -> [(north_m, east_m, alt_m), ...]``: expands a YAML ``pattern:`` entry.
PatternExpander = Callable[[str, float, dict[str, Any]], list[tuple[float, float, float]]]

_REL = int(MavFrame.GLOBAL_RELATIVE_ALT_INT)
_MISSION_FRAME = int(MavFrame.MISSION)
_NAN = float("nan")
_WPL_HEADER = "QGC WPL 110"
_TOP_KEYS = ("version", "name", "home", "vehicle", "speed_m_s", "mission", "fence", "world")
_ENTRY_KINDS = (
    "takeoff", "waypoint", "pattern", "payload_release", "payload_grab", "loiter", "speed", "delay", "jump",
    "return_to_launch", "land", "mav_item",
)  # fmt: skip


class MissionFileError(ValueError):
    """A mission file that cannot be read or written; one line naming the file, line, item, field and fix.

    ``FILE:LINE: mission item 3 (waypoint): field 'alt_m': expected a number, got 'ten'; fix: ...``
    """

    def __init__(
        self,
        path: str | Path,
        message: str,
        *,
        section: str = "",
        item_index: int | None = None,
        field: str = "",
        line: int | None = None,
        fix: str = "",
    ) -> None:
        where = [str(path) if line is None else f"{path}:{line}"]
        if section:
            where.append(section if item_index is None else f"{section} item {item_index}")
        if field:
            where.append(f"field '{field}'")
        text = ": ".join([*where, " ".join(message.split())])
        super().__init__(f"{text}; fix: {fix}" if fix else text)
        self.path = str(path)
        self.item_index = item_index
        self.field = field
        self.line = line


def expand_pattern(pattern_type: str, spacing_m: float, params: dict[str, Any]) -> list[tuple[float, float, float]]:
    """Default :data:`PatternExpander`: the control engineer's parametric trajectories (SPEC §6.5)."""
    from autopilot.trajectories import make_trajectory  # heavy module, only needed by pattern entries

    return [(float(n), float(e), float(a)) for n, e, a in make_trajectory(pattern_type, **params).waypoints(spacing_m)]


# --------------------------------------------------------------------------------------------- YAML reading


class _YamlReader:
    """Parses one YAML v1 document into a :class:`MissionPlan`."""

    def __init__(self, path: str | Path, expander: PatternExpander, source: YamlSource | None = None) -> None:
        self.path = path
        self.expander = expander
        self.source = source
        self.section = ""
        self.index: int | None = None
        self.kind = ""
        #: The ``mission:`` entry index of each mission item (patterns expand to many, speed_m_s adds one).
        self.entry_of_seq: list[int | None] = []

    def line(self, *path: str | int) -> int | None:
        """The line of the deepest node along ``path`` (None without a source)."""
        return self.source.line(*path) if self.source is not None else None

    def fail(self, message: str, field: str = "", fix: str = "") -> MissionFileError:
        section = f"{self.section} ({self.kind})" if self.kind and self.index is None else self.section
        if self.kind and self.index is not None:
            message = f"({self.kind}) {message}"
        node = [p for p in (self.section, self.index, self.kind, field) if p not in ("", None)]
        return MissionFileError(
            self.path, message, section=section, item_index=self.index, field=field, line=self.line(*node), fix=fix
        )

    def number(self, d: Mapping[str, Any], key: str, lo: float = -math.inf, hi: float = math.inf) -> float:
        if key not in d:
            raise self.fail("missing required field", key, fix=f"add '{key}: <number>'")
        value = d[key]
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise self.fail(f"expected a number, got {value!r}", key, fix=f"write a plain number, e.g. '{key}: 10'")
        v = float(value)
        if not math.isfinite(v):
            raise self.fail(f"{v} is not a finite number", key, fix="write a finite number")
        if not lo <= v <= hi:
            raise self.fail(f"{v:g} outside [{lo:g}, {hi:g}]", key, fix=f"use a value from {lo:g} to {hi:g}")
        return v

    def mapping(self, value: Any, allowed: Sequence[str], field: str = "") -> dict[str, Any]:
        if value is None:
            value = {}
        if not isinstance(value, dict):
            example = f"{{{allowed[0]}: ...}}" if allowed else "{}"
            raise self.fail(f"expected a mapping, got {type(value).__name__}", field, fix=f"write e.g. {example}")
        for key in value:
            if key not in allowed:
                fix = did_you_mean(key, allowed) if allowed else "remove it (this entry takes no fields: write {})"
                raise self.fail(f"unknown key (allowed: {', '.join(allowed) or 'none'})", str(key), fix=fix)
        return value

    def latlon(self, d: Mapping[str, Any], frame: LocalNedFrame, required: bool) -> tuple[float, float] | None:
        """(lat, lon) from {north_m, east_m} or {lat_deg, lon_deg}; None when absent and optional."""
        has_ne = "north_m" in d or "east_m" in d
        has_ll = "lat_deg" in d or "lon_deg" in d
        if has_ne and has_ll:
            raise self.fail("give either north_m/east_m or lat_deg/lon_deg, not both", "lat_deg")
        if has_ll:
            return self.number(d, "lat_deg", -90.0, 90.0), self.number(d, "lon_deg", -180.0, 180.0)
        if has_ne:
            g = frame.geodetic_from_ned(self.number(d, "north_m"), self.number(d, "east_m"), 0.0)
            return g.lat_deg, g.lon_deg
        if required:
            raise self.fail("missing position (north_m/east_m or lat_deg/lon_deg)", "north_m")
        return None

    def yaw(self, d: Mapping[str, Any]) -> float:
        return self.number(d, "yaw_deg", -360.0, 360.0) if "yaw_deg" in d else _NAN

    def read(self, doc: Any) -> MissionPlan:
        if not isinstance(doc, dict):
            raise MissionFileError(
                self.path,
                f"expected a YAML mapping at top level, got {type(doc).__name__}",
                line=1,
                fix="start with 'name: ...', 'home: {...}' and 'mission: [...]' (see missions/delivery.yaml)",
            )
        for key in doc:
            if key not in _TOP_KEYS:
                raise MissionFileError(
                    self.path,
                    f"unknown top-level key (allowed: {', '.join(_TOP_KEYS)})",
                    field=key,
                    line=self.line(key),
                    fix=did_you_mean(key, _TOP_KEYS),
                )
        if doc.get("version", 1) != 1:
            raise MissionFileError(
                self.path,
                f"schema version {doc['version']!r} unsupported (expected 1)",
                field="version",
                line=self.line("version"),
                fix="write 'version: 1' or remove the line",
            )
        self.section = "home"
        home_d = self.mapping(doc.get("home"), ("lat_deg", "lon_deg", "alt_m"), "home")
        home = GeoPoint(
            self.number(home_d, "lat_deg", -90.0, 90.0),
            self.number(home_d, "lon_deg", -180.0, 180.0),
            self.number(home_d, "alt_m", -500.0, 9000.0),
        )
        self.section = ""
        speed = self.number(doc, "speed_m_s", 0.1, 50.0) if doc.get("speed_m_s") is not None else None
        name = doc.get("name", Path(self.path).stem)
        vehicle = doc.get("vehicle", DEFAULT_VEHICLE)
        for key, value in (("name", name), ("vehicle", vehicle)):
            if not isinstance(value, str) or not value:
                raise MissionFileError(
                    self.path,
                    f"expected a non-empty string, got {value!r}",
                    field=key,
                    line=self.line(key),
                    fix=f"write e.g. '{key}: {'x500' if key == 'vehicle' else 'my_delivery'}'",
                )
        world = doc.get("world")
        if world is not None and not isinstance(world, dict):
            raise MissionFileError(
                self.path,
                "expected a mapping",
                field="world",
                line=self.line("world"),
                fix="write 'world: {obstacles: [...]}'",
            )
        frame = LocalNedFrame(home)
        items = self.mission(doc.get("mission"), frame, speed)
        fence = self.fence(doc.get("fence"), frame)
        return MissionPlan(name, home, items, fence, speed, vehicle, world)

    # ---- mission entries

    def mission(self, entries: Any, frame: LocalNedFrame, speed: float | None) -> list[MissionItem]:
        self.section = "mission"
        if entries is None:
            entries = []
        if not isinstance(entries, list):
            raise MissionFileError(
                self.path,
                "expected a list of entries",
                field="mission",
                line=self.line("mission"),
                fix="write one '- kind: {...}' entry per line under 'mission:'",
            )
        raw: list[MissionItem] = []
        if speed is not None:
            raw.append(_speed_item(speed))
        self.entry_of_seq = [None] * len(raw)
        first_seq: list[int] = []
        jumps: list[tuple[int, int, int]] = []  # (seq, to_entry, entry index)
        for idx, entry in enumerate(entries):
            self.index, self.kind = idx, ""
            if not isinstance(entry, dict) or len(entry) != 1:
                raise self.fail(
                    "each entry is a mapping with exactly one key", fix="write e.g. '- waypoint: {north_m: 40, ...}'"
                )
            ((kind, body),) = entry.items()
            self.kind = str(kind)
            first_seq.append(len(raw))
            if kind == "jump":
                d = self.mapping(body, ("to_entry", "repeat"))
                to_entry = self.number(d, "to_entry", 0, max(len(entries) - 1, 0))
                repeat = self.number(d, "repeat", -1, 1e6)
                if to_entry != int(to_entry) or repeat != int(repeat):
                    raise self.fail("to_entry and repeat must be integers", "to_entry")
                jumps.append((len(raw), int(to_entry), idx))
                raw.append(MissionItem(0, int(MavCmd.DO_JUMP), _MISSION_FRAME, param2=repeat))
            else:
                raw.extend(self.entry(str(kind), body, frame))
            self.entry_of_seq += [idx] * (len(raw) - len(self.entry_of_seq))
        for seq, to_entry, idx in jumps:
            target = first_seq[to_entry]
            if to_entry == idx:
                self.index, self.kind = idx, "jump"
                raise self.fail(f"jump to itself (entry {idx})", "to_entry", fix="jump to an earlier entry's index")
            raw[seq] = replace(raw[seq], param1=float(target))
        self.index, self.kind = None, ""
        return [replace(item, seq=k) for k, item in enumerate(raw)]

    def entry(self, kind: str, body: Any, frame: LocalNedFrame) -> list[MissionItem]:
        pos_keys = ("north_m", "east_m", "lat_deg", "lon_deg")
        if kind == "takeoff":
            d = self.mapping(body, ("alt_m", "yaw_deg", *pos_keys))
            ll = self.latlon(d, frame, required=False) or (0.0, 0.0)
            return [_nav(MavCmd.NAV_TAKEOFF, ll, self.number(d, "alt_m", 0.0, 10000.0), p4=self.yaw(d))]
        if kind == "waypoint":
            d = self.mapping(body, ("alt_m", "accept_radius_m", "hold_s", "yaw_deg", *pos_keys))
            ll = self.latlon(d, frame, required=True)
            assert ll is not None
            acc = self.number(d, "accept_radius_m", 0.0, 1000.0) if "accept_radius_m" in d else 0.0
            hold = self.number(d, "hold_s", 0.0, 86400.0) if "hold_s" in d else 0.0
            alt = self.number(d, "alt_m", -1000.0, 10000.0)
            return [_nav(MavCmd.NAV_WAYPOINT, ll, alt, p1=hold, p2=acc, p4=self.yaw(d))]
        if kind == "pattern":
            return self.pattern(body, frame)
        if kind in ("payload_release", "payload_grab"):
            d = self.mapping(body, ("gripper",))
            instance = self.number(d, "gripper", 1, 6) if "gripper" in d else 1.0
            action = GripperAction.RELEASE if kind == "payload_release" else GripperAction.GRAB
            return [MissionItem(0, int(MavCmd.DO_GRIPPER), _MISSION_FRAME, param1=instance, param2=float(action))]
        if kind == "loiter":
            d = self.mapping(body, ("seconds", "alt_m", "yaw_deg", *pos_keys))
            seconds = self.number(d, "seconds", 0.0, 86400.0)
            ll = self.latlon(d, frame, required=False)
            alt = self.number(d, "alt_m", -1000.0, 10000.0) if ll is not None or "alt_m" in d else 0.0
            if ll is None and "alt_m" in d:
                raise self.fail("alt_m needs a position (without one the vehicle loiters where it is)", "alt_m")
            return [_nav(MavCmd.NAV_LOITER_TIME, ll or (0.0, 0.0), alt, p1=seconds, p4=self.yaw(d))]
        if kind == "speed":
            d = self.mapping(body, ("m_s",))
            return [_speed_item(self.number(d, "m_s", 0.1, 50.0))]
        if kind == "delay":
            d = self.mapping(body, ("seconds",))
            seconds = self.number(d, "seconds", 0.0, 86400.0)
            return [
                MissionItem(
                    0, int(MavCmd.NAV_DELAY), _MISSION_FRAME, param1=seconds, param2=-1.0, param3=-1.0, param4=-1.0
                )
            ]
        if kind == "return_to_launch":
            self.mapping(body, ())
            return [MissionItem(0, int(MavCmd.NAV_RETURN_TO_LAUNCH), _MISSION_FRAME)]
        if kind == "land":
            d = self.mapping(body, ("yaw_deg", *pos_keys))
            ll = self.latlon(d, frame, required=False) or (0.0, 0.0)
            return [_nav(MavCmd.NAV_LAND, ll, 0.0, p4=self.yaw(d))]
        if kind == "mav_item":
            return [self.mav_item(body)]
        raise self.fail(
            f"unknown mission entry (allowed: {', '.join(_ENTRY_KINDS)})", kind, fix=did_you_mean(kind, _ENTRY_KINDS)
        )

    def pattern(self, body: Any, frame: LocalNedFrame) -> list[MissionItem]:
        if not isinstance(body, dict):
            raise self.fail("expected a mapping with at least type and spacing_m")
        params = dict(body)
        ptype = params.pop("type", None)
        if not isinstance(ptype, str):
            raise self.fail("missing or non-string pattern type", "type")
        spacing = self.number(params, "spacing_m", 0.05, 10000.0)
        params.pop("spacing_m")
        acc = self.number(params, "accept_radius_m", 0.0, 1000.0) if "accept_radius_m" in params else 0.0
        params.pop("accept_radius_m", None)
        try:
            points = self.expander(ptype, spacing, params)
        except (TypeError, ValueError, KeyError) as exc:
            raise self.fail(f"pattern {ptype!r} could not be expanded: {exc}", "type") from None
        if not points:
            raise self.fail(f"pattern {ptype!r} expanded to no waypoints", "type")
        items = []
        for n, e, alt in points:
            if not (math.isfinite(n) and math.isfinite(e) and math.isfinite(alt)):
                raise self.fail(f"pattern {ptype!r} produced a non-finite point ({n}, {e}, {alt})", "type")
            g = frame.geodetic_from_ned(n, e, 0.0)
            items.append(_nav(MavCmd.NAV_WAYPOINT, (g.lat_deg, g.lon_deg), alt, p2=acc))
        return items

    def mav_item(self, body: Any) -> MissionItem:
        keys = ("command", "frame", "param1", "param2", "param3", "param4", "lat_deg", "lon_deg", "alt_m")
        d = self.mapping(body, (*keys, "autocontinue"))
        values = {}
        for key in keys:
            v = d.get(key, 0.0)
            if isinstance(v, bool) or not isinstance(v, int | float):
                raise self.fail(f"expected a number, got {v!r}", key)
            values[key] = float(v)
        if "command" not in d:
            raise self.fail("missing required field", "command")
        auto = d.get("autocontinue", True)
        if not isinstance(auto, bool):
            raise self.fail(f"expected true or false, got {auto!r}", "autocontinue")
        return MissionItem(
            0,
            int(values["command"]),
            int(values["frame"]) if "frame" in d else _REL,
            values["param1"],
            values["param2"],
            values["param3"],
            values["param4"],
            values["lat_deg"],
            values["lon_deg"],
            values["alt_m"],
            auto,
        )

    # ---- fence entries

    def fence(self, entries: Any, frame: LocalNedFrame) -> list[MissionItem]:
        self.section = "fence"
        if entries is None:
            entries = []
        if not isinstance(entries, list):
            raise MissionFileError(
                self.path,
                "expected a list of zones",
                field="fence",
                line=self.line("fence"),
                fix="write one '- exclusion_circle: {...}' zone per line under 'fence:'",
            )
        items: list[MissionItem] = []
        for idx, entry in enumerate(entries):
            self.index, self.kind = idx, ""
            if not isinstance(entry, dict) or len(entry) != 1:
                raise self.fail(
                    "each zone is a mapping with exactly one key", fix="write e.g. '- exclusion_circle: {...}'"
                )
            ((kind, body),) = entry.items()
            self.kind = str(kind)
            inclusion = str(kind).startswith("inclusion_")
            if kind in ("exclusion_circle", "inclusion_circle"):
                allowed = ("north_m", "east_m", "lat_deg", "lon_deg", "radius_m", *(("group",) if inclusion else ()))
                d = self.mapping(body, allowed)
                ll = self.latlon(d, frame, required=True)
                assert ll is not None
                radius = self.number(d, "radius_m", 0.01, 1e6)
                group = int(self.number(d, "group", 0, 255)) if "group" in d else 0
                items += circle_fence_items(len(items), ll[0], ll[1], radius, inclusion=inclusion, group=group)
            elif kind in ("exclusion_polygon", "inclusion_polygon"):
                items += self.polygon(body, frame, len(items), inclusion)
            else:
                zones = ("exclusion_circle", "exclusion_polygon", "inclusion_circle", "inclusion_polygon")
                raise self.fail(
                    f"unknown fence zone (allowed: {', '.join(zones)})", str(kind), fix=did_you_mean(kind, zones)
                )
        self.index, self.kind = None, ""
        return items

    def polygon(self, body: Any, frame: LocalNedFrame, seq: int, inclusion: bool) -> list[MissionItem]:
        group = 0
        if isinstance(body, dict):
            d = self.mapping(body, ("vertices_ne_m", "vertices_lat_lon_deg", *(("group",) if inclusion else ())))
            group = int(self.number(d, "group", 0, 255)) if "group" in d else 0
            if ("vertices_ne_m" in d) == ("vertices_lat_lon_deg" in d):
                raise self.fail("give exactly one of vertices_ne_m or vertices_lat_lon_deg", "vertices_ne_m")
            field = "vertices_ne_m" if "vertices_ne_m" in d else "vertices_lat_lon_deg"
            vertices, geodetic = d[field], field == "vertices_lat_lon_deg"
        else:
            field, vertices, geodetic = "vertices", body, False
        if not isinstance(vertices, list) or len(vertices) < 3:
            raise self.fail("a polygon needs a list of at least 3 [a, b] vertices", field)
        latlon: list[tuple[float, float]] = []
        for k, v in enumerate(vertices):
            if not isinstance(v, list | tuple) or len(v) != 2:
                raise self.fail(f"vertex {k} must be a pair [a, b], got {v!r}", field)
            pair = {"a": v[0], "b": v[1]}
            if geodetic:
                latlon.append((self.number(pair, "a", -90.0, 90.0), self.number(pair, "b", -180.0, 180.0)))
            else:
                g = frame.geodetic_from_ned(self.number(pair, "a"), self.number(pair, "b"), 0.0)
                latlon.append((g.lat_deg, g.lon_deg))
        return polygon_fence_items(seq, latlon, inclusion=inclusion, group=group)


def _nav(cmd: MavCmd, latlon: tuple[float, float], alt_m: float, *, p1=0.0, p2=0.0, p3=0.0, p4=_NAN) -> MissionItem:
    return MissionItem(0, int(cmd), _REL, float(p1), float(p2), float(p3), float(p4), latlon[0], latlon[1], alt_m)


def _speed_item(speed_m_s: float) -> MissionItem:
    return MissionItem(0, int(MavCmd.DO_CHANGE_SPEED), _MISSION_FRAME, param1=1.0, param2=speed_m_s, param3=-1.0)


# --------------------------------------------------------------------------------------------- YAML writing


def _clean(d: dict[str, Any]) -> dict[str, Any]:
    return {k: v for k, v in d.items() if not (isinstance(v, float) and math.isnan(v))}


def _friendly_entry(item: MissionItem, seq_offset: int) -> dict[str, Any] | None:
    """The friendly YAML form of one item, or None when only ``mav_item`` can express it."""
    ll = {"lat_deg": item.x_lat_deg, "lon_deg": item.y_lon_deg}
    yaw = {"yaw_deg": item.param4}
    cmd = item.command
    if cmd == MavCmd.NAV_TAKEOFF:
        here = item.x_lat_deg == 0.0 and item.y_lon_deg == 0.0
        return {"takeoff": _clean({"alt_m": item.z_alt_m, **({} if here else ll), **yaw})}
    if cmd == MavCmd.NAV_WAYPOINT:
        body = {**ll, "alt_m": item.z_alt_m, "accept_radius_m": item.param2, "hold_s": item.param1, **yaw}
        return {"waypoint": _clean({k: v for k, v in body.items() if k not in ("accept_radius_m", "hold_s") or v})}
    if cmd == MavCmd.DO_GRIPPER:
        kind = "payload_release" if item.param2 == GripperAction.RELEASE else "payload_grab"
        return {kind: {} if item.param1 == 1.0 else {"gripper": item.param1}}
    if cmd == MavCmd.NAV_LOITER_TIME:
        here = item.x_lat_deg == 0.0 and item.y_lon_deg == 0.0
        return {"loiter": _clean({"seconds": item.param1, **({} if here else {**ll, "alt_m": item.z_alt_m}), **yaw})}
    if cmd == MavCmd.DO_CHANGE_SPEED:
        return {"speed": {"m_s": item.param2}}
    if cmd == MavCmd.NAV_DELAY:
        return {"delay": {"seconds": item.param1}}
    if cmd == MavCmd.DO_JUMP:
        return {"jump": {"to_entry": int(item.param1) - seq_offset, "repeat": int(item.param2)}}
    if cmd == MavCmd.NAV_RETURN_TO_LAUNCH:
        return {"return_to_launch": {}}
    if cmd == MavCmd.NAV_LAND:
        here = item.x_lat_deg == 0.0 and item.y_lon_deg == 0.0
        return {"land": _clean({**({} if here else ll), **yaw})}
    return None


def _raw_entry(item: MissionItem) -> dict[str, Any]:
    return {
        "mav_item": {
            "command": item.command,
            "frame": item.frame,
            "param1": item.param1,
            "param2": item.param2,
            "param3": item.param3,
            "param4": item.param4,
            "lat_deg": item.x_lat_deg,
            "lon_deg": item.y_lon_deg,
            "alt_m": item.z_alt_m,
            "autocontinue": item.autocontinue,
        }
    }


def _yaml_mission_entries(plan: MissionPlan, path: str | Path) -> list[dict[str, Any]]:
    items = list(plan.items)
    offset = 0
    if plan.speed_m_s is not None and items and items_match(items[:1], [replace(_speed_item(plan.speed_m_s))]):
        items, offset = items[1:], 1
    frame = LocalNedFrame(plan.home)
    reader = _YamlReader(path, _no_patterns)
    entries: list[dict[str, Any]] = []
    for item in items:
        entry = _friendly_entry(item, offset)
        if entry is not None:
            ((kind, body),) = entry.items()
            try:
                if kind == "jump":
                    back = [MissionItem(0, int(MavCmd.DO_JUMP), _MISSION_FRAME, param1=item.param1, param2=item.param2)]
                    exact = body["to_entry"] >= 0
                else:
                    back, exact = reader.entry(kind, body, frame), True
            except MissionFileError:
                back, exact = [], False
            if not (exact and items_match([replace(b, seq=item.seq) for b in back], [item], deg_tol=0.0, tol=0.0)):
                entry = None
        entries.append(entry if entry is not None else _raw_entry(item))
    return entries


def _no_patterns(pattern_type: str, spacing_m: float, params: dict[str, Any]) -> list[tuple[float, float, float]]:
    raise ValueError("patterns are not expanded while writing")


def _fence_shapes(fence: Sequence[MissionItem]) -> list[tuple[MissionItem, list[tuple[float, float]]]]:
    """Group FENCE items into zones: (first item, [(lat, lon), ...]); circles have one vertex."""
    shapes = []
    i = 0
    while i < len(fence):
        item = fence[i]
        is_polygon = item.command in (
            MavCmd.NAV_FENCE_POLYGON_VERTEX_INCLUSION,
            MavCmd.NAV_FENCE_POLYGON_VERTEX_EXCLUSION,
        )
        count = max(int(item.param1), 1) if is_polygon else 1
        shapes.append((item, [(v.x_lat_deg, v.y_lon_deg) for v in fence[i : i + count]]))
        i += count
    return shapes


def _yaml_fence_entries(plan: MissionPlan) -> list[dict[str, Any]]:
    entries = []
    for first, verts in _fence_shapes(plan.fence):
        inclusion = first.command in (MavCmd.NAV_FENCE_CIRCLE_INCLUSION, MavCmd.NAV_FENCE_POLYGON_VERTEX_INCLUSION)
        group = {"group": int(first.param2)} if inclusion and first.param2 else {}
        prefix = "inclusion" if inclusion else "exclusion"
        if first.command in (MavCmd.NAV_FENCE_CIRCLE_INCLUSION, MavCmd.NAV_FENCE_CIRCLE_EXCLUSION):
            body = {"lat_deg": first.x_lat_deg, "lon_deg": first.y_lon_deg, "radius_m": first.param1, **group}
            entries.append({f"{prefix}_circle": body})
        else:
            entries.append({f"{prefix}_polygon": {"vertices_lat_lon_deg": [list(v) for v in verts], **group}})
    return entries


def _write_yaml(plan: MissionPlan, path: Path) -> None:
    doc: dict[str, Any] = {
        "name": plan.name,
        "home": {"lat_deg": plan.home.lat_deg, "lon_deg": plan.home.lon_deg, "alt_m": plan.home.alt_amsl_m},
    }
    if plan.vehicle:  # empty: not known (a downloaded mission): no line rather than a wrong name
        doc["vehicle"] = plan.vehicle
    if plan.speed_m_s is not None:
        doc["speed_m_s"] = plan.speed_m_s
    doc["mission"] = _yaml_mission_entries(plan, path)
    if plan.fence:
        doc["fence"] = _yaml_fence_entries(plan)
    if plan.world is not None:
        doc["world"] = plan.world
    path.write_text(yaml.safe_dump(doc, sort_keys=False, default_flow_style=None, width=120))


# --------------------------------------------------------------------------------------------- QGC WPL 110


def _fmt(v: float) -> str:
    return repr(float(v))


def _jump_shift(item: MissionItem, delta: int) -> MissionItem:
    return replace(item, param1=item.param1 + delta) if item.command == MavCmd.DO_JUMP else item


def _write_wpl(plan: MissionPlan, path: Path, allow_drop_fence: bool) -> None:
    if plan.fence and not allow_drop_fence:
        raise MissionFileError(path, "QGC WPL 110 cannot hold fence items: save as .plan or .yaml instead")
    h = plan.home
    lines = [
        _WPL_HEADER,
        "\t".join(["0", "1", "0", "16", "0", "0", "0", "0", _fmt(h.lat_deg), _fmt(h.lon_deg), _fmt(h.alt_amsl_m), "1"]),
    ]
    for item in plan.items:
        it = _jump_shift(item, +1)
        cols = [str(item.seq + 1), "0", str(it.frame), str(it.command)]
        cols += [_fmt(v) for v in (it.param1, it.param2, it.param3, it.param4, it.x_lat_deg, it.y_lon_deg, it.z_alt_m)]
        cols.append("1" if it.autocontinue else "0")
        lines.append("\t".join(cols))
    path.write_text("\n".join(lines) + "\n")


def _read_wpl(path: Path) -> MissionPlan:
    numbered = [(n, ln) for n, ln in enumerate(path.read_text().splitlines(), start=1) if ln.strip()]
    if not numbered or numbered[0][1].strip() != _WPL_HEADER:
        line = numbered[0][0] if numbered else 1
        raise MissionFileError(
            path, f"first line must be '{_WPL_HEADER}'", line=line, fix=f"write '{_WPL_HEADER}' there"
        )
    rows: list[tuple[int, list[str]]] = [(n, ln.split()) for n, ln in numbered[1:]]
    if not rows:
        raise MissionFileError(
            path, "no home line (line 0) after the header", line=numbered[0][0], fix="add the home position line"
        )
    values: list[tuple[int, int, int, list[float], bool]] = []
    columns = "INDEX CURRENT FRAME COMMAND P1 P2 P3 P4 LAT LON ALT AUTOCONTINUE"
    for idx, (line, cols) in enumerate(rows):
        if len(cols) != 12:
            raise MissionFileError(
                path,
                f"expected 12 columns, got {len(cols)}",
                section="line",
                item_index=idx,
                line=line,
                fix=f"write the tab-separated columns {columns}",
            )
        try:
            index, frame, command = int(cols[0]), int(cols[2]), int(cols[3])
            nums = [float(c) for c in cols[4:11]]
            auto = int(cols[11]) != 0
        except ValueError as exc:
            raise MissionFileError(
                path, f"not a number: {exc}", section="line", item_index=idx, line=line, fix=f"columns: {columns}"
            ) from None
        if index != idx:
            raise MissionFileError(
                path,
                f"index column is {index}, expected {idx}",
                section="line",
                item_index=idx,
                field="seq",
                line=line,
                fix=f"number the lines 0, 1, 2, ... (this one {idx})",
            )
        values.append((index, frame, command, nums, auto))
    _, home_frame, _, home_nums, _ = values[0]
    if home_frame not in (MavFrame.GLOBAL, MavFrame.GLOBAL_INT):
        raise MissionFileError(
            path,
            "home (line 0) must be in frame 0 (GLOBAL, altitude AMSL)",
            section="line",
            item_index=0,
            field="frame",
        )
    home = GeoPoint(home_nums[4], home_nums[5], home_nums[6])
    items = []
    for index, frame, command, n, auto in values[1:]:
        item = MissionItem(index - 1, command, frame, n[0], n[1], n[2], n[3], n[4], n[5], n[6], auto)
        items.append(_jump_shift(item, -1))
    return MissionPlan(path.stem, home, items, [], _leading_speed(items))


def _leading_speed(items: Sequence[MissionItem]) -> float | None:
    if items and items[0].command == MavCmd.DO_CHANGE_SPEED and items[0].param2 > 0.0:
        return items[0].param2
    return None


# --------------------------------------------------------------------------------------------- QGC .plan


def _json_num(v: float) -> float | None:
    return None if math.isnan(v) else v


def _plan_num(v: Any, path: Path, idx: int, field: str) -> float:
    if v is None:
        return _NAN
    if isinstance(v, bool) or not isinstance(v, int | float):
        raise MissionFileError(
            path, f"expected a number or null, got {v!r}", section="mission", item_index=idx, field=field
        )
    return float(v)


def _write_plan(plan: MissionPlan, path: Path) -> None:
    items_json = []
    for item in plan.items:
        it = _jump_shift(item, +1)
        params = [it.param1, it.param2, it.param3, it.param4, it.x_lat_deg, it.y_lon_deg, it.z_alt_m]
        items_json.append(
            {
                "type": "SimpleItem",
                "autoContinue": it.autocontinue,
                "command": it.command,
                "doJumpId": item.seq + 1,
                "frame": it.frame,
                "params": [_json_num(p) for p in params],
            }
        )
    circles, polygons = [], []
    for first, verts in _fence_shapes(plan.fence):
        inclusion = first.command in (MavCmd.NAV_FENCE_CIRCLE_INCLUSION, MavCmd.NAV_FENCE_POLYGON_VERTEX_INCLUSION)
        if first.command in (MavCmd.NAV_FENCE_CIRCLE_INCLUSION, MavCmd.NAV_FENCE_CIRCLE_EXCLUSION):
            circle = {"center": [first.x_lat_deg, first.y_lon_deg], "radius": first.param1}
            circles.append({"circle": circle, "inclusion": inclusion, "version": 1})
        else:
            polygons.append({"inclusion": inclusion, "polygon": [list(v) for v in verts], "version": 1})
    cruise = plan.speed_m_s if plan.speed_m_s is not None else 5.0
    doc = {
        "fileType": "Plan",
        "groundStation": "quadsitl",
        "version": 1,
        "mission": {
            "version": 2,
            "firmwareType": 12,  # MAV_AUTOPILOT_PX4
            "vehicleType": 2,  # MAV_TYPE_QUADROTOR
            "cruiseSpeed": cruise,
            "hoverSpeed": cruise,
            "plannedHomePosition": [plan.home.lat_deg, plan.home.lon_deg, plan.home.alt_amsl_m],
            "items": items_json,
        },
        "geoFence": {"version": 2, "circles": circles, "polygons": polygons},
        "rallyPoints": {"version": 2, "points": []},
        "quadsitl": {"name": plan.name, "vehicle": plan.vehicle, "speed_m_s": plan.speed_m_s, "world": plan.world},
    }
    path.write_text(json.dumps(doc, indent=2) + "\n")


def _read_plan(path: Path) -> MissionPlan:
    try:
        doc = json.loads(path.read_text())
    except json.JSONDecodeError as exc:
        raise MissionFileError(
            path, f"not valid JSON: {exc.msg} (column {exc.colno})", line=exc.lineno, fix="save the plan again from QGC"
        ) from None
    if not isinstance(doc, dict) or doc.get("fileType") != "Plan":
        raise MissionFileError(path, "not a QGroundControl plan (fileType must be 'Plan')", field="fileType")
    mission = doc.get("mission")
    if not isinstance(mission, dict):
        raise MissionFileError(path, "missing 'mission' object", field="mission")
    home_l = mission.get("plannedHomePosition")
    if not (isinstance(home_l, list) and len(home_l) == 3 and all(isinstance(v, int | float) for v in home_l)):
        raise MissionFileError(path, "expected [lat, lon, alt_amsl]", field="mission.plannedHomePosition")
    home = GeoPoint(float(home_l[0]), float(home_l[1]), float(home_l[2]))
    items: list[MissionItem] = []
    for idx, it in enumerate(mission.get("items") or []):
        if not isinstance(it, dict) or it.get("type") != "SimpleItem":
            kind = it.get("type") if isinstance(it, dict) else type(it).__name__
            raise MissionFileError(
                path,
                f"unsupported item type {kind!r} (only SimpleItem; convert complex items in QGC)",
                section="mission",
                item_index=idx,
                field="type",
            )
        params = it.get("params")
        if not isinstance(params, list) or len(params) != 7:
            raise MissionFileError(
                path, "expected a list of 7 numbers", section="mission", item_index=idx, field="params"
            )
        for key in ("command", "frame"):
            if not isinstance(it.get(key), int) or isinstance(it.get(key), bool):
                raise MissionFileError(
                    path, f"expected an integer, got {it.get(key)!r}", section="mission", item_index=idx, field=key
                )
        p = [_plan_num(v, path, idx, f"params[{k}]") for k, v in enumerate(params)]
        auto = it.get("autoContinue", True)
        item = MissionItem(idx, it["command"], it["frame"], p[0], p[1], p[2], p[3], p[4], p[5], p[6], bool(auto))
        items.append(_jump_shift(item, -1))
    fence: list[MissionItem] = []
    geofence = doc.get("geoFence") or {}
    try:
        for poly in geofence.get("polygons", []):
            verts = [(float(a), float(b)) for a, b in poly["polygon"]]
            fence += polygon_fence_items(len(fence), verts, inclusion=bool(poly.get("inclusion", True)))
        for circ in geofence.get("circles", []):
            (lat, lon), radius = circ["circle"]["center"], circ["circle"]["radius"]
            fence += circle_fence_items(
                len(fence), float(lat), float(lon), float(radius), inclusion=bool(circ.get("inclusion", True))
            )
    except (KeyError, TypeError, ValueError) as exc:
        raise MissionFileError(path, f"malformed zone: {exc!r}", section="geoFence") from None
    extra = doc.get("quadsitl") if isinstance(doc.get("quadsitl"), dict) else {}
    world = extra.get("world")
    return MissionPlan(
        str(extra.get("name") or path.stem),
        home,
        items,
        fence,
        _leading_speed(items),
        str(extra.get("vehicle") or DEFAULT_VEHICLE),
        world if isinstance(world, dict) else None,
    )


# --------------------------------------------------------------------------------------------- entry points


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
    reader: _YamlReader | None = None
    text = ""
    try:
        text = p.read_text()
        if fmt == "yaml":
            try:
                source = parse_yaml(text, p)
            except YamlSyntaxError as exc:
                raise MissionFileError(p, f"not valid YAML: {exc.detail}", line=exc.line, fix=exc.fix) from None
            reader = _YamlReader(p, expander, source)
            plan = reader.read(source.data)
        elif fmt == "wpl":
            plan = _read_wpl(p)
        else:
            plan = _read_plan(p)
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


def _item_line(fmt: str, text: str, reader: _YamlReader | None, section: str, index: int | None) -> int | None:
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
        _write_yaml(plan, p)
    elif fmt == "wpl":
        _write_wpl(plan, p, allow_drop_fence)
    else:
        _write_plan(plan, p)
