"""Forward obstacle sensor: a stereo camera fused with an ultrasonic range finder (paper §3.3, SPEC §7).

Model, per call of :meth:`ObstacleSensor.detect` (the sim calls it at ``config.rate_hz``):

- **Stereo camera** looking along body +x (FRD forward): a grid of rays over the horizontal and
  vertical field of view, sphere-traced against the true obstacles up to ``camera_range_m``; a ray
  stops at the first surface, so nearer obstacles hide farther ones (occlusion). One more ray per
  obstacle goes toward its true nearest point, so small obstacles between grid rays are not missed.
  An obstacle is *seen* when any ray hits it first.
- **What it reports** for a seen obstacle: the stereo pipeline fits an enclosing volume to the
  segmented points — the sphere itself, the cylinder itself, or for a box its circumscribed vertical
  cylinder — and reports that volume's nearest point (body FRD) and radius. Range noise grows with
  the square of the range as stereo depth does: ``σ = depth_noise_m + depth_noise_per_m2 · r²``;
  the radius gets ``radius_noise_frac`` relative noise; both seeded.
- **Ultrasonic** range along body +x in a narrow cone (``ultrasonic_half_angle_deg``), short range,
  precise: when the reported point lies in the cone and range, and the echo comes from the same
  surface (not a box: its reported volume is the circumscribed cylinder), it is fused with the
  camera range by inverse-variance weighting.

On the wire each detection is one ``OBSTACLE_DISTANCE_3D`` (``mavlink_bridge.contract.wire.ObstacleDetection``):
``frame = MAV_FRAME_BODY_FRD``, ``obstacle_id`` = index of the obstacle in the world (stable, like a
tracker id), position = the nearest point, and the radius/shape as the bridge codec documents. Chosen
over OBSTACLE_DISTANCE (a 2D ring of ranges, no elevation) and DISTANCE_SENSOR (one range) because
it carries a 3D point per obstacle, which a 3D over/under/left/right planner needs.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit

from mavlink_bridge.contract.frames import dcm_from_quat
from mavlink_bridge.contract.wire import ObstacleDetection, ObstacleShape

from .world import KIND_BOX, KIND_CYLINDER, KIND_SPHERE, OBSTACLE_PARAM_WIDTH, World, obstacle_distance_m

_HIT_EPS_M = 1e-3
#: A detection's bounding volume: centre NED (a column's top centre), radius, is a ground column, shape.
_Volume = tuple[np.ndarray, float, bool, ObstacleShape]
_MAX_MARCH_STEPS = 128


@dataclass(frozen=True, slots=True)
class ObstacleSensorConfig:
    """Stereo camera + ultrasonic parameters (angles in degrees, distances in metres)."""

    rate_hz: float = 10.0
    camera_hfov_deg: float = 90.0
    camera_vfov_deg: float = 60.0
    camera_range_m: float = 25.0
    camera_rays_h: int = 19
    camera_rays_v: int = 11
    depth_noise_m: float = 0.03
    depth_noise_per_m2: float = 0.0008  # σ at 25 m ≈ 0.53 m
    radius_noise_frac: float = 0.03
    ultrasonic_range_m: float = 6.0
    ultrasonic_half_angle_deg: float = 12.5
    ultrasonic_noise_m: float = 0.02
    max_others: int = 6  # other vehicles (a fleet's) tracked at once: the nearest in view


@njit(cache=True)
def _march(
    kinds: np.ndarray, params: np.ndarray, origin: np.ndarray, dirs: np.ndarray, max_range: float, out: np.ndarray
) -> None:
    """Sphere-trace rays ``dirs`` (m, 3) from ``origin``; ``out[i] = (range, obstacle index)`` or (inf, -1)."""
    for i in range(dirs.shape[0]):
        t = 0.0
        out[i, 0] = np.inf
        out[i, 1] = -1.0
        for _ in range(_MAX_MARCH_STEPS):
            n = origin[0] + t * dirs[i, 0]
            e = origin[1] + t * dirs[i, 1]
            d = origin[2] + t * dirs[i, 2]
            best = np.inf
            best_k = -1
            for k in range(kinds.shape[0]):
                dist = obstacle_distance_m(kinds[k], params[k], n, e, d)
                if dist < best:
                    best = dist
                    best_k = k
            if best < _HIT_EPS_M:
                out[i, 0] = t
                out[i, 1] = best_k
                break
            t += best
            if t > max_range:
                break


def _grid_dirs_frd(config: ObstacleSensorConfig) -> np.ndarray:
    az = np.radians(np.linspace(-config.camera_hfov_deg / 2, config.camera_hfov_deg / 2, config.camera_rays_h))
    el = np.radians(np.linspace(-config.camera_vfov_deg / 2, config.camera_vfov_deg / 2, config.camera_rays_v))
    a, e = np.meshgrid(az, el)
    # FRD: x forward, y right, z down; positive elevation looks up (negative z)
    return np.stack((np.cos(e) * np.cos(a), np.cos(e) * np.sin(a), -np.sin(e)), axis=-1).reshape(-1, 3)


class ObstacleSensor:
    """Seeded stereo-camera + ultrasonic obstacle sensor over a :class:`sim.world.World`."""

    def __init__(self, world: World, seed: int = 0, config: ObstacleSensorConfig | None = None) -> None:
        self.world = world
        self.config = config or ObstacleSensorConfig()
        self._rng = np.random.default_rng(seed)
        self._kinds, self._params = world.obstacle_arrays()
        self._grid_frd = _grid_dirs_frd(self.config)
        n = len(world.obstacles)
        self._hits = np.empty((len(self._grid_frd) + n, 2))
        self._dirs = np.empty((len(self._grid_frd) + n, 3))
        self._tan_h = math.tan(math.radians(self.config.camera_hfov_deg / 2))
        self._tan_v = math.tan(math.radians(self.config.camera_vfov_deg / 2))
        self._cos_us = math.cos(math.radians(self.config.ultrasonic_half_angle_deg))
        # bounding volumes: (centre NED, radius, is_column, shape)
        self._volumes: list[_Volume] = []
        for kind, p in zip(self._kinds, self._params, strict=True):
            if kind == KIND_SPHERE:
                self._volumes.append((p[:3].copy(), float(p[3]), False, ObstacleShape.SPHERE))
            elif kind == KIND_CYLINDER:
                self._volumes.append((np.array((p[0], p[1], -p[3])), float(p[2]), True, ObstacleShape.CYLINDER))
            elif kind == KIND_BOX:
                self._volumes.append(
                    (np.array((p[0], p[1], -p[6])), float(math.hypot(p[4], p[5])), True, ObstacleShape.BOX)
                )

    def _in_fov(self, v_frd: np.ndarray) -> bool:
        x = float(v_frd[0])
        return x > 1e-6 and abs(v_frd[1]) <= self._tan_h * x and abs(v_frd[2]) <= self._tan_v * x

    @staticmethod
    def _nearest_on_volume(volume: _Volume, pos: np.ndarray) -> np.ndarray:
        center, radius, column, _ = volume
        if not column:
            d = pos - center
            n = float(np.linalg.norm(d))
            return center + d * (radius / n) if n > 1e-9 else center + np.array((radius, 0.0, 0.0))
        d = np.array((pos[0] - center[0], pos[1] - center[1]))
        n = float(np.linalg.norm(d))
        h = d * (radius / n) if n > radius else d
        down = min(max(float(pos[2]), float(center[2])), 0.0)  # between the top and the ground
        return np.array((center[0] + h[0], center[1] + h[1], down))

    @staticmethod
    def _nearest_on_obstacle(kind: int, params: np.ndarray, pos: np.ndarray) -> np.ndarray:
        """True nearest surface point via the signed-distance gradient (central differences)."""
        h = 1e-4
        grad = np.empty(3)
        for i in range(3):
            dp = np.zeros(3)
            dp[i] = h
            plus = obstacle_distance_m(kind, params, *(pos + dp))
            minus = obstacle_distance_m(kind, params, *(pos - dp))
            grad[i] = (plus - minus) / (2 * h)
        dist = obstacle_distance_m(kind, params, pos[0], pos[1], pos[2])
        g = float(np.linalg.norm(grad))
        return pos - dist * grad / max(g, 1e-9)

    def _scene(
        self, pos: np.ndarray, r_ned_frd: np.ndarray, others: np.ndarray | None
    ) -> tuple[np.ndarray, np.ndarray, list[_Volume], list[int]]:
        """The world's obstacles plus those of ``others`` (rows ``north, east, down, radius, id``: other vehicles as
        spheres) that reach into the camera's range and field of view: kinds, params, volumes and report ids."""
        ids = list(range(len(self._volumes)))
        if others is None or not len(others):
            return self._kinds, self._params, self._volumes, ids
        radius = others[:, 3]
        rel_frd = (others[:, :3] - pos) @ r_ned_frd  # each row: R^T (centre - pos)
        x, y, z = rel_frd[:, 0], np.abs(rel_frd[:, 1]), np.abs(rel_frd[:, 2])
        th, tv = self._tan_h, self._tan_v
        in_view = (
            (np.linalg.norm(rel_frd, axis=1) - radius <= self.config.camera_range_m)
            & (x > -radius)
            & ((y - th * x) <= radius * math.sqrt(1.0 + th * th))  # the sphere reaches past each side plane
            & ((z - tv * x) <= radius * math.sqrt(1.0 + tv * tv))
        )
        near = others[in_view]
        if len(near) > self.config.max_others:  # the nearest ones (a stereo tracker's object slots)
            gap_m = np.linalg.norm(near[:, :3] - pos, axis=1) - near[:, 3]
            near = near[np.sort(np.argsort(gap_m, kind="stable")[: self.config.max_others])]
        if not len(near):
            return self._kinds, self._params, self._volumes, ids
        spheres = np.zeros((len(near), OBSTACLE_PARAM_WIDTH))
        spheres[:, :4] = near[:, :4]
        kinds = np.concatenate((self._kinds, np.full(len(near), KIND_SPHERE, dtype=np.int64)))
        params = np.vstack((self._params, spheres))
        volumes = self._volumes + [(row[:3].copy(), float(row[3]), False, ObstacleShape.SPHERE) for row in near]
        return kinds, params, volumes, ids + [int(i) for i in near[:, 4]]

    def detect(
        self, pos_ned: np.ndarray, q_ned_frd: np.ndarray, time_us: int, others: np.ndarray | None = None
    ) -> tuple[ObstacleDetection, ...]:
        """The obstacles seen now from ``pos_ned`` with attitude ``q_ned_frd`` (FRD detections, seeded noise).

        ``others`` (m, 5): other vehicles as spheres ``north, east, down, radius, obstacle id`` (a fleet world's
        vehicles see each other; ids after the world's obstacles)."""
        cfg = self.config
        pos = np.ascontiguousarray(pos_ned, dtype=np.float64)
        if not self._volumes and (others is None or not len(others)):
            return ()
        r_ned_frd = dcm_from_quat(np.asarray(q_ned_frd, float))
        kinds, params, volumes, ids = self._scene(pos, r_ned_frd, others)
        if not volumes:
            return ()
        n_grid = len(self._grid_frd)
        n_rays = n_grid + len(volumes)
        dirs = self._dirs if n_rays == len(self._dirs) else np.empty((n_rays, 3))
        hits = self._hits if n_rays == len(self._hits) else np.empty((n_rays, 2))
        np.matmul(self._grid_frd, r_ned_frd.T, out=dirs[:n_grid])
        # one extra ray per obstacle toward its true nearest point (when that point is in view)
        extra = np.zeros(len(volumes), bool)
        n_static = len(self._volumes)
        for k in range(len(volumes)):
            if k < n_static:
                rel = self._nearest_on_obstacle(kinds[k], params[k], pos) - pos
            else:  # another vehicle: a sphere, whose nearest point is exact
                rel = self._nearest_on_volume(volumes[k], pos) - pos
            rng = float(np.linalg.norm(rel))
            dirs[n_grid + k] = (1.0, 0.0, 0.0)
            if 1e-6 < rng <= cfg.camera_range_m and self._in_fov(r_ned_frd.T @ rel):
                dirs[n_grid + k] = rel / rng
                extra[k] = True
        if len(volumes) == n_static:
            _march(kinds, params, pos, dirs, cfg.camera_range_m, hits)
        else:  # other vehicles are seen by the ray toward each (small: the grid would rarely add one) and occlude
            _march(self._kinds, self._params, pos, dirs[:n_grid], cfg.camera_range_m, hits[:n_grid])
            _march(kinds, params, pos, dirs[n_grid:], cfg.camera_range_m, hits[n_grid:])
        seen = set(int(k) for k in hits[:n_grid, 1] if k >= 0)
        seen |= {k for k in range(len(volumes)) if extra[k] and int(hits[n_grid + k, 1]) == k}
        us_range = self._ultrasonic(kinds, params, pos, r_ned_frd)
        return tuple(self._report(volumes[k], ids[k], pos, r_ned_frd, time_us, us_range) for k in sorted(seen))

    def _ultrasonic(self, kinds: np.ndarray, params: np.ndarray, pos: np.ndarray, r_ned_frd: np.ndarray) -> float:
        """True range to the nearest surface in the ultrasonic cone (inf beyond its range)."""
        half = math.radians(self.config.ultrasonic_half_angle_deg)
        dirs_frd = [(1.0, 0.0, 0.0)] + [
            (math.cos(half), math.sin(half) * math.cos(a), math.sin(half) * math.sin(a))
            for a in np.linspace(0, 2 * math.pi, 8, endpoint=False)
        ]
        dirs = np.array(dirs_frd) @ r_ned_frd.T
        hits = np.empty((len(dirs), 2))
        _march(kinds, params, pos, dirs, self.config.ultrasonic_range_m, hits)
        return float(hits[:, 0].min())

    def _report(
        self, volume: _Volume, obstacle_id: int, pos: np.ndarray, r_ned_frd: np.ndarray, time_us: int, us_range: float
    ) -> ObstacleDetection:
        cfg = self.config
        _, radius, _, shape = volume
        rel_ned = self._nearest_on_volume(volume, pos) - pos
        rel_frd = r_ned_frd.T @ rel_ned
        rng = float(np.linalg.norm(rel_frd))
        los = rel_frd / max(rng, 1e-9)
        sigma = cfg.depth_noise_m + cfg.depth_noise_per_m2 * rng * rng
        measured = rng + float(self._rng.normal(0.0, sigma))
        fusable = shape is not ObstacleShape.BOX and abs(us_range - rng) < 3.0 * sigma + 0.1  # same surface
        if rng <= cfg.ultrasonic_range_m and los[0] >= self._cos_us and math.isfinite(us_range) and fusable:
            us = us_range + float(self._rng.normal(0.0, cfg.ultrasonic_noise_m))
            w_cam, w_us = 1.0 / sigma**2, 1.0 / cfg.ultrasonic_noise_m**2
            measured = (w_cam * measured + w_us * us) / (w_cam + w_us)
        measured = max(measured, 0.0)
        radius_est = radius * (1.0 + float(np.clip(self._rng.normal(0.0, cfg.radius_noise_frac), -0.1, 0.1)))
        p = los * measured
        return ObstacleDetection(time_us, obstacle_id, (float(p[0]), float(p[1]), float(p[2])), radius_est, shape)
