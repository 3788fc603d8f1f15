"""The commander's mission target from the executor's (about home → about the origin) and the nose heading.

Split from :mod:`autopilot.navigation.navigator`: pure functions of the target, the home frame, the parameters
and the avoidance planner's latest output.
"""

from __future__ import annotations

import math
from collections.abc import Callable

from autopilot.flight_tasks.setpoints import NavTarget, TargetKind
from autopilot.mission.executor import MissionRoute, NavKind
from autopilot.mission.executor import NavTarget as MissionTarget
from autopilot.navigation.home_frame import HomeFrame
from autopilot.parameters.store import ParamStore
from mavlink_bridge.contract.frames import Vec3

#: In AUTO_MISSION the nose (forward camera) faces a route point at least this far ahead (m), none closer than
#: FACE_MIN_M (closer, the heading is kept: no spinning over a waypoint).
FACE_AHEAD_M = 6.0
FACE_MIN_M = 2.0


def mission_nav_target(target: MissionTarget, frame: HomeFrame, params: ParamStore, land_speed_m_s: float,
                       face_yaw_rad: float = math.nan) -> NavTarget:  # fmt: skip
    """The executor's target (about home) as a commander target (about the origin); a waypoint or return
    without a yaw of its own gets ``face_yaw_rad`` (MPC_YAW_MODE 0: the nose, and the camera, along the path)."""
    p = params.get
    n, e, d = frame.origin_from_home(target.pos_ned_m)
    speed = min(target.speed_m_s, p("MPC_XY_VEL_MAX"))
    up, down = p("MPC_Z_VEL_MAX_UP"), p("MPC_Z_VEL_MAX_DN")
    yaw = math.nan if math.isnan(target.yaw_deg) else math.radians(target.yaw_deg)
    if math.isnan(yaw) and target.kind in (NavKind.WAYPOINT, NavKind.RETURN):
        yaw = face_yaw_rad
    kind = target.kind
    if kind is NavKind.IDLE:
        return NavTarget(TargetKind.IDLE, (n, e, d))
    if kind is NavKind.LAND:
        return NavTarget(TargetKind.LAND, (n, e, d), yaw, speed, up, land_speed_m_s)
    if kind is NavKind.TAKEOFF:
        up = p("MPC_TKO_SPEED")
    return NavTarget(TargetKind.POSITION, (n, e, d), yaw, speed, up, down)


def face_along_path(
    params: ParamStore,
    planner_output: object | None,
    pos_home_ned_m: Vec3,
    target: MissionTarget,
    mission_route: Callable[[], MissionRoute | None],
) -> float:
    """Heading (rad) toward where the vehicle is going, about home: the detour's look-ahead point while
    avoiding, else the first route point at least FACE_AHEAD_M away (dense patterns), else the target.
    NaN (keep the heading) with MPC_YAW_MODE 1 or nothing far enough away."""
    if params.get("MPC_YAW_MODE") >= 0.5:
        return math.nan
    pos = pos_home_ned_m
    look = getattr(planner_output, "look_ahead_ned", None)
    if look is None or getattr(planner_output, "setpoint", None) is None:
        look = target.pos_ned_m
        if target.kind is NavKind.WAYPOINT and math.hypot(look[0] - pos[0], look[1] - pos[1]) < FACE_AHEAD_M:
            route = mission_route()
            if route is not None:
                for row in route.pos_ned_m.tolist()[1:]:
                    look = row
                    if math.hypot(row[0] - pos[0], row[1] - pos[1]) >= FACE_AHEAD_M:
                        break
    dn, de = look[0] - pos[0], look[1] - pos[1]
    return math.atan2(de, dn) if math.hypot(dn, de) >= FACE_MIN_M else math.nan
