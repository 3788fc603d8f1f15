"""POSCTL from a joystick (MANUAL_CONTROL): the sticks ask for a velocity about the heading; centred, the vehicle
holds (PX4's position mode in spirit).

Each axis loses a deadzone of ``MPC_HOLD_DZ`` around centre and the rest is rescaled to 0..1. The pitch and
roll sticks ask for a horizontal velocity forward/right of the current heading, at most ``MPC_VEL_MANUAL``
(capped by ``MPC_XY_VEL_MAX``) at full deflection of both together; throttle above/below centre climbs/descends
at up to ``MPC_Z_VEL_MAX_UP``/``MPC_Z_VEL_MAX_DN``; the yaw stick turns at up to ``MPC_YAWRAUTO_MAX``. The
commander flies the demand as a VELOCITY target, and holds where the vehicle can stop once every stick is
centred or the input is older than ``COM_RC_LOSS_T`` (wall clock, like the other GCS-link timeouts). On the
ground, throttle above centre (a climb of at least 0.3 m/s) takes off; held down, the vehicle lands and
disarms like any landing.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

from autopilot.estimation import VehicleState
from autopilot.flight_tasks.hold import HoldTask
from autopilot.flight_tasks.setpoints import NavTarget
from autopilot.flight_tasks.targets import velocity_target
from autopilot.parameters.store import ParamStore
from mavlink_bridge.contract.frames import ne_from_heading_frame
from mavlink_bridge.contract.vehicle_api import ManualInput
from mavlink_bridge.contract.wire import Vec3

#: After the sticks let go, the vehicle holds where it is once slower than this on each axis (m/s) ...
_STICK_STOPPED_M_S = 0.2
#: ... or after braking this long (sim µs), whichever comes first.
_STICK_BRAKE_MAX_US = 5_000_000


@dataclass(frozen=True, slots=True)
class StickDemand:
    """What the sticks ask for: a velocity (NED), its speed limits and a yaw rate (clockwise +)."""

    vel_ned_m_s: Vec3
    yaw_rate_rad_s: float
    speed_xy_m_s: float
    speed_up_m_s: float
    speed_down_m_s: float


def deadzone(value: float, width: float) -> float:
    """``value`` in [-1, 1] without a centre band of +-``width``, the rest rescaled to [-1, 1]."""
    magnitude = abs(value)
    if magnitude <= width:
        return 0.0
    return math.copysign(min(1.0, (magnitude - width) / (1.0 - width)), value)


def stick_demand(sticks: ManualInput, yaw_rad: float, params: ParamStore) -> StickDemand | None:
    """The velocity and yaw rate the sticks ask for at heading ``yaw_rad``; None when every stick is centred."""
    p = params.get
    dz = p("MPC_HOLD_DZ")
    forward, right = deadzone(sticks.forward, dz), deadzone(sticks.right, dz)
    climb, turn = deadzone(2.0 * sticks.throttle - 1.0, dz), deadzone(sticks.yaw, dz)
    if forward == 0.0 and right == 0.0 and climb == 0.0 and turn == 0.0:
        return None
    deflection = math.hypot(forward, right)
    if deflection > 1.0:  # both sticks full: the same top speed as one
        forward, right = forward / deflection, right / deflection
    speed_xy, up, down = min(p("MPC_VEL_MANUAL"), p("MPC_XY_VEL_MAX")), p("MPC_Z_VEL_MAX_UP"), p("MPC_Z_VEL_MAX_DN")
    north, east = ne_from_heading_frame(forward * speed_xy, right * speed_xy, yaw_rad)
    vel = (north, east, -climb * (up if climb > 0.0 else down))
    return StickDemand(vel, turn * math.radians(p("MPC_YAWRAUTO_MAX")), speed_xy, up, down)


class StickTask:
    """POSCTL (PX4's ``FlightTaskManualPosition`` in spirit): the latest joystick input flown as a velocity."""

    def __init__(self) -> None:
        self.sticks: ManualInput | None = None
        self._flying = False  # flying the sticks, or braking after them (not yet holding)
        self._brake_since_us: int | None = None

    def target(
        self,
        state: VehicleState,
        fresh: bool,
        params: ParamStore,
        speeds: Callable[[], tuple[float, float, float]],
        hold: HoldTask,
    ) -> NavTarget | None:
        """The sticks' velocity target while ``fresh``, or None to hold. When the sticks let go (centred, or stale)
        the vehicle brakes to a stop (a zero velocity target within ``speeds()``) and then holds where it stopped
        (``hold``), as PX4 does: no overshoot and return to a precomputed point."""
        demand = None
        if self.sticks is not None and fresh and state.valid:
            demand = stick_demand(self.sticks, state.yaw_rad, params)
        if demand is not None:
            self._flying = True
            self._brake_since_us = None
            limits = (demand.speed_xy_m_s, demand.speed_up_m_s, demand.speed_down_m_s)
            return velocity_target(demand.vel_ned_m_s, limits, yaw_rate_rad_s=demand.yaw_rate_rad_s)
        if not self._flying:
            return None
        if self._brake_since_us is None:
            self._brake_since_us = state.time_us
        vn, ve, vd = state.vel_ned_m_s
        slow = math.hypot(vn, ve) < _STICK_STOPPED_M_S and abs(vd) < _STICK_STOPPED_M_S
        if slow or state.time_us - self._brake_since_us >= _STICK_BRAKE_MAX_US:
            self._flying = False
            hold.pos_ned_m, hold.yaw_rad = state.pos_ned_m, math.nan
            return None
        return velocity_target((0.0, 0.0, 0.0), speeds())
