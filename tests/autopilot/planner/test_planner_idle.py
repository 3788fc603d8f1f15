"""``AvoidancePlanner.idle_output`` (the runner's shortcut with nothing to avoid) equals what ``update`` returns.

Through a whole encounter: idle before the obstacle is seen, None while it is tracked or a detour is
flown, idle again once the obstacle is forgotten and the detour ended; and CA_ENABLE = 0.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from autopilot.planner.param_decls import PlannerParams
from autopilot.planner.planner import AvoidancePlanner, PlannerState
from mavlink_bridge.contract.frames import quat_from_euler
from mavlink_bridge.contract.wire import ObstacleDetection, ObstacleShape

Q_NORTH = quat_from_euler(0.0, 0.0, 0.0)
TARGET = (80.0, 0.0, -10.0)
NEXT = np.array([[80.0, 30.0, -10.0]])


def _detection(time_us: int, pos: np.ndarray, center: np.ndarray, r: float) -> ObstacleDetection:
    rel = center - pos
    surface = rel - r * rel / np.linalg.norm(rel)
    return ObstacleDetection(time_us, 1, tuple(float(x) for x in surface), r, ObstacleShape.SPHERE)  # type: ignore[arg-type]


def _fly(planner: AvoidancePlanner, seen_us: tuple[int, int], end_us: int) -> tuple[int, int]:
    """Fly north at 5 m/s (tracking the detour once there is one); count steps where idle_output answered."""
    pos, vel = np.array([0.0, 0.0, -10.0]), np.array([5.0, 0.0, 0.0])
    center = np.array([20.0, 0.3, -10.0])
    idle_steps = busy_steps = 0
    for time_us in range(0, end_us, 20_000):
        detections = (_detection(time_us, pos, center, 2.0),) if seen_us[0] <= time_us <= seen_us[1] else ()
        idle = planner.idle_output(time_us, detections)
        out = planner.update(time_us, pos, vel, Q_NORTH, detections, TARGET, NEXT)
        if idle is not None:
            assert idle == out
            idle_steps += 1
        else:
            busy_steps += 1
        if out.setpoint is not None:
            pos, vel = np.array(out.setpoint.pos_ned_m), np.array(out.setpoint.vel_ned_m_s)
        else:
            pos = pos + vel * 0.02
    return idle_steps, busy_steps


def test_idle_output_equals_update_through_an_encounter() -> None:
    params = PlannerParams()
    planner = AvoidancePlanner(params)
    end_us = 2_000_000 + round(params.forget_s * 1e6) + 8_000_000
    idle_steps, busy_steps = _fly(planner, (1_000_000, 2_000_000), end_us)
    assert planner.state is PlannerState.CLEAR
    assert idle_steps > 0 and busy_steps > 0
    assert planner.idle_output(10**10, ()) is not None  # forgotten, detour over, rejoin consumed or dropped


def test_idle_output_with_avoidance_disabled() -> None:
    planner = AvoidancePlanner(replace(PlannerParams(), enable=False))
    idle_steps, busy_steps = _fly(planner, (1_000_000, 2_000_000), 3_000_000)
    assert planner.state is PlannerState.DISABLED
    assert idle_steps > 0 and busy_steps > 0
