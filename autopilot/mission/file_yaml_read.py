"""Reading the project's YAML v1 mission file (SPEC §8) into a MissionPlan, with the line of every error."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import replace
from pathlib import Path
from typing import Any

from autopilot.geofence.fence import circle_fence_items, polygon_fence_items
from autopilot.mission.file_common import MissionFileError, PatternExpander, speed_item
from autopilot.mission.plan import DEFAULT_VEHICLE, MissionPlan
from mavlink_bridge.contract.frames import GeoPoint, LocalNedFrame
from mavlink_bridge.contract.mav_enums import GripperAction, MavCmd, MavFrame
from mavlink_bridge.contract.source_lines import YamlSource, did_you_mean
from mavlink_bridge.contract.vehicle_api import MissionItem

_REL = int(MavFrame.GLOBAL_RELATIVE_ALT_INT)
_MISSION_FRAME = int(MavFrame.MISSION)
_NAN = float("nan")
#: ``vehicles``/``traffic`` (a fleet world, SPEC §13) are the simulator's and each vehicle's: not read here.
_TOP_KEYS = ("version", "name", "home", "vehicle", "speed_m_s", "mission", "fence", "world", "vehicles", "traffic",
             "traffic_link")  # fmt: skip
_ENTRY_KINDS = (
    "takeoff", "waypoint", "pattern", "payload_release", "payload_grab", "loiter", "speed", "delay", "jump",
    "return_to_launch", "land", "mav_item",
)  # fmt: skip


class YamlReader:
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
        #: YAML path of the entry being read: () for the file's own mission, ("vehicles", i) for a fleet vehicle's.
        self.prefix: tuple[str | int, ...] = ()

    def line(self, *path: str | int) -> int | None:
        """The line of the deepest node along ``path`` (None without a source)."""
        return self.source.line(*self.prefix, *path) if self.source is not None else None

    def fail(self, message: str, field: str = "", fix: str = "") -> MissionFileError:
        section = f"{self.section} ({self.kind})" if self.kind and self.index is None else self.section
        if self.prefix:
            section = f"vehicles[{self.prefix[1]}] {section}".rstrip()
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

    def read_vehicle(self, index: int, entry: Any, world: MissionPlan) -> MissionPlan:
        """Fleet vehicle ``index``'s ``mission:``/``fence:``/``speed_m_s:`` as a plan about the world's home (SPEC
        §13; its name and airframe from the entry; its ``failures:`` are the autopilot's ``--fleet-vehicle``). Leaves
        ``prefix`` at the entry, for the caller's checks."""
        self.prefix, self.section, self.index, self.kind = ("vehicles", index), "", None, ""
        entry = self.mapping(entry, ("name", "vehicle", "home", "mission", "fence", "speed_m_s", "failures"))
        speed = self.number(entry, "speed_m_s", 0.1, 50.0) if entry.get("speed_m_s") is not None else world.speed_m_s
        frame = LocalNedFrame(world.home)
        items = self.mission(entry.get("mission"), frame, speed)
        fence = self.fence(entry.get("fence"), frame)
        name, vehicle = str(entry.get("name", f"vehicle{index}")), str(entry.get("vehicle") or world.vehicle)
        return MissionPlan(name, world.home, items, fence, speed, vehicle, world.world)

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
            raw.append(speed_item(speed))
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
            return [speed_item(self.number(d, "m_s", 0.1, 50.0))]
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
