"""Small path and volume shapes the planner builds: a braking curve, path samples, merged obstacle volumes."""

from __future__ import annotations

import math

import numpy as np

from .bezier import BezierPath, bernstein_matrix
from .obstacle_map import ObstacleKind, TrackedObstacle

#: Spacing of the samples a path is checked at (m).
SAMPLE_STEP_M = 0.4


def enclosing_volume(a: TrackedObstacle, b: TrackedObstacle) -> TrackedObstacle:
    """The smallest sphere (or, if either is a column, vertical column) enclosing two obstacles; keeps a's id."""
    column = ObstacleKind.COLUMN in (a.kind, b.kind)
    ca, cb = a.center_ned, b.center_ned
    if column:
        cb = (cb[0], cb[1], ca[2])
    d = math.dist(ca, cb)
    if d + b.radius_m <= a.radius_m:
        c, r = ca, a.radius_m
    elif d + a.radius_m <= b.radius_m:
        c, r = cb, b.radius_m
    else:
        r = 0.5 * (d + a.radius_m + b.radius_m)
        f = (r - a.radius_m) / d
        c = (ca[0] + (cb[0] - ca[0]) * f, ca[1] + (cb[1] - ca[1]) * f, ca[2] + (cb[2] - ca[2]) * f)
    kind = ObstacleKind.COLUMN if column else ObstacleKind.SPHERE
    return TrackedObstacle(a.obstacle_id, kind, c, r, a.first_seen_us, a.last_seen_us, a.detections)


def brake_path(pos_ned: np.ndarray, vel_ned: np.ndarray, a_max_m_s2: float) -> BezierPath:
    """Straight constant deceleration to a hover (cubic Hermite with end velocity 0, |a| = |v|/T)."""
    pos = np.asarray(pos_ned, float)
    vel = np.asarray(vel_ned, float)
    speed = float(np.linalg.norm(vel))
    duration = max(speed / a_max_m_s2, 0.05)
    stop = pos + vel * duration / 2.0
    ctrl = np.stack((pos, pos + vel * duration / 3.0, stop, stop))[None]
    ctrl.setflags(write=False)
    durations = np.array((duration,))
    durations.setflags(write=False)
    return BezierPath(ctrl, durations, speed, speed / duration, True)


def sample_path(path: BezierPath) -> np.ndarray:
    """Samples of a path at the planner's checking step (for telemetry and checks)."""
    n = max(2, math.ceil(path.v_bound_m_s * float(path.durations_s.max()) / SAMPLE_STEP_M))
    basis = bernstein_matrix(3, np.linspace(0.0, 1.0, n + 1))
    return np.einsum("mj,kjd->kmd", basis, path.ctrl_ned).reshape(-1, 3)
