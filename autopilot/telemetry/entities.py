"""Entity paths of a quadsitl recording (SPEC §9): one place, shared by the logger, blueprint and readers.

3D entities live under ``world`` (NED, declared with ``ViewCoordinates.FRD``: X forward = north,
Y right = east, Z down). Things expressed about home (route, detours, obstacles, fence) live
under ``world/home``, whose transform is the home position in the local NED frame. Series are
``Scalars`` with one column per component (named by ``SeriesLines``); the timeline is ``sim_time``.
"""

from __future__ import annotations

TIMELINE = "sim_time"

WORLD = "world"
VEHICLE = "world/vehicle"
VEHICLE_BODY = "world/vehicle/body"
SETPOINT = "world/setpoint"
TARGETS = "world/targets"  # navigation targets as they were commanded (about the origin)
TRAIL = "world/trail"
SEPARATION_VOLUME = "world/separation_volume"  # a fleet vehicle's own UAV separation volume (its position)
HOME = "world/home"
ROUTE = "world/home/route"
DETOUR = "world/home/detour"
PLANNED_ROUTE = "world/home/planned_route"  # the leg routed around the fence / known obstacles (issue 13)
OBSTACLES_SENSED = "world/home/obstacles/sensed"
OBSTACLES_SAFETY = "world/home/obstacles/safety"
OBSTACLES_TRUE = "world/home/obstacles/true"
FENCE = "world/home/fence"
TICKS = "world/home/ticks"  # the labelled north/east grid of the top view (hidden in the 3D view)

POS_NED = "position/pos_ned_m"
POS_SP_NED = "position/pos_sp_ned_m"
POS_ERR_NED = "errors/pos_err_ned_m"
ATT_ERR = "errors/att_err_deg"
ATT = "attitude/att_deg"
ATT_SP = "attitude/att_sp_deg"
GAINS_POSITION = "gains/position"  # /kp, /ki, /kd with x, y, z
GAINS_ATTITUDE = "gains/attitude"  # /kp, /ki, /kd with roll, pitch, yaw
MOTORS = "motors/motor_cmd"
THRUST = "thrust/thrust_n"
TORQUE = "thrust/torque_frd_nm"
BATTERY_REMAINING = "battery/remaining_pct"
BATTERY_VOLTAGE = "battery/voltage_v"
CLEARANCE = "planner/clearance_m"
MISSION_SEQ = "mission/seq"
LOG = "log"

# monitor (any MAVLink vehicle)
MON_ATT = "monitor/attitude_deg"
MON_POS = "monitor/pos_ned_m"
MON_ALT = "monitor/alt_rel_m"
MON_MISSION = "monitor/mission_seq"
MON_VEHICLE = "world/monitor_vehicle"
MON_TRAIL = "world/monitor_trail"

XYZ = ("north", "east", "down")
RPY = ("roll", "pitch", "yaw")
MOTOR_NAMES = ("m0 front-right", "m1 rear-left", "m2 front-left", "m3 rear-right")


def gain_path(loop: str, term: str) -> str:
    """``gains/<position|attitude>/<kp|ki|kd>``."""
    return f"gains/{loop}/{term}"
