"""The simulated world: home, obstacles, wind and payload — the ``world:`` part of a mission YAML (SPEC §8).

Obstacles are given relative to home (north/east metres, altitudes above home) and converted to
local NED. Cylinders and boxes stand on the ground (z from 0 up to −height); a sphere floats at
``alt_m``. Every shape exposes a signed distance (negative inside) used for clearance and collision;
the same numba kernels serve :meth:`World.clearance_m` and the physics step.
"""

from __future__ import annotations

import math
import re
from abc import ABC, abstractmethod
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import yaml
from numba import njit

from mavlink_bridge.contract.failure_schedule import FailureScheduleError, ScheduledFailure, parse_failures
from mavlink_bridge.contract.frames import GeoPoint
from mavlink_bridge.contract.source_lines import YamlSyntaxError, did_you_mean, read_yaml

#: Default home when a world has none (SPEC §8 example, Hangzhou).
DEFAULT_HOME = GeoPoint(30.2635, 120.1233, 12.0)

KIND_SPHERE = 0
KIND_CYLINDER = 1
KIND_BOX = 2
#: Width of the packed obstacle parameter rows (see :meth:`World.obstacle_arrays`).
OBSTACLE_PARAM_WIDTH = 7


class WorldConfigError(ValueError):
    """The world description was refused; the message names the entry, field and allowed range."""


@njit(cache=True, error_model="numpy")
def _capped_distance(d_h: float, d_v: float) -> float:
    """Signed distance of the intersection of two slabs with signed distances ``d_h`` and ``d_v``."""
    if d_h > 0.0 and d_v > 0.0:
        return math.sqrt(d_h * d_h + d_v * d_v)
    return max(d_h, d_v)


@njit(cache=True, error_model="numpy")
def obstacle_distance_m(kind: int, p: np.ndarray, north_m: float, east_m: float, down_m: float) -> float:
    """Signed distance (m, negative inside) from a NED point to one packed obstacle ``p``.

    Packing: sphere ``(n, e, d, r)``; cylinder ``(n, e, r, h)``; box ``(n, e, cos ψ, sin ψ, l/2, w/2, h)``.
    Ground-standing shapes extend from z = 0 up to z = −h (and are treated as unbounded below).
    """
    dn = north_m - p[0]
    de = east_m - p[1]
    if kind == KIND_SPHERE:
        dd = down_m - p[2]
        return math.sqrt(dn * dn + de * de + dd * dd) - p[3]
    if kind == KIND_CYLINDER:
        return _capped_distance(math.sqrt(dn * dn + de * de) - p[2], -p[3] - down_m)
    # box: rotate into the box frame (x along yaw)
    bx = abs(p[2] * dn + p[3] * de) - p[4]
    by = abs(-p[3] * dn + p[2] * de) - p[5]
    d_h = _capped_distance(bx, by)
    return _capped_distance(d_h, -p[6] - down_m)


@njit(cache=True, error_model="numpy")
def min_obstacle_distance_m(
    kinds: np.ndarray, params: np.ndarray, north_m: float, east_m: float, down_m: float
) -> float:
    """Smallest signed distance to any obstacle (inf when there are none)."""
    best = np.inf
    for k in range(kinds.shape[0]):
        d = obstacle_distance_m(kinds[k], params[k], north_m, east_m, down_m)
        if d < best:
            best = d
    return best


@njit(cache=True, error_model="numpy")
def _distances(kinds: np.ndarray, params: np.ndarray, pos_ned: np.ndarray, out: np.ndarray) -> None:
    for i in range(pos_ned.shape[0]):
        out[i] = min_obstacle_distance_m(kinds, params, pos_ned[i, 0], pos_ned[i, 1], pos_ned[i, 2])


def _as_points(pos_ned: np.ndarray) -> np.ndarray:
    pts = np.ascontiguousarray(pos_ned, dtype=np.float64)
    return pts.reshape(1, 3) if pts.ndim == 1 else pts


class _Shape(ABC):
    """Common behaviour of the obstacle shapes: packing for the kernels and signed distance."""

    kind: int

    @abstractmethod
    def packed(self) -> np.ndarray:
        """The shape as one row of :meth:`World.obstacle_arrays` params."""

    def distance_m(self, pos_ned: np.ndarray) -> np.ndarray:
        """Signed distance (m, negative inside) of each point of ``pos_ned`` (n, 3) or (3,)."""
        pts = _as_points(pos_ned)
        out = np.empty(pts.shape[0])
        _distances(np.array([self.kind], dtype=np.int64), self.packed().reshape(1, -1), pts, out)
        return out


@dataclass(frozen=True)
class Sphere(_Shape):
    """A floating sphere centred ``alt_m`` above home (m)."""

    north_m: float
    east_m: float
    alt_m: float
    radius_m: float
    kind = KIND_SPHERE

    def packed(self) -> np.ndarray:
        return np.array([self.north_m, self.east_m, -self.alt_m, self.radius_m, 0.0, 0.0, 0.0])


@dataclass(frozen=True)
class Cylinder(_Shape):
    """A vertical cylinder standing on the ground, ``height_m`` tall."""

    north_m: float
    east_m: float
    radius_m: float
    height_m: float
    kind = KIND_CYLINDER

    def packed(self) -> np.ndarray:
        return np.array([self.north_m, self.east_m, self.radius_m, self.height_m, 0.0, 0.0, 0.0])


@dataclass(frozen=True)
class Box(_Shape):
    """A box standing on the ground, centred at (north, east); ``size_m`` = (length along yaw, width, height)."""

    north_m: float
    east_m: float
    size_m: tuple[float, float, float]
    yaw_deg: float = 0.0
    kind = KIND_BOX

    def packed(self) -> np.ndarray:
        yaw = math.radians(self.yaw_deg)
        length, width, height = self.size_m
        return np.array([self.north_m, self.east_m, math.cos(yaw), math.sin(yaw), length / 2, width / 2, height])


Obstacle = Sphere | Cylinder | Box


@dataclass(frozen=True)
class WindConfig:
    """Mean wind (m/s, NED, the air's velocity) plus Gauss–Markov gusts of std ``gust_m_s``, seeded."""

    mean_ned_m_s: tuple[float, float, float] = (0.0, 0.0, 0.0)
    gust_m_s: float = 0.0
    seed: int = 0
    gust_time_constant_s: float = 2.0


@dataclass(frozen=True)
class World:
    """Everything the simulator knows and the autopilot must sense."""

    home: GeoPoint
    obstacles: tuple[Obstacle, ...]
    wind: WindConfig
    payload_kg: float
    #: failures at sim times (``failures:``); the autopilot injects them (the simulator's truth is untouched)
    failures: tuple[ScheduledFailure, ...] = ()

    def obstacle_arrays(self) -> tuple[np.ndarray, np.ndarray]:
        """Packed obstacles for the numba kernels: kinds (k,) int64 and params (k, 7) float64."""
        kinds = np.array([o.kind for o in self.obstacles], dtype=np.int64)
        params = np.zeros((len(self.obstacles), OBSTACLE_PARAM_WIDTH))
        for k, o in enumerate(self.obstacles):
            params[k] = o.packed()
        return kinds, params

    def clearance_m(self, pos_ned: np.ndarray) -> np.ndarray:
        """Smallest signed distance (m) from each point (n, 3) or (3,) to any obstacle; inf when none."""
        pts = _as_points(pos_ned)
        out = np.empty(pts.shape[0])
        kinds, params = self.obstacle_arrays()
        _distances(kinds, params, pts, out)
        return out


def empty_world(home: GeoPoint | None = None) -> World:
    """No obstacles, calm air, no payload."""
    return World(home=home or DEFAULT_HOME, obstacles=(), wind=WindConfig(), payload_kg=0.0)


# ---- loading and validation ---------------------------------------------------------------------------

_COORD_RANGE = (-1e5, 1e5)
_SIZE_RANGE = (0.01, 1e4)


def _num(where: str, key: str, value: Any, lo: float, hi: float) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
        raise WorldConfigError(
            f"{where}.{key}: expected a finite number in [{lo:g}, {hi:g}], got {value!r}; fix: write a plain number"
        )
    if not lo <= value <= hi:
        raise WorldConfigError(
            f"{where}.{key}: {value!r} is outside the allowed range [{lo:g}, {hi:g}]; fix: use a value in that range"
        )
    return float(value)


def _fields(where: str, spec: Any, required: set[str], optional: set[str] = frozenset()) -> dict[str, Any]:
    if not isinstance(spec, dict):
        raise WorldConfigError(f"{where}: expected a mapping with {sorted(required)}, got {spec!r}")
    missing = sorted(required - set(spec))
    unknown = sorted(set(spec) - required - optional)
    if missing:
        raise WorldConfigError(
            f"{where}: missing field(s) {missing}; fix: add {', '.join(f'{m}: ...' for m in missing)}"
        )
    if unknown:
        allowed = sorted(required | optional)
        raise WorldConfigError(
            f"{where}.{unknown[0]}: unknown field(s) {unknown}; allowed {allowed}; "
            f"fix: {did_you_mean(unknown[0], allowed)}"
        )
    return spec


def _obstacle(index: int, entry: Any) -> Obstacle:
    if not isinstance(entry, dict) or len(entry) != 1:
        raise WorldConfigError(f"world.obstacles[{index}]: expected one of cylinder/box/sphere: {{...}}, got {entry!r}")
    ((shape, spec),) = entry.items()
    where = f"world.obstacles[{index}].{shape}"
    lo, hi = _COORD_RANGE
    slo, shi = _SIZE_RANGE
    if shape == "sphere":
        s = _fields(where, spec, {"north_m", "east_m", "alt_m", "radius_m"})
        return Sphere(
            _num(where, "north_m", s["north_m"], lo, hi),
            _num(where, "east_m", s["east_m"], lo, hi),
            _num(where, "alt_m", s["alt_m"], -1e4, 1e4),
            _num(where, "radius_m", s["radius_m"], slo, shi),
        )
    if shape == "cylinder":
        s = _fields(where, spec, {"north_m", "east_m", "radius_m", "height_m"})
        return Cylinder(
            _num(where, "north_m", s["north_m"], lo, hi),
            _num(where, "east_m", s["east_m"], lo, hi),
            _num(where, "radius_m", s["radius_m"], slo, shi),
            _num(where, "height_m", s["height_m"], slo, shi),
        )
    if shape == "box":
        s = _fields(where, spec, {"north_m", "east_m", "size_m"}, {"yaw_deg"})
        size = s["size_m"]
        if not isinstance(size, list | tuple) or len(size) != 3:
            raise WorldConfigError(f"{where}.size_m: expected [length, width, height] in metres, got {size!r}")
        return Box(
            _num(where, "north_m", s["north_m"], lo, hi),
            _num(where, "east_m", s["east_m"], lo, hi),
            tuple(_num(where, f"size_m[{i}]", v, slo, shi) for i, v in enumerate(size)),  # type: ignore[arg-type]
            _num(where, "yaw_deg", s.get("yaw_deg", 0.0), -360.0, 360.0),
        )
    shapes = ("cylinder", "box", "sphere")
    raise WorldConfigError(
        f"world.obstacles[{index}].{shape}: unknown shape {shape!r}; allowed {', '.join(shapes)}; "
        f"fix: {did_you_mean(shape, shapes)}"
    )


def _wind(spec: Any) -> WindConfig:
    where = "world.wind"
    keys = {"north_m_s", "east_m_s", "down_m_s", "gust_m_s", "seed", "gust_time_constant_s"}
    s = _fields(where, spec, set(), keys)
    mean = tuple(_num(where, k, s.get(k, 0.0), -50.0, 50.0) for k in ("north_m_s", "east_m_s", "down_m_s"))
    seed = s.get("seed", 0)
    if isinstance(seed, bool) or not isinstance(seed, int) or not 0 <= seed < 2**63:
        raise WorldConfigError(f"{where}.seed: expected an integer in [0, 2^63), got {seed!r}")
    return WindConfig(
        mean_ned_m_s=mean,  # type: ignore[arg-type]
        gust_m_s=_num(where, "gust_m_s", s.get("gust_m_s", 0.0), 0.0, 30.0),
        seed=seed,
        gust_time_constant_s=_num(where, "gust_time_constant_s", s.get("gust_time_constant_s", 2.0), 0.05, 600.0),
    )


def _home(spec: Any) -> GeoPoint:
    s = _fields("home", spec, {"lat_deg", "lon_deg"}, {"alt_m"})
    return GeoPoint(
        _num("home", "lat_deg", s["lat_deg"], -90.0, 90.0),
        _num("home", "lon_deg", s["lon_deg"], -180.0, 180.0),
        _num("home", "alt_m", s.get("alt_m", 0.0), -500.0, 9000.0),
    )


def load_world(source: str | Path | dict) -> World:
    """The world of a mission YAML (path, YAML text or parsed dict); ``mission:``/``fence:`` are ignored.

    Accepts either a whole mission document (``home``, ``world: {obstacles, wind, payload_kg, failures}``) or
    a bare world mapping (``obstacles``, ``wind``, ``payload_kg``, ``failures``, optional ``home``).
    """
    if isinstance(source, dict):
        doc = source
    else:
        looks_like_yaml = isinstance(source, str) and ("\n" in source or source.lstrip().startswith("{"))
        if not looks_like_yaml and not Path(source).is_file():
            raise WorldConfigError(f"world: no such file {str(source)!r}; fix: check the path given to --world")
        if looks_like_yaml:
            try:
                doc = yaml.safe_load(str(source))
            except yaml.YAMLError as exc:
                raise WorldConfigError(f"not valid YAML ({exc})") from exc
        else:
            try:
                parsed = read_yaml(source)
            except YamlSyntaxError as exc:
                raise WorldConfigError(str(exc)) from None
            try:
                return _world_of(parsed.data)
            except WorldConfigError as exc:  # name the file and line: FILE:LINE: world.obstacles[2]...: ...
                node = _node_path(str(exc))
                if node[:1] == ("world",) and not (isinstance(parsed.data, dict) and "world" in parsed.data):
                    node = node[1:]  # a bare world mapping
                raise WorldConfigError(f"{parsed.where(*node)}: {exc}") from None
    return _world_of(doc)


def _node_path(message: str) -> tuple[str | int, ...]:
    """The YAML path of the ``world.obstacles[2].box.size_m[1]: ...`` a message starts with."""
    head = message.split(": ", 1)[0].split()[0]
    return tuple(int(p[1:-1]) if p.startswith("[") else p for p in re.findall(r"\[\d+\]|[A-Za-z_]+", head))


def _world_of(doc: Any) -> World:
    """The world of a parsed mission or bare world mapping (WorldConfigError naming the field)."""
    if not isinstance(doc, dict):
        raise WorldConfigError(f"expected a mapping (mission or world), got {type(doc).__name__}")
    home = _home(doc["home"]) if "home" in doc else DEFAULT_HOME
    world_keys = {"obstacles", "wind", "payload_kg", "home", "failures"}
    # a mission with a world, a bare world mapping, or a mission without a world
    bare = doc if set(doc) <= world_keys else {}
    world_spec = (doc["world"] or {}) if "world" in doc else bare
    w = _fields("world", world_spec, set(), world_keys)
    obstacles_spec = w.get("obstacles") or []
    if not isinstance(obstacles_spec, list):
        raise WorldConfigError(f"world.obstacles: expected a list, got {obstacles_spec!r}")
    return World(
        home=home,
        obstacles=tuple(_obstacle(i, e) for i, e in enumerate(obstacles_spec)),
        wind=_wind(w.get("wind") or {}),
        payload_kg=_num("world", "payload_kg", w.get("payload_kg", 0.0), 0.0, 50.0),
        failures=_failures(w.get("failures")),
    )


def _failures(spec: Any) -> tuple[ScheduledFailure, ...]:
    try:
        return parse_failures(spec)
    except FailureScheduleError as exc:
        raise WorldConfigError(str(exc)) from None
