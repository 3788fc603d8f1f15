"""AUTO_RTL: climb to ``MIS_RTL_ALT`` above home (if lower), fly home, wait ``RTL_LAND_DELAY``, land (PX4's RTL
navigator mode). The LAND phase is the land task's, over home."""

from __future__ import annotations

import math
from enum import Enum

from autopilot.estimation import VehicleState
from autopilot.flight_tasks.hold import HoldTask
from autopilot.flight_tasks.land import LandTask
from autopilot.flight_tasks.setpoints import NavTarget, TargetKind
from autopilot.flight_tasks.targets import face_yaw
from autopilot.parameters.store import ParamStore
from mavlink_bridge.contract.wire import Vec3


class RtlPhase(Enum):
    """Where an RTL is."""

    CLIMB = "climb"
    RETURN = "return"
    LOITER = "loiter"
    LAND = "land"


class RtlTask:
    """The phase, the return altitude (local down), the point above home and when the loiter there ends."""

    def __init__(self) -> None:
        self.phase = RtlPhase.CLIMB
        self.down_m = 0.0
        self.loiter_until_us = 0
        self.goto_ned: Vec3 = (0.0, 0.0, 0.0)
        self.goto_yaw = math.nan

    def start(self, state: VehicleState, home_down_m: float, params: ParamStore) -> None:
        self.phase = RtlPhase.CLIMB
        self.down_m = min(state.pos_ned_m[2], home_down_m - params.get("MIS_RTL_ALT"))

    def target(
        self,
        state: VehicleState,
        home_ned_m: Vec3,
        params: ParamStore,
        speeds: tuple[float, float, float],
        hold: HoldTask,
        land: LandTask,
    ) -> NavTarget | None:
        """The target of the phase; None in the LAND phase (fly the land task, whose spot is now home)."""
        p = params.get
        n, e, d = state.pos_ned_m
        if self.phase is RtlPhase.CLIMB:
            if d - self.down_m < p("MIS_ALT_ACC_RAD"):
                self.phase = RtlPhase.RETURN
                self.goto_ned = (home_ned_m[0], home_ned_m[1], self.down_m)
                self.goto_yaw = face_yaw(params, state, self.goto_ned)
            else:
                hold.pos_ned_m = (n, e, self.down_m)
                return NavTarget(TargetKind.POSITION, hold.pos_ned_m, math.nan, *speeds)
        if self.phase is RtlPhase.RETURN:
            if math.hypot(n - home_ned_m[0], e - home_ned_m[1]) < p("MIS_ACC_RAD"):
                self.phase = RtlPhase.LOITER
                self.loiter_until_us = state.time_us + int(p("RTL_LAND_DELAY") * 1e6)
            else:
                return NavTarget(TargetKind.POSITION, self.goto_ned, self.goto_yaw, *speeds)
        if self.phase is RtlPhase.LOITER:
            if state.time_us >= self.loiter_until_us:
                self.phase = RtlPhase.LAND
                land.ne = (home_ned_m[0], home_ned_m[1])
            else:
                return NavTarget(TargetKind.POSITION, self.goto_ned, math.nan, *speeds)
        return None
