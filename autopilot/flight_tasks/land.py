"""AUTO_LAND: descend over a spot (``MPC_Z_VEL_MAX_DN``, then ``MPC_LAND_SPEED`` below ``MPC_LAND_ALT2`` above
home) until the land detector sees touchdown (PX4's ``FlightTaskAuto`` land).

After a position-loss failsafe the landing is *blind*: a DESCEND target brakes on the dead-reckoned velocity and
descends level, without horizontal position control, until the position comes back.
"""

from __future__ import annotations

import math

from autopilot.estimation import VehicleState
from autopilot.flight_tasks.setpoints import NavTarget, TargetKind
from autopilot.flight_tasks.targets import NO_POSITION
from autopilot.parameters.store import ParamStore


def land_speed_m_s(params: ParamStore, alt_rel_home_m: float) -> float:
    """Descent speed of a landing: MPC_LAND_SPEED below MPC_LAND_ALT2 above home, else MPC_Z_VEL_MAX_DN."""
    p = params.get
    return p("MPC_LAND_SPEED") if alt_rel_home_m < p("MPC_LAND_ALT2") else p("MPC_Z_VEL_MAX_DN")


class LandTask:
    """The landing spot (local NE), whether the landing is blind, and the targets built once per change."""

    def __init__(self) -> None:
        self.ne: tuple[float, float] = (0.0, 0.0)
        self.blind = False  # AUTO_LAND without a horizontal position (position-loss failsafe)
        self._key: tuple[object, ...] = ()
        self._nav: NavTarget | None = None
        self._descend_nav: NavTarget | None = None
        self._descend_version = -1

    def start(self, state: VehicleState, ne: tuple[float, float] | None = None) -> None:
        """Land over ``ne`` (default: where the vehicle is)."""
        self.ne = ne if ne is not None else (state.pos_ned_m[0], state.pos_ned_m[1])

    def target(self, state: VehicleState, params: ParamStore, speed_dn_m_s: float, speed_xy_m_s: float) -> NavTarget:
        """LAND over ``ne``; one object while the spot, the speeds and the parameters stay (so the setpoint
        generator's prepared step applies). Its down is the vehicle's when it was made: LAND holds only the xy."""
        key = (self.ne, speed_dn_m_s, speed_xy_m_s, params.version)
        nav = self._nav
        if nav is None or key != self._key:
            self._key = key
            pos = (self.ne[0], self.ne[1], state.pos_ned_m[2])
            nav = self._nav = NavTarget(
                TargetKind.LAND, pos, math.nan, speed_xy_m_s, params.get("MPC_Z_VEL_MAX_UP"), speed_dn_m_s
            )
        return nav

    def descend_target(self, params: ParamStore, speed_dn_m_s: float, speed_xy_m_s: float) -> NavTarget:
        """DESCEND (position lost): stop and descend at the land speeds; one object while they and the parameters
        stay (no allocation per step)."""
        nav = self._descend_nav
        if nav is None or nav.speed_down_m_s != speed_dn_m_s or self._descend_version != params.version:
            self._descend_version = params.version
            speeds = (speed_xy_m_s, params.get("MPC_Z_VEL_MAX_UP"), speed_dn_m_s)
            nav = self._descend_nav = NavTarget(TargetKind.DESCEND, NO_POSITION, math.nan, *speeds)
        return nav
