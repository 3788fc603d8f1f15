"""HOLD (AUTO_LOITER): hold a point, PX4's ``FlightTaskAutoLineSmoothVel`` loiter.

The hold point is also what the other tasks leave behind: takeoff climbs to it, a stick stop and a touchdown
hold where the vehicle is, an RTL climb holds its column, DO_REPOSITION moves it.
"""

from __future__ import annotations

import math

from autopilot.estimation import VehicleState
from autopilot.flight_tasks.setpoints import NavTarget, TargetKind
from mavlink_bridge.contract.wire import Vec3


class HoldTask:
    """The hold point (local NED about the origin) and yaw (NaN: keep the heading)."""

    def __init__(self) -> None:
        self.pos_ned_m: Vec3 = (0.0, 0.0, 0.0)
        self.yaw_rad = math.nan
        self._key: tuple[object, ...] = ()
        self._target = NavTarget(TargetKind.IDLE)

    def hold_here(self, state: VehicleState, acc_hor_m_s2: float) -> None:
        """Hold where the vehicle can stop: its position plus the braking distance at ``acc_hor_m_s2``."""
        vn, ve, _ = state.vel_ned_m_s
        speed = math.hypot(vn, ve)
        k = speed / (2.0 * acc_hor_m_s2)
        n, e, d = state.pos_ned_m
        self.pos_ned_m = (n + vn * k, e + ve * k, d)
        self.yaw_rad = math.nan

    def target(self, speeds: tuple[float, float, float]) -> NavTarget:
        """The hold target; the same object every step while the point, the yaw and ``speeds`` stay."""
        key = (self.pos_ned_m, self.yaw_rad, *speeds)
        if key != self._key:
            self._key = key
            self._target = NavTarget(TargetKind.POSITION, *key)
        return self._target
