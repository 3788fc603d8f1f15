"""OFFBOARD: fly the latest external position or velocity setpoint (SET_POSITION_TARGET_*, PX4's
``FlightTaskOffboard``), within the speed limits in force. Entering and leaving the mode is the commander's."""

from __future__ import annotations

from dataclasses import replace

from autopilot.estimation import VehicleState
from autopilot.flight_tasks.setpoints import NavTarget, TargetKind
from autopilot.flight_tasks.targets import velocity_target
from mavlink_bridge.contract.frames import ne_from_heading_frame
from mavlink_bridge.contract.wire import Vec3


class OffboardTask:
    """The latest setpoint as a target (None before any), and a body-frame velocity turned every step."""

    def __init__(self) -> None:
        self.setpoint: NavTarget | None = None
        self._body_vel: Vec3 | None = None

    def set_position(self, pos_ned_m: Vec3, yaw_rad: float, speeds: tuple[float, float, float]) -> None:
        self.setpoint = NavTarget(TargetKind.POSITION, pos_ned_m, yaw_rad, *speeds)
        self._body_vel = None

    def set_velocity(
        self, vel_m_s: Vec3, yaw_rad: float, yaw_rate_rad_s: float, body: bool, speeds: tuple[float, float, float]
    ) -> None:
        """A velocity setpoint (m/s, NED; with ``body`` forward/right/down about the heading).

        A body-frame velocity is turned with the heading of every control step: at ``--speed max`` a client's
        20 Hz (wall clock) stream can be several tenths of a second of sim time apart, and turned once on
        receipt (as PX4 does in real time) the course would lag a turning heading by that much.
        """
        ned = (0.0, 0.0, vel_m_s[2]) if body else vel_m_s
        self.setpoint = velocity_target(ned, speeds, yaw_rad, yaw_rate_rad_s)
        self._body_vel = vel_m_s if body else None

    def target(self, state: VehicleState) -> NavTarget | None:
        """The setpoint now (a body velocity in NED at the current heading), None before any."""
        target = self.setpoint
        if target is None or self._body_vel is None:
            return target
        forward, right, down = self._body_vel
        north, east = ne_from_heading_frame(forward, right, state.yaw_rad) if state.valid else (0.0, 0.0)
        return replace(target, vel_ned_m_s=(north, east, down))  # no heading (invalid state): stop horizontally
