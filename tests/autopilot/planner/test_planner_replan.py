"""Planner state machine: obstacles seen while replans are rate-limited are never dropped (issue 6 follow-up).

Regression for the collision of benchmark field 12 (quick run, seed 20240611): a box first detected
0.16 s after a replan (inside ``CA_REPLAN_S``) was never checked against the active detour, and its
later detections did not count as changes, so the detour was flown into it.
"""

from __future__ import annotations

import numpy as np

from autopilot.planner.obstacle_map import ObstacleMap
from autopilot.planner.param_decls import PlannerParams
from autopilot.planner.planner import AvoidancePlanner, DecisionReason, PlannerState
from mavlink_bridge.contract.frames import quat_from_euler
from mavlink_bridge.contract.wire import ObstacleDetection, ObstacleShape

Q_NORTH = quat_from_euler(0.0, 0.0, 0.0)  # body FRD axes = NED axes
POS = np.array([0.0, 0.0, -10.0])
VEL = np.array([5.0, 0.0, 0.0])
TARGET = (80.0, 0.0, -10.0)


def _sphere_detection(time_us: int, oid: int, pos: np.ndarray, center: np.ndarray, r: float) -> ObstacleDetection:
    """What the sensor reports for a sphere: its nearest surface point relative to the vehicle, body FRD."""
    rel = center - pos
    surface = rel - r * rel / np.linalg.norm(rel)
    return ObstacleDetection(
        time_us, oid, (float(surface[0]), float(surface[1]), float(surface[2])), r, ObstacleShape.SPHERE
    )


def test_obstacle_seen_inside_the_replan_interval_is_checked_and_avoided() -> None:
    params = PlannerParams()
    planner = AvoidancePlanner(params)
    first = np.array([20.0, 0.5, -10.0])
    out = planner.update(0, POS, VEL, Q_NORTH, [_sphere_detection(0, 1, POS, first, 2.0)], TARGET)
    assert out.state is PlannerState.DETOUR and out.detour is not None
    # a second obstacle right on the detour, first seen 0.1 s later (< CA_REPLAN_S = 0.2 s)
    samples = out.detour.samples_ned
    blocker = samples[int(0.45 * len(samples))].copy()
    t_us = 100_000
    assert t_us < params.replan_s * 1e6
    decisions = []
    for k in range(6):  # keeps being detected, never grows or moves: no new "change" after the first
        time_us = t_us + k * 100_000
        pos = np.array(out.setpoint.pos_ned_m)  # the vehicle tracks the detour
        vel = np.array(out.setpoint.vel_ned_m_s)
        out = planner.update(time_us, pos, vel, Q_NORTH, [_sphere_detection(time_us, 2, pos, blocker, 1.0)], TARGET)
        decisions += out.decisions
    assert [d.reason for d in decisions] == [DecisionReason.REPLAN]
    assert decisions[0].time_us == round(params.replan_s * 1e6)  # as soon as the rate limit allows
    assert out.state is PlannerState.DETOUR and len(out.obstacles) == 2
    clearance = min(float(o.signed_distance(out.detour.samples_ned).min()) for o in out.obstacles)
    assert clearance >= params.r_safe_m


def test_slow_drift_accumulates_into_a_change() -> None:
    """A track that creeps by less than the change threshold per detection is still republished."""
    m = ObstacleMap()
    pos = np.array([0.0, 0.0, -10.0])
    seen = []
    for k in range(40):  # the reported surface creeps 5 cm per frame sideways
        det = ObstacleDetection(k, 1, (15.0, 0.05 * k, 0.0), 2.0, ObstacleShape.SPHERE)
        seen.append(m.update(k * 100_000, pos, Q_NORTH, [det]))
    assert sum(1 for s in seen if s) >= 3  # republished several times over the 2 m of drift
    assert abs(m.obstacles[0].center_ned[1] - 0.05 * 39) < 1.5  # the snapshot follows the track
