"""The obstacle map: tracked obstacles built from sensor detections (merge, track, forget).

A detection (``mavlink_bridge.contract.wire.ObstacleDetection``, OBSTACLE_DISTANCE_3D on the wire) gives
the nearest sensed surface point in body FRD and a radius estimate. The map turns it into a
volume in local NED:

- ``SPHERE`` (and ``UNKNOWN``): a sphere of that radius whose centre lies one radius behind the
  surface point along the line of sight;
- ``CYLINDER`` and ``BOX`` (world obstacles that stand on the ground, SPEC §8): a vertical
  column of that radius (the sensor reports a box's circumscribed horizontal radius), from the
  ground up with an unknown top, so the planner never plans *over* it.

Detections with the same sensor id update one track (range-weighted mean: near, precise
readings count more); a detection whose volume overlaps a track by more than ``merge_m`` is
merged into it (enclosing volume); tracks not detected for ``forget_s`` are dropped.

The published snapshot (``obstacles``) is what the planner plans against. A track is reported
*changed* (and the snapshot rebuilt) when its centre has moved more than ``CHANGE_CENTER_M`` or
its radius grown more than ``CHANGE_RADIUS_M`` since the snapshot, so slow drift accumulates into
a change instead of leaving the planner with a stale volume: the snapshot is always within those
bounds of the track.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from enum import Enum

import numpy as np

from mavlink_bridge.contract.frames import Vec3, rotate_frd_to_ned
from mavlink_bridge.contract.wire import ObstacleDetection, ObstacleShape

from .geometry import cylinder_signed_distance, sphere_signed_distance

#: A track whose centre moved this far (m) from its published snapshot is reported changed.
CHANGE_CENTER_M = 0.3
#: A track whose radius grew this much (m) beyond its published snapshot is reported changed.
CHANGE_RADIUS_M = 0.2


class ObstacleKind(Enum):
    """How the planner models an obstacle volume."""

    SPHERE = "sphere"
    COLUMN = "column"  # vertical cylinder from the ground up, top unknown


@dataclass(frozen=True, slots=True)
class TrackedObstacle:
    """One obstacle in the map (local NED). ``top_down`` is ``-inf`` for a column of unknown top."""

    obstacle_id: int
    kind: ObstacleKind
    center_ned: tuple[float, float, float]
    radius_m: float
    first_seen_us: int
    last_seen_us: int
    detections: int
    top_down: float = -math.inf

    def signed_distance(self, points_ned: np.ndarray) -> np.ndarray:
        """Signed distance (m) of points ``(n, 3)`` to the obstacle surface."""
        if self.kind is ObstacleKind.SPHERE:
            return sphere_signed_distance(points_ned, np.array(self.center_ned), self.radius_m)
        return cylinder_signed_distance(points_ned, np.array(self.center_ned[:2]), self.radius_m, self.top_down)


@dataclass(slots=True)
class _Track:
    """A track's running sums (plain floats: a handful of detections per frame, numpy costs more per call)."""

    obstacle_id: int
    kind: ObstacleKind
    center_sum: list[float]
    radius_sum: float
    weight: float
    first_seen_us: int
    last_seen_us: int
    detections: int
    published_center: Vec3  # centre and radius in the snapshot the planner sees
    published_radius: float

    @property
    def center(self) -> Vec3:
        w = self.weight
        return (self.center_sum[0] / w, self.center_sum[1] / w, self.center_sum[2] / w)

    @property
    def radius(self) -> float:
        return self.radius_sum / self.weight

    def drifted(self) -> bool:
        """Whether the track moved or grew beyond the change thresholds since it was published."""
        moved = math.dist(self.center, self.published_center) > CHANGE_CENTER_M
        return moved or self.radius > self.published_radius + CHANGE_RADIUS_M

    def frozen(self) -> TrackedObstacle:
        """The published (frozen) volume; records it as the reference for ``drifted``."""
        c = self.center
        self.published_center, self.published_radius = c, self.radius
        return TrackedObstacle(
            self.obstacle_id, self.kind, c, self.radius, self.first_seen_us, self.last_seen_us, self.detections
        )


def _kind_of(shape: ObstacleShape) -> ObstacleKind:
    return ObstacleKind.COLUMN if shape in (ObstacleShape.CYLINDER, ObstacleShape.BOX) else ObstacleKind.SPHERE


def _volume(det: ObstacleDetection, pos: Vec3, rel_ned: Vec3) -> tuple[ObstacleKind, Vec3, float, float]:
    """(kind, centre NED, radius m, range m) of a detection whose surface point is ``rel_ned`` from ``pos``."""
    rng = math.sqrt(rel_ned[0] ** 2 + rel_ned[1] ** 2 + rel_ned[2] ** 2)
    surface = (pos[0] + rel_ned[0], pos[1] + rel_ned[1], pos[2] + rel_ned[2])
    kind = _kind_of(det.shape)
    radius = max(float(det.radius_m), 0.1)
    if kind is ObstacleKind.SPHERE:
        f = radius / max(rng, 1e-6)
        return (
            kind,
            (surface[0] + f * rel_ned[0], surface[1] + f * rel_ned[1], surface[2] + f * rel_ned[2]),
            radius,
            rng,
        )
    h = math.hypot(rel_ned[0], rel_ned[1])
    if h > 1e-6:
        surface = (surface[0] + radius * rel_ned[0] / h, surface[1] + radius * rel_ned[1] / h, surface[2])
    return kind, surface, radius, rng


def detection_volumes(
    detections: Sequence[ObstacleDetection], pos_ned: Sequence[float] | np.ndarray, q_ned_frd: Sequence[float]
) -> list[tuple[ObstacleKind, Vec3, float, float]]:
    """(kind, centre NED, radius m, range m) of each of one frame's detections seen from ``pos_ned`` with attitude
    ``q_ned_frd`` (one rotation of the whole frame's surface points, body FRD -> NED)."""
    if not detections:
        return []
    frame_frd = np.array([d.pos_frd_m for d in detections], float)
    rel_ned = rotate_frd_to_ned(np.asarray(q_ned_frd, float), frame_frd).tolist()
    p = np.asarray(pos_ned, float).tolist()
    pos = (p[0], p[1], p[2])
    return [_volume(det, pos, (r[0], r[1], r[2])) for det, r in zip(detections, rel_ned, strict=True)]


class ObstacleMap:
    """Tracks obstacles from detections; feed it every sensor frame with ``update``."""

    def __init__(self, merge_m: float = 1.0, forget_s: float = 20.0) -> None:
        self.merge_m = merge_m
        self.forget_s = forget_s
        self._tracks: dict[int, _Track] = {}
        self._alias: dict[int, int] = {}  # sensor obstacle id -> track id
        self._snapshot: tuple[TrackedObstacle, ...] = ()
        self._arrays = ObstacleArrays(())

    @property
    def obstacles(self) -> tuple[TrackedObstacle, ...]:
        """The tracked obstacles (frozen snapshot, rebuilt on change)."""
        return self._snapshot

    @property
    def empty(self) -> bool:
        """No obstacle is tracked (an update without detections then changes nothing)."""
        return not self._tracks

    @property
    def arrays(self) -> ObstacleArrays:
        """The snapshot as arrays (rebuilt with it)."""
        return self._arrays

    def clear(self) -> None:
        self._tracks.clear()
        self._alias.clear()
        self._snapshot = ()
        self._arrays = ObstacleArrays(())

    def update(
        self, time_us: int, pos_ned: np.ndarray, q_ned_frd: np.ndarray, detections: Iterable[ObstacleDetection]
    ) -> set[int]:
        """Fold detections into the map and forget stale tracks; returns ids of new or changed tracks.

        A track "changes" when its centre moves more than 0.3 m or its radius grows more than 0.2 m.
        """
        changed: set[int] = set()
        detections = tuple(detections)
        for det, (kind, center, radius, rng) in zip(detections, detection_volumes(detections, pos_ned, q_ned_frd),
                                                    strict=True):  # fmt: skip
            weight = 1.0 / (1.0 + (rng / 10.0) ** 2)
            track = self._find(det.obstacle_id, kind, center, radius)
            if track is None:
                self._tracks[det.obstacle_id] = _Track(
                    det.obstacle_id,
                    kind,
                    [c * weight for c in center],
                    radius * weight,
                    weight,
                    time_us,
                    time_us,
                    1,
                    center,
                    radius,
                )
                self._alias[det.obstacle_id] = det.obstacle_id
                changed.add(det.obstacle_id)
                continue
            self._alias[det.obstacle_id] = track.obstacle_id
            if det.obstacle_id == track.obstacle_id:
                cs = track.center_sum
                cs[0] += center[0] * weight
                cs[1] += center[1] * weight
                cs[2] += center[2] * weight
                track.radius_sum += radius * weight
                track.weight += weight
            else:  # merge: grow the track to enclose both volumes
                self._enclose(track, center, radius)
            track.last_seen_us = max(track.last_seen_us, time_us)
            track.detections += 1
            if track.drifted():
                changed.add(track.obstacle_id)
        forget_us = self.forget_s * 1e6
        stale = [k for k, t in self._tracks.items() if time_us - t.last_seen_us > forget_us]
        for k in stale:
            del self._tracks[k]
        if stale:
            self._alias = {s: t for s, t in self._alias.items() if t in self._tracks}
        if changed or stale:
            self._snapshot = tuple(t.frozen() for t in self._tracks.values())
            self._arrays = ObstacleArrays(self._snapshot)
        return changed

    def forget(self, sensor_ids: Iterable[int]) -> bool:
        """Drop the tracks of these sensor ids (objects known to be something else: a tracked vehicle is traffic,
        not an obstacle); True when the snapshot changed. A volume one of them was merged into stays as grown."""
        ids = set(sensor_ids)
        gone = [k for k in ids if k in self._tracks]
        for k in gone:
            del self._tracks[k]
        self._alias = {s: t for s, t in self._alias.items() if t in self._tracks and s not in ids}
        if not gone:
            return False
        self._snapshot = tuple(t.frozen() for t in self._tracks.values())
        self._arrays = ObstacleArrays(self._snapshot)
        return True

    def _find(self, sensor_id: int, kind: ObstacleKind, center: Vec3, radius: float) -> _Track | None:
        track_id = self._alias.get(sensor_id)
        if track_id is not None and track_id in self._tracks:
            return self._tracks[track_id]
        for track in self._tracks.values():
            if track.kind is not kind:
                continue
            c = track.center
            dx, dy = center[0] - c[0], center[1] - c[1]
            gap = math.sqrt(dx * dx + dy * dy + ((center[2] - c[2]) ** 2 if kind is ObstacleKind.SPHERE else 0.0))
            if gap - radius - track.radius < -self.merge_m:
                return track
        return None

    @staticmethod
    def _enclose(track: _Track, center: Vec3, radius: float) -> None:
        c0, r0 = track.center, track.radius
        if track.kind is ObstacleKind.COLUMN:  # columns merge in the horizontal plane
            center = (center[0], center[1], c0[2])
        d = math.dist(center, c0)
        if d + radius <= r0:
            return
        if d + r0 <= radius:
            c1, r1 = center, radius
        else:
            r1 = 0.5 * (d + r0 + radius)
            f = (r1 - r0) / d
            c1 = (c0[0] + (center[0] - c0[0]) * f, c0[1] + (center[1] - c0[1]) * f, c0[2] + (center[2] - c0[2]) * f)
        track.center_sum = [c * track.weight for c in c1]
        track.radius_sum = r1 * track.weight


def row_signed_distance(row: tuple[int, float, float, float, float, bool, float], p: Vec3) -> float:
    """Signed distance of a point to one ``ObstacleArrays.rows`` volume (same as ``signed_distance``)."""
    _, cx, cy, cz, r, sphere, top = row
    h = math.hypot(p[0] - cx, p[1] - cy)
    if sphere:
        return math.hypot(h, p[2] - cz) - r
    dr, cap = h - r, top - p[2]
    if cap > 0.0:
        return math.hypot(max(dr, 0.0), cap) + min(max(dr, cap), 0.0)
    return dr


class ObstacleArrays:
    """Tracked obstacles as arrays, for signed distances of many points to all of them in one pass.

    Same volumes as :meth:`TrackedObstacle.signed_distance`: spheres ``|p − c| − r``; columns the
    exact capped-cylinder distance with ``top_down`` (``-inf``: unknown top) and no bottom (the ground).
    """

    def __init__(self, obstacles: tuple[TrackedObstacle, ...]) -> None:
        self.obstacles = obstacles
        n = len(obstacles)
        self.ids = np.array([o.obstacle_id for o in obstacles], dtype=np.int64)
        self.center = np.array([o.center_ned for o in obstacles], float).reshape(n, 3)
        self.radius = np.array([o.radius_m for o in obstacles], float)
        self.is_sphere = np.array([o.kind is ObstacleKind.SPHERE for o in obstacles], bool)
        self.top_down = np.array([o.top_down for o in obstacles], float)
        self.any_sphere = bool(self.is_sphere.any())
        self.any_column = not bool(self.is_sphere.all())
        self.any_capped = bool(np.isfinite(self.top_down[~self.is_sphere]).any())  # a column with a known top
        self._north, self._east, self._down = (
            self.center[:, 0].copy(),
            self.center[:, 1].copy(),
            self.center[:, 2].copy(),
        )
        #: The same volumes as plain tuples ``(id, north, east, down, radius, is_sphere, top_down)`` for scalar
        #: per-segment checks (numpy's per-call overhead dominates on a handful of points).
        self.rows: tuple[tuple[int, float, float, float, float, bool, float], ...] = tuple(
            (o.obstacle_id, *o.center_ned, o.radius_m, o.kind is ObstacleKind.SPHERE, o.top_down) for o in obstacles
        )

    def __len__(self) -> int:
        return len(self.obstacles)

    def nearest_distance(self, p: Vec3) -> float:
        """Smallest signed surface distance (m) of one point to any obstacle (inf when there is none)."""
        return min((row_signed_distance(row, p) for row in self.rows), default=math.inf)

    def signed_distance(self, points_ned: np.ndarray, index: list[int] | None = None) -> np.ndarray:
        """Signed surface distances (m) of points ``(m, 3)`` to every obstacle, shape ``(m, n)``; with ``index``,
        to those obstacles only, shape ``(m, len(index))``."""
        p = np.asarray(points_ned, float)
        north, east, down, radius, is_sphere = self._north, self._east, self._down, self.radius, self.is_sphere
        any_sphere, any_column, top_down = self.any_sphere, self.any_column, self.top_down
        if index is not None:
            north, east, down, radius, is_sphere = (
                north[index],
                east[index],
                down[index],
                radius[index],
                is_sphere[index],
            )
            any_sphere, any_column, top_down = bool(is_sphere.any()), not bool(is_sphere.all()), top_down[index]
        horiz = np.hypot(p[:, 0:1] - north, p[:, 1:2] - east)
        if not any_column:
            return np.hypot(horiz, p[:, 2:3] - down) - radius
        column = horiz - radius
        if self.any_capped:
            dr = column
            with np.errstate(invalid="ignore"):
                cap = top_down - p[:, 2:3]  # > 0 above the top
                column = np.where(
                    cap > 0.0, np.sqrt(np.maximum(dr, 0.0) ** 2 + cap * cap) + np.minimum(np.maximum(dr, cap), 0.0), dr
                )
        if not any_sphere:
            return column
        return np.where(is_sphere, np.hypot(horiz, p[:, 2:3] - down) - radius, column)
