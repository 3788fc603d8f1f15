"""The fleet parts of a world file: ``vehicles:`` and ``traffic:`` (SPEC §13).

Both keys are optional; a file without them is one vehicle, exactly as before. Every ``north_m``/``east_m``
is about the world's home (vehicles' homes, their missions, traffic paths). Instance i (the i-th entry of
``vehicles:``) is MAV_SYS_ID i+1. Vehicles' ``mission:``/``fence:``/``speed_m_s:`` are the autopilot's to read
(the same items as the top-level ``mission:``); here they are only checked for their container type. A vehicle's
``failures:`` (the world's ``failures:`` schema) are that vehicle's alone; the world's go to every vehicle
(:meth:`FleetSpec.failures_of` merges them, as the autopilot's ``--fleet-vehicle`` does).
Errors name the file and line: ``FILE:LINE: vehicles[1].home.north_m: ...``.
"""

from __future__ import annotations

import re
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from mavlink_bridge.contract.failure_schedule import (
    FailureScheduleError,
    ScheduledFailure,
    merge_failures,
    mission_failures,
    parse_failures,
)
from mavlink_bridge.contract.frames import GeoPoint, LocalNedFrame
from mavlink_bridge.contract.source_lines import YamlSyntaxError, did_you_mean, read_yaml
from mavlink_bridge.contract.traffic import AdsbEmitterType
from sim.traffic_link import TRAFFIC_LINK_KEYS, TrafficLinkConfig
from sim.world import DEFAULT_HOME, WorldConfigError, _fields, _home, _node_path, _num

#: MAV_SYS_ID is one byte and 0 is broadcast: at most 254 vehicles (PX4 refuses more than 255 instances).
MAX_VEHICLES = 254
_NAME = re.compile(r"^[A-Za-z][A-Za-z0-9_-]{0,31}$")
_CALLSIGN = re.compile(r"^[A-Z0-9 ]{1,8}$")
_COORD = (-1e5, 1e5)
#: ADS-B emitter names as written in a file: the MAVLink enum's names in lower case (``rotorcraft`` too).
EMITTER_NAMES: dict[str, AdsbEmitterType] = {e.name.lower(): e for e in AdsbEmitterType}
EMITTER_NAMES["rotorcraft"] = AdsbEmitterType.ROTOCRAFT  # MAVLink spells it ROTOCRAFT


@dataclass(frozen=True, slots=True)
class FleetVehicle:
    """One ``vehicles:`` entry: instance ``index`` (MAV_SYS_ID ``index + 1``), home on the ground about the world's."""

    index: int
    name: str
    vehicle: str | None  # airframe name or path; None: the file's ``vehicle:``, else the default
    home_north_m: float
    home_east_m: float
    mission: tuple[Any, ...]  # raw ``mission:`` entries (the autopilot's mission reader parses them)
    fence: Any  # raw ``fence:`` (None when absent)
    speed_m_s: float | None
    failures: tuple[ScheduledFailure, ...] = ()  # this vehicle's own (``vehicles[i].failures``), by time

    @property
    def sys_id(self) -> int:
        """MAV_SYS_ID of this vehicle (PX4: instance + 1)."""
        return self.index + 1


@dataclass(frozen=True, slots=True)
class TrafficWaypoint:
    """A point of a scripted aircraft's path: about the world's home, ``alt_m`` above it."""

    north_m: float
    east_m: float
    alt_m: float


@dataclass(frozen=True, slots=True)
class ScriptedAircraft:
    """One ``traffic:`` entry: flown along ``path`` at ``speed_m_s`` from ``start_s`` (sim time) to its end."""

    callsign: str
    icao: int
    emitter: AdsbEmitterType
    path: tuple[TrafficWaypoint, ...]
    speed_m_s: float
    start_s: float


@dataclass(frozen=True, slots=True)
class FleetSpec:
    """The fleet of a world file (empty tuples: a single-vehicle world)."""

    home: GeoPoint
    vehicles: tuple[FleetVehicle, ...]
    traffic: tuple[ScriptedAircraft, ...]
    world_failures: tuple[ScheduledFailure, ...] = ()  # the world's ``failures:``: every vehicle's
    traffic_link: tuple[tuple[str, float], ...] = ()  # the world's ``traffic_link:`` (TrafficLinkConfig fields)

    @property
    def is_fleet(self) -> bool:
        """True when the file lists ``vehicles:`` (one simulator, one autopilot per vehicle)."""
        return bool(self.vehicles)

    def failures_of(self, index: int) -> tuple[ScheduledFailure, ...]:
        """What vehicle ``index``'s autopilot injects: the world's failures and its own, merged by time (the
        world's first at a tie), as ``quadsitl autopilot --world-failures W --fleet-vehicle NAME`` reads them."""
        return merge_failures(self.world_failures, self.vehicles[index].failures)


def load_fleet(path: str | Path) -> FleetSpec:
    """``vehicles:`` and ``traffic:`` of a mission YAML (WorldConfigError ``FILE:LINE: field: ...``)."""
    try:
        parsed = read_yaml(path)
    except YamlSyntaxError as exc:
        raise WorldConfigError(str(exc)) from None
    except OSError as exc:
        raise WorldConfigError(f"world: cannot read {str(path)!r} ({exc.strerror})") from None
    try:
        return fleet_of(parsed.data)
    except WorldConfigError as exc:
        raise WorldConfigError(f"{parsed.where(*_node_path(str(exc)))}: {exc}") from None


def fleet_of(doc: Any) -> FleetSpec:
    """The fleet of a parsed mission document (WorldConfigError naming the field)."""
    if not isinstance(doc, dict):
        return FleetSpec(DEFAULT_HOME, (), ())
    home = _home(doc["home"]) if "home" in doc else DEFAULT_HOME
    vehicles_spec = doc.get("vehicles")
    traffic_spec = doc.get("traffic")
    for key, spec in (("vehicles", vehicles_spec), ("traffic", traffic_spec)):
        if spec is not None and not isinstance(spec, list):
            raise WorldConfigError(f"{key}: expected a list of entries, got {spec!r}")
    vehicles = tuple(_vehicle(i, e, home) for i, e in enumerate(vehicles_spec or []))
    if len(vehicles) > MAX_VEHICLES:
        raise WorldConfigError(f"vehicles: {len(vehicles)} vehicles, at most {MAX_VEHICLES} (MAV_SYS_ID is 1..254)")
    names = [v.name for v in vehicles]
    for i, name in enumerate(names):
        if name in names[:i]:
            raise WorldConfigError(f"vehicles[{i}].name: {name!r} is used twice; fix: give each vehicle its own name")
    traffic = tuple(_aircraft(i, e) for i, e in enumerate(traffic_spec or []))
    icaos = [a.icao for a in traffic]
    for i, icao in enumerate(icaos):
        if icao in icaos[:i]:
            raise WorldConfigError(f"traffic[{i}].icao: 0x{icao:06X} is used twice; fix: one address per aircraft")
    link = _traffic_link(doc["traffic_link"]) if "traffic_link" in doc else ()
    return FleetSpec(home, vehicles, traffic, _failures(lambda: mission_failures(doc)), link)


def _traffic_link(spec: Any) -> tuple[tuple[str, float], ...]:
    """``traffic_link:``: numbers of the UTM relay and the ADS-B link (``sim.traffic_link.TrafficLinkConfig``)."""
    s = _fields("traffic_link", spec, set(), set(TRAFFIC_LINK_KEYS))
    pairs = tuple((key, _num("traffic_link", key, value, 0.0, 1e6)) for key, value in sorted(s.items()))
    problem = TrafficLinkConfig.with_overrides(pairs).problem()
    if problem is not None:
        raise WorldConfigError(f"traffic_link.{problem}")
    return pairs


def _vehicle(index: int, entry: Any, world_home: GeoPoint) -> FleetVehicle:
    where = f"vehicles[{index}]"
    s = _fields(where, entry, {"name", "home"}, {"vehicle", "mission", "fence", "speed_m_s", "failures"})
    name = s["name"]
    if not isinstance(name, str) or not _NAME.match(name):
        raise WorldConfigError(
            f"{where}.name: expected a name of letters, digits, '_' or '-' (up to 32, a letter first), got {name!r}"
        )
    airframe = s.get("vehicle")
    if airframe is not None and (not isinstance(airframe, str) or not airframe):
        raise WorldConfigError(f"{where}.vehicle: expected an airframe name such as x500, got {airframe!r}")
    north_m, east_m = _vehicle_home(f"{where}.home", s["home"], world_home)
    mission = s.get("mission") or []
    if not isinstance(mission, list):
        raise WorldConfigError(f"{where}.mission: expected a list of mission entries, got {mission!r}")
    fence = s.get("fence")
    if fence is not None and not isinstance(fence, dict | list):
        raise WorldConfigError(f"{where}.fence: expected a fence mapping as the top-level fence:, got {fence!r}")
    speed = s.get("speed_m_s")
    return FleetVehicle(
        index,
        name,
        airframe,
        north_m,
        east_m,
        tuple(mission),
        fence,
        None if speed is None else _num(where, "speed_m_s", speed, 0.1, 50.0),
        _failures(lambda: parse_failures(s.get("failures"), ("vehicles", index, "failures"))),
    )


def _failures(parse: Callable[[], tuple[ScheduledFailure, ...]]) -> tuple[ScheduledFailure, ...]:
    """A parsed ``failures:`` list, its FailureScheduleError as the world's error (``vehicles[1].failures[0]...``)."""
    try:
        return parse()
    except FailureScheduleError as exc:
        raise WorldConfigError(str(exc)) from None


def _vehicle_home(where: str, spec: Any, world_home: GeoPoint) -> tuple[float, float]:
    """(north_m, east_m) of a vehicle's home about the world's, from ``{north_m, east_m}`` or ``{lat_deg, lon_deg}``."""
    s = _fields(where, spec, set(), {"north_m", "east_m", "lat_deg", "lon_deg"})
    has_ne = "north_m" in s or "east_m" in s
    has_ll = "lat_deg" in s or "lon_deg" in s
    if has_ne == has_ll:
        raise WorldConfigError(
            f"{where}: give either north_m/east_m or lat_deg/lon_deg (about the world's home); fix: e.g. "
            "home: {north_m: 0, east_m: 8}"
        )
    if has_ne:
        north_m = _num(where, "north_m", s.get("north_m", 0.0), *_COORD)
        return north_m, _num(where, "east_m", s.get("east_m", 0.0), *_COORD)
    for key in ("lat_deg", "lon_deg"):
        if key not in s:
            raise WorldConfigError(f"{where}: missing {key}; fix: give both lat_deg and lon_deg")
    lat = _num(where, "lat_deg", s["lat_deg"], -90.0, 90.0)
    lon = _num(where, "lon_deg", s["lon_deg"], -180.0, 180.0)
    north_m, east_m, _ = LocalNedFrame(world_home).ned_from_geodetic(lat, lon, world_home.alt_amsl_m)
    if not (_COORD[0] <= north_m <= _COORD[1] and _COORD[0] <= east_m <= _COORD[1]):
        raise WorldConfigError(f"{where}.lat_deg: {lat}, {lon} is over 100 km from the world's home")
    return float(north_m), float(east_m)


def _aircraft(index: int, entry: Any) -> ScriptedAircraft:
    where = f"traffic[{index}]"
    s = _fields(where, entry, {"callsign", "icao", "path", "speed_m_s"}, {"emitter", "start_s"})
    callsign = s["callsign"]
    if not isinstance(callsign, str) or not _CALLSIGN.match(callsign):
        raise WorldConfigError(f"{where}.callsign: expected 1-8 capital letters or digits, got {callsign!r}")
    icao = s["icao"]
    if isinstance(icao, bool) or not isinstance(icao, int) or not 0 < icao <= 0xFFFFFF:
        raise WorldConfigError(f"{where}.icao: expected a 24-bit ICAO address such as 0xA1B2C3, got {icao!r}")
    emitter_name = s.get("emitter", "no_info")
    if not isinstance(emitter_name, str) or emitter_name.lower() not in EMITTER_NAMES:
        raise WorldConfigError(
            f"{where}.emitter: unknown ADS-B emitter type {emitter_name!r}; fix: "
            f"{did_you_mean(str(emitter_name).lower(), EMITTER_NAMES)}"
        )
    path = s["path"]
    if not isinstance(path, list) or len(path) < 2:
        raise WorldConfigError(f"{where}.path: expected at least two points {{north_m, east_m, alt_m}}, got {path!r}")
    points = []
    for k, p in enumerate(path):
        at = f"{where}.path[{k}]"
        q = _fields(at, p, {"north_m", "east_m", "alt_m"})
        points.append(
            TrafficWaypoint(
                _num(at, "north_m", q["north_m"], *_COORD),
                _num(at, "east_m", q["east_m"], *_COORD),
                _num(at, "alt_m", q["alt_m"], -500.0, 20000.0),
            )
        )
    return ScriptedAircraft(
        callsign,
        icao,
        EMITTER_NAMES[emitter_name.lower()],
        tuple(points),
        _num(where, "speed_m_s", s["speed_m_s"], 0.1, 400.0),
        _num(where, "start_s", s.get("start_s", 0.0), 0.0, 1e6),
    )
