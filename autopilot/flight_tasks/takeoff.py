"""AUTO_TAKEOFF: climb to the takeoff altitude above home at ``MPC_TKO_SPEED``, then HOLD (PX4's
``FlightTaskAuto`` takeoff). Altitudes: ``MIS_TAKEOFF_ALT`` by default, or the command's (see the commander)."""

from __future__ import annotations

import math

from autopilot.estimation import VehicleState
from autopilot.flight_tasks.hold import HoldTask
from autopilot.flight_tasks.setpoints import NavTarget, TargetKind
from autopilot.parameters.store import ParamStore


class TakeoffTask:
    """The takeoff altitude above home and its local down; the climb goes to the hold point above the vehicle."""

    def __init__(self) -> None:
        self.alt_rel_m = 0.0
        self.down_m = 0.0

    def start(self, state: VehicleState, home_down_m: float, alt_rel_m: float, hold: HoldTask) -> None:
        """Climb ``alt_rel_m`` above home (down ``home_down_m``) over where the vehicle is."""
        self.alt_rel_m = alt_rel_m
        self.down_m = home_down_m - alt_rel_m
        hold.pos_ned_m = (state.pos_ned_m[0], state.pos_ned_m[1], self.down_m)
        hold.yaw_rad = math.nan

    def reached(self, state: VehicleState, params: ParamStore) -> bool:
        """Within ``MIS_ALT_ACC_RAD`` of the takeoff altitude."""
        return abs(state.pos_ned_m[2] - self.down_m) < params.get("MIS_ALT_ACC_RAD")

    @staticmethod
    def target(hold: HoldTask, params: ParamStore, speed_xy_m_s: float) -> NavTarget:
        """The climb to the hold point at ``MPC_TKO_SPEED``."""
        vxy = speed_xy_m_s
        return NavTarget(TargetKind.POSITION, hold.pos_ned_m, math.nan, vxy, params.get("MPC_TKO_SPEED"), vxy)
