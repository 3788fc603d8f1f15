"""Geofence zones from FENCE mission items, in local NED, with the checks the planner reuses (SPEC §7, §8).

Zones are vertical prisms (horizontal shape, any altitude). MAVLink semantics
(MAV_CMD_NAV_FENCE_*): the vehicle must stay outside every exclusion zone and, when
inclusion zones exist, inside *all* inclusion zones of at least one inclusion group
(param2 of inclusion items). A polygon is ``param1`` consecutive vertex items of the
same command. Polygons are assumed simple (not self-intersecting).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from mavlink_bridge.contract.frames import GeoPoint, LocalNedFrame
from mavlink_bridge.contract.mav_enums import FENCE_COMMANDS, GLOBAL_FRAMES, MavCmd, MavFrame, command_name
from mavlink_bridge.contract.vehicle_api import MissionItem, MissionType

Vec2 = tuple[float, float]


class FenceError(ValueError):
    """A FENCE item list that does not describe valid zones; ``item_index`` names the culprit."""

    def __init__(self, item_index: int, message: str, field: str = "") -> None:
        super().__init__(f"fence item {item_index}: {message}")
        self.item_index = item_index
        self.field = field
        self.message = message


def _point_segment_distance(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Distance from point(s) ``p`` to segments ``a``-``b`` (2D, broadcast on leading axes)."""
    ab = b - a
    denom = np.einsum("...i,...i->...", ab, ab)
    t = np.einsum("...i,...i->...", p - a, ab) / np.where(denom > 0.0, denom, 1.0)
    t = np.clip(t, 0.0, 1.0)
    closest = a + t[..., None] * ab
    return np.linalg.norm(p - closest, axis=-1)


def _cross(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    return u[..., 0] * v[..., 1] - u[..., 1] * v[..., 0]


def segment_to_segments_distance(a: np.ndarray, b: np.ndarray, starts: np.ndarray, ends: np.ndarray) -> np.ndarray:
    """Minimum 2D distance between segment ``a``-``b`` and each segment ``starts[i]``-``ends[i]`` (0 if crossing)."""
    d = np.minimum(
        np.minimum(_point_segment_distance(a, starts, ends), _point_segment_distance(b, starts, ends)),
        np.minimum(_point_segment_distance(starts, a, b), _point_segment_distance(ends, a, b)),
    )
    r, s = b - a, ends - starts
    qp = starts - a
    rxs = _cross(np.broadcast_to(r, s.shape), s)
    safe = np.where(rxs != 0.0, rxs, 1.0)
    t = _cross(qp, s) / safe
    u = _cross(qp, np.broadcast_to(r, s.shape)) / safe
    crossing = (rxs != 0.0) & (t >= 0.0) & (t <= 1.0) & (u >= 0.0) & (u <= 1.0)
    return np.where(crossing, 0.0, d)


def _polyline_gap(points: np.ndarray, starts: np.ndarray, ends: np.ndarray, distance: bool = True) -> float:
    """Smallest 2D distance between the segments of a polyline ``points`` (n, 2) and the edges ``starts``-``ends``
    (k, 2); 0 when any two cross. ``distance`` False: only whether they cross (0, else inf)."""
    a, b = points[:-1, None, :], points[1:, None, :]  # (m, 1, 2)
    c, d = starts[None, :, :], ends[None, :, :]  # (1, k, 2)
    r, q = b - a, d - c
    rxs = r[..., 0] * q[..., 1] - r[..., 1] * q[..., 0]
    safe = np.where(rxs != 0.0, rxs, 1.0)
    w = c - a
    t = (w[..., 0] * q[..., 1] - w[..., 1] * q[..., 0]) / safe
    u = (w[..., 0] * r[..., 1] - w[..., 1] * r[..., 0]) / safe
    crossing = (rxs != 0.0) & (t >= 0.0) & (t <= 1.0) & (u >= 0.0) & (u <= 1.0)
    if bool(crossing.any()):
        return 0.0
    if not distance:
        return math.inf
    gap = np.minimum(
        np.minimum(_point_segment_distance(a, c, d), _point_segment_distance(b, c, d)),
        np.minimum(_point_segment_distance(c, a, b), _point_segment_distance(d, a, b)),
    )
    return float(gap.min())


def _points_inside(points: np.ndarray, vertices: np.ndarray) -> np.ndarray:
    """Even-odd test of points (n, 2) against a polygon's vertices (k, 2)."""
    x, y = points[:, 0][:, None], points[:, 1][:, None]
    xi, yi = vertices[:, 0][None, :], vertices[:, 1][None, :]
    xj, yj = np.roll(vertices[:, 0], 1)[None, :], np.roll(vertices[:, 1], 1)[None, :]
    with np.errstate(divide="ignore", invalid="ignore"):
        hit = ((yi > y) != (yj > y)) & (x < (xj - xi) * (y - yi) / (yj - yi) + xi)
    return (np.count_nonzero(hit, axis=1) % 2) == 1


@dataclass(frozen=True, slots=True)
class CircleZone:
    """A circular zone centred at ``center_ne_m`` (north, east, m) of ``radius_m``."""

    center_ne_m: Vec2
    radius_m: float
    inclusion: bool
    group: int = 0

    def contains(self, pos_ned: Sequence[float]) -> bool:
        """True when the horizontal position is inside the circle (boundary included)."""
        return math.hypot(pos_ned[0] - self.center_ne_m[0], pos_ned[1] - self.center_ne_m[1]) <= self.radius_m

    def boundary_distance_m(self, pos_ned: Sequence[float]) -> float:
        """Horizontal distance to the circle's boundary."""
        d = math.hypot(pos_ned[0] - self.center_ne_m[0], pos_ned[1] - self.center_ne_m[1])
        return abs(d - self.radius_m)

    def allowed_distance_m(self, pos_ned: Sequence[float]) -> float:
        """How far (m) the horizontal position is on the allowed side of the circle (inside an inclusion, outside an
        exclusion); negative on the wrong side."""
        inside_m = self.radius_m - math.hypot(pos_ned[0] - self.center_ne_m[0], pos_ned[1] - self.center_ne_m[1])
        return inside_m if self.inclusion else -inside_m

    def segment_clear(self, a_ned: Sequence[float], b_ned: Sequence[float], margin_m: float = 0.0) -> bool:
        """Exclusion: the segment stays more than ``margin_m`` outside. Inclusion: it stays ``margin_m`` inside."""
        c = np.asarray(self.center_ne_m)
        a, b = np.asarray(a_ned[:2], dtype=float), np.asarray(b_ned[:2], dtype=float)
        if self.inclusion:
            limit = self.radius_m - margin_m
            return bool(np.linalg.norm(a - c) <= limit and np.linalg.norm(b - c) <= limit)
        return bool(_point_segment_distance(c, a, b) > self.radius_m + margin_m)

    def path_clear(self, points_ne: np.ndarray, margin_m: float = 0.0) -> bool:
        """:meth:`segment_clear` for every segment of a polyline (n, 2), vectorised."""
        c = np.asarray(self.center_ne_m)
        if self.inclusion:
            return bool(np.all(np.linalg.norm(points_ne - c, axis=1) <= self.radius_m - margin_m))
        if len(points_ne) < 2:
            return bool(np.all(np.linalg.norm(points_ne - c, axis=1) > self.radius_m + margin_m))
        reach = self.radius_m + margin_m  # the path's bounding box out of reach: clear at once
        lo, hi = points_ne.min(axis=0), points_ne.max(axis=0)
        if np.any(lo > c + reach) or np.any(hi < c - reach):
            return True
        return bool(np.all(_point_segment_distance(c, points_ne[:-1], points_ne[1:]) > self.radius_m + margin_m))


@dataclass(frozen=True, slots=True)
class PolygonZone:
    """A polygonal zone; ``vertices_ne_m`` are (north, east) in metres, in order, not closed."""

    vertices_ne_m: tuple[Vec2, ...]
    inclusion: bool
    group: int = 0
    _box: tuple[float, float, float, float] = field(init=False, repr=False, compare=False)  # n/e min, max
    #: The edges' start and end points (n, 2), built once: the failsafe's fence check runs every control step.
    _edge_points: tuple[np.ndarray, np.ndarray] = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        ns = [v[0] for v in self.vertices_ne_m]
        es = [v[1] for v in self.vertices_ne_m]
        object.__setattr__(self, "_box", (min(ns), min(es), max(ns), max(es)) if ns else (0.0, 0.0, 0.0, 0.0))
        v = np.asarray(self.vertices_ne_m, dtype=float).reshape(-1, 2)
        object.__setattr__(self, "_edge_points", (v, np.roll(v, -1, axis=0)))

    def _edges(self) -> tuple[np.ndarray, np.ndarray]:
        return self._edge_points

    def contains(self, pos_ned: Sequence[float]) -> bool:
        """Even-odd ray casting on the horizontal position."""
        x, y = float(pos_ned[0]), float(pos_ned[1])
        inside = False
        verts = self.vertices_ne_m
        j = len(verts) - 1
        for i in range(len(verts)):
            xi, yi = verts[i]
            xj, yj = verts[j]
            if (yi > y) != (yj > y) and x < (xj - xi) * (y - yi) / (yj - yi) + xi:
                inside = not inside
            j = i
        return inside

    def boundary_distance_m(self, pos_ned: Sequence[float]) -> float:
        """Horizontal distance to the nearest edge."""
        starts, ends = self._edges()
        return float(np.min(_point_segment_distance(np.asarray(pos_ned[:2], dtype=float), starts, ends)))

    def allowed_distance_m(self, pos_ned: Sequence[float]) -> float:
        """How far (m) the horizontal position is on the allowed side of the edge (inside an inclusion, outside an
        exclusion); negative on the wrong side."""
        d = self.boundary_distance_m(pos_ned)
        return d if self.contains(pos_ned) == self.inclusion else -d

    def segment_clear(self, a_ned: Sequence[float], b_ned: Sequence[float], margin_m: float = 0.0) -> bool:
        """Exclusion: the segment stays more than ``margin_m`` outside. Inclusion: it stays ``margin_m`` inside."""
        a, b = np.asarray(a_ned[:2], dtype=float), np.asarray(b_ned[:2], dtype=float)
        starts, ends = self._edges()
        gap = float(np.min(segment_to_segments_distance(a, b, starts, ends)))
        if gap <= 0.0 or gap < margin_m:
            return False
        inside_a, inside_b = self.contains(a_ned), self.contains(b_ned)
        return (inside_a and inside_b) if self.inclusion else not (inside_a or inside_b)

    def path_clear(self, points_ne: np.ndarray, margin_m: float = 0.0) -> bool:
        """:meth:`segment_clear` for every segment of a polyline (n >= 2, 2), vectorised; an exclusion zone whose
        bounding box (grown by the margin) misses the path's is clear at once."""
        if not self.inclusion:
            lo, hi = points_ne.min(axis=0), points_ne.max(axis=0)
            n0, e0, n1, e1 = self._box
            m = margin_m + 1e-9
            if lo[0] > n1 + m or hi[0] < n0 - m or lo[1] > e1 + m or hi[1] < e0 - m:
                return True
        starts, ends = self._edges()
        gap = _polyline_gap(points_ne, starts, ends, distance=margin_m > 0.0)
        if gap <= 0.0 or gap < margin_m:
            return False
        inside = _points_inside(points_ne, starts)
        return bool(inside.all()) if self.inclusion else not bool(inside.any())


FenceZone = CircleZone | PolygonZone


@dataclass(frozen=True, slots=True)
class Geofence:
    """All zones of one FENCE mission. Empty means "no fence": nothing is ever violated."""

    zones: tuple[FenceZone, ...] = ()

    @property
    def exclusions(self) -> tuple[FenceZone, ...]:
        return tuple(z for z in self.zones if not z.inclusion)

    def _inclusion_groups(self) -> list[list[FenceZone]]:
        groups: dict[int, list[FenceZone]] = {}
        for z in self.zones:
            if z.inclusion:
                groups.setdefault(z.group, []).append(z)
        return list(groups.values())

    def violates(self, pos_ned: Sequence[float], margin_m: float = 0.0) -> bool:
        """True when the position is inside (or within ``margin_m`` of) an exclusion zone, or outside
        (or within ``margin_m`` of the edge of) every inclusion group."""
        for z in self.exclusions:
            if z.contains(pos_ned) or z.boundary_distance_m(pos_ned) < margin_m:
                return True
        groups = self._inclusion_groups()
        if not groups:
            return False
        return not any(
            all(z.contains(pos_ned) and z.boundary_distance_m(pos_ned) >= margin_m for z in g) for g in groups
        )

    def segment_clear(self, a_ned: Sequence[float], b_ned: Sequence[float], margin_m: float = 0.0) -> bool:
        """True when the straight segment a→b keeps ``margin_m`` from every exclusion zone and stays
        ``margin_m`` inside all zones of some inclusion group (when there are any)."""
        if not all(z.segment_clear(a_ned, b_ned, margin_m) for z in self.exclusions):
            return False
        groups = self._inclusion_groups()
        return not groups or any(all(z.segment_clear(a_ned, b_ned, margin_m) for z in g) for g in groups)

    def path_clear(self, points_ned: np.ndarray, margin_m: float = 0.0) -> bool:
        """:meth:`segment_clear` for every segment of a sampled path (n >= 2, 2 or 3), vectorised per zone."""
        pts = np.ascontiguousarray(np.asarray(points_ned, dtype=float)[:, :2])
        if len(pts) < 2:
            return len(pts) == 0 or not self.violates(pts[0], margin_m)
        if not all(z.path_clear(pts, margin_m) for z in self.exclusions):
            return False
        groups = self._inclusion_groups()
        return not groups or any(all(z.path_clear(pts, margin_m) for z in g) for g in groups)


def _check_latlon(index: int, item: MissionItem) -> None:
    lat, lon = item.x_lat_deg, item.y_lon_deg
    if not (math.isfinite(lat) and -90.0 <= lat <= 90.0):
        raise FenceError(index, f"latitude {lat} outside [-90, 90]", "x_lat_deg")
    if not (math.isfinite(lon) and -180.0 <= lon <= 180.0):
        raise FenceError(index, f"longitude {lon} outside [-180, 180]", "y_lon_deg")


@dataclass(frozen=True, slots=True)
class GeoZone:
    """One zone as uploaded (geodetic): a circle (``radius_m`` > 0, one vertex = the centre) or a polygon.

    ``first_item`` is the index of its first FENCE item (for messages naming the item)."""

    vertices_lat_lon_deg: tuple[tuple[float, float], ...]
    radius_m: float  # 0 for a polygon
    inclusion: bool
    group: int
    first_item: int

    def to_local(self, frame: LocalNedFrame, alt_amsl_m: float) -> FenceZone:
        """The zone in local NED about ``frame``'s origin (horizontal only)."""
        pts: list[Vec2] = []
        for lat, lon in self.vertices_lat_lon_deg:
            n, e, _ = frame.ned_from_geodetic(lat, lon, alt_amsl_m)
            pts.append((n, e))
        if self.radius_m > 0.0:
            return CircleZone(pts[0], self.radius_m, self.inclusion, self.group)
        return PolygonZone(tuple(pts), self.inclusion, self.group)


@dataclass(frozen=True, slots=True)
class GeoFence:
    """A FENCE upload stored geodetically (SPEC §7): accepted before home is known, made local once it is."""

    zones: tuple[GeoZone, ...] = ()

    def to_local(self, home: GeoPoint) -> Geofence:
        """The zones about ``home`` (north, east in metres)."""
        frame = LocalNedFrame(home)
        return Geofence(tuple(z.to_local(frame, home.alt_amsl_m) for z in self.zones))


def geo_fence_from_items(items: Sequence[MissionItem]) -> GeoFence:
    """Parse FENCE items into geodetic zones (no home needed). Raises :class:`FenceError` naming the item."""
    zones: list[GeoZone] = []
    i = 0
    while i < len(items):
        item = items[i]
        if item.command not in FENCE_COMMANDS:
            raise FenceError(i, f"command {command_name(item.command)} is not a fence item", "command")
        if item.frame not in GLOBAL_FRAMES:
            raise FenceError(i, f"frame {item.frame} unsupported (use a global frame: 0, 3, 5 or 6)", "frame")
        _check_latlon(i, item)
        if item.command in (MavCmd.NAV_FENCE_CIRCLE_INCLUSION, MavCmd.NAV_FENCE_CIRCLE_EXCLUSION):
            radius = item.param1
            if not (math.isfinite(radius) and radius > 0.0):
                raise FenceError(i, f"circle radius (param1) {radius} must be > 0 m", "param1")
            inclusion = item.command == MavCmd.NAV_FENCE_CIRCLE_INCLUSION
            group = _group(i, item) if inclusion else 0
            zones.append(GeoZone(((item.x_lat_deg, item.y_lon_deg),), float(radius), inclusion, group, i))
            i += 1
            continue
        count = item.param1
        if not (math.isfinite(count) and count == int(count) and count >= 3):
            raise FenceError(i, f"polygon vertex count (param1) {count} must be an integer >= 3", "param1")
        count = int(count)
        if i + count > len(items):
            raise FenceError(i, f"polygon declares {count} vertices but only {len(items) - i} items follow")
        verts: list[tuple[float, float]] = []
        for k in range(i, i + count):
            v = items[k]
            if v.command != item.command or v.param1 != item.param1:
                raise FenceError(
                    k,
                    f"polygon vertex {k - i + 1} of {count}: expected {command_name(item.command)} "
                    f"with vertex count {count}, got {command_name(v.command)} count {v.param1}",
                )
            _check_latlon(k, v)
            verts.append((v.x_lat_deg, v.y_lon_deg))
        inclusion = item.command == MavCmd.NAV_FENCE_POLYGON_VERTEX_INCLUSION
        zones.append(GeoZone(tuple(verts), 0.0, inclusion, _group(i, item) if inclusion else 0, i))
        i += count
    return GeoFence(tuple(zones))


def _group(index: int, item: MissionItem) -> int:
    group = item.param2
    if not (math.isfinite(group) and group == int(group) and 0 <= group <= 255):
        raise FenceError(index, f"inclusion group (param2) {group} must be an integer in [0, 255]", "param2")
    return int(group)


def geofence_from_items(items: Sequence[MissionItem], home: GeoPoint) -> Geofence:
    """Parse FENCE items into zones about ``home``. Raises :class:`FenceError` naming the item."""
    return geo_fence_from_items(items).to_local(home)


def zone_label(zone: FenceZone, index: int) -> str:
    """e.g. ``exclusion circle 2 (r 8 m at 60 N 10 E)`` for messages (``index`` counts zones from 1)."""
    kind = ("inclusion " if zone.inclusion else "exclusion ") + (
        "circle" if isinstance(zone, CircleZone) else "polygon"
    )
    if isinstance(zone, CircleZone):
        n, e = zone.center_ne_m
        return f"{kind} {index} (r {zone.radius_m:.0f} m at {n:.0f} N {e:.0f} E)"
    return f"{kind} {index} ({len(zone.vertices_ne_m)} vertices)"


def circle_fence_items(
    seq: int, lat_deg: float, lon_deg: float, radius_m: float, *, inclusion: bool, group: int = 0
) -> list[MissionItem]:
    """The one FENCE item of a circle zone."""
    cmd = MavCmd.NAV_FENCE_CIRCLE_INCLUSION if inclusion else MavCmd.NAV_FENCE_CIRCLE_EXCLUSION
    return [
        MissionItem(
            seq=seq,
            command=int(cmd),
            frame=int(MavFrame.GLOBAL),
            param1=float(radius_m),
            param2=float(group) if inclusion else 0.0,
            x_lat_deg=float(lat_deg),
            y_lon_deg=float(lon_deg),
            mission_type=MissionType.FENCE,
        )
    ]


def polygon_fence_items(
    seq: int, vertices_lat_lon_deg: Sequence[tuple[float, float]], *, inclusion: bool, group: int = 0
) -> list[MissionItem]:
    """The vertex FENCE items of a polygon zone, starting at ``seq``."""
    cmd = MavCmd.NAV_FENCE_POLYGON_VERTEX_INCLUSION if inclusion else MavCmd.NAV_FENCE_POLYGON_VERTEX_EXCLUSION
    count = float(len(vertices_lat_lon_deg))
    return [
        MissionItem(
            seq=seq + k,
            command=int(cmd),
            frame=int(MavFrame.GLOBAL),
            param1=count,
            param2=float(group) if inclusion else 0.0,
            x_lat_deg=float(lat),
            y_lon_deg=float(lon),
            mission_type=MissionType.FENCE,
        )
        for k, (lat, lon) in enumerate(vertices_lat_lon_deg)
    ]
