"""What every flight task builds its :class:`NavTarget` from: velocity targets and the yaw that faces a point."""

from __future__ import annotations

import math

from autopilot.estimation import VehicleState
from autopilot.flight_tasks.setpoints import NavTarget, TargetKind
from autopilot.parameters.store import ParamStore
from mavlink_bridge.contract.wire import Vec3

#: The position of a target that has none (VELOCITY, DESCEND).
NO_POSITION = (math.nan, math.nan, math.nan)
#: Face the target only when it is at least this far away horizontally (m).
_FACE_TARGET_MIN_M = 2.0


def velocity_target(
    vel_ned_m_s: Vec3,
    speeds: tuple[float, float, float],
    yaw_rad: float = math.nan,
    yaw_rate_rad_s: float = math.nan,
) -> NavTarget:
    """A VELOCITY target (it has no position) within ``speeds`` (xy, up, down)."""
    return NavTarget(TargetKind.VELOCITY, NO_POSITION, yaw_rad, *speeds, vel_ned_m_s, yaw_rate_rad_s)


def face_yaw(params: ParamStore, state: VehicleState, target_ned: Vec3) -> float:
    """The heading toward ``target_ned`` (``MPC_YAW_MODE`` 0, far enough away), else NaN (keep the heading)."""
    if params.get("MPC_YAW_MODE") >= 0.5:
        return math.nan
    dn, de = target_ned[0] - state.pos_ned_m[0], target_ned[1] - state.pos_ned_m[1]
    return math.atan2(de, dn) if math.hypot(dn, de) >= _FACE_TARGET_MIN_M else math.nan
