"""MAVLink command, frame and state numbers used by missions (MAV_CMD, MAV_FRAME, ...), without pymavlink.

Values are the MAVLink common-dialect numbers so a codec converts by a plain cast.
The per-command parameter meaning (SPEC §8) is written next to each member.
"""

from __future__ import annotations

from enum import IntEnum


class MavCmd(IntEnum):
    """MAV_CMD numbers the autopilot knows (mission items and COMMAND_LONG/INT)."""

    NAV_WAYPOINT = 16  # p1 hold_s, p2 accept_radius_m (0 = default), p3 pass radius, p4 yaw_deg (NaN = path); x y z
    NAV_LOITER_UNLIM = 17
    NAV_LOITER_TURNS = 18
    NAV_LOITER_TIME = 19  # p1 time_s, p4 yaw_deg; x y z (lat = lon = 0: current position)
    NAV_RETURN_TO_LAUNCH = 20
    NAV_LAND = 21  # p4 yaw_deg; x y (lat = lon = 0: current position)
    NAV_TAKEOFF = 22  # p4 yaw_deg; x y (lat = lon = 0: current position); z alt
    NAV_DELAY = 93  # p1 delay_s (>= 0; -1 = time of day, unsupported)
    DO_SET_MODE = 176
    DO_JUMP = 177  # p1 target seq, p2 repeat count (-1 = forever)
    DO_CHANGE_SPEED = 178  # p1 speed type, p2 speed_m_s (-1 no change, -2 default)
    DO_SET_HOME = 179
    DO_REPOSITION = 192
    DO_GRIPPER = 211  # p1 gripper instance, p2 action (GripperAction)
    MISSION_START = 300
    COMPONENT_ARM_DISARM = 400
    INJECT_FAILURE = 420  # p1 FailureUnit, p2 FailureType, p3 instance (motors 1-based; 0 = all)
    SET_MESSAGE_INTERVAL = 511
    REQUEST_MESSAGE = 512
    NAV_FENCE_RETURN_POINT = 5000
    NAV_FENCE_POLYGON_VERTEX_INCLUSION = 5001  # p1 vertex count, p2 inclusion group; x y
    NAV_FENCE_POLYGON_VERTEX_EXCLUSION = 5002  # p1 vertex count; x y
    NAV_FENCE_CIRCLE_INCLUSION = 5003  # p1 radius_m, p2 inclusion group; x y
    NAV_FENCE_CIRCLE_EXCLUSION = 5004  # p1 radius_m; x y
    NAV_RALLY_POINT = 5100


class MavFrame(IntEnum):
    """MAV_FRAME numbers."""

    GLOBAL = 0  # altitude AMSL
    LOCAL_NED = 1
    MISSION = 2  # no position (DO_ commands)
    GLOBAL_RELATIVE_ALT = 3  # altitude above home
    LOCAL_ENU = 4
    GLOBAL_INT = 5
    GLOBAL_RELATIVE_ALT_INT = 6
    LOCAL_OFFSET_NED = 7
    GLOBAL_TERRAIN_ALT = 10
    GLOBAL_TERRAIN_ALT_INT = 11


class GripperAction(IntEnum):
    """GRIPPER_ACTIONS (DO_GRIPPER param2)."""

    RELEASE = 0
    GRAB = 1


class FailureUnit(IntEnum):
    """FAILURE_UNIT (MAV_CMD_INJECT_FAILURE param1)."""

    SENSOR_GYRO = 0
    SENSOR_ACCEL = 1
    SENSOR_MAG = 2
    SENSOR_BARO = 3
    SENSOR_GPS = 4
    SENSOR_OPTICAL_FLOW = 5
    SENSOR_VIO = 6
    SENSOR_DISTANCE_SENSOR = 7
    SENSOR_AIRSPEED = 8
    SYSTEM_BATTERY = 100
    SYSTEM_MOTOR = 101
    SYSTEM_SERVO = 102
    SYSTEM_AVOIDANCE = 103
    SYSTEM_RC_SIGNAL = 104
    SYSTEM_MAVLINK_SIGNAL = 105


class FailureType(IntEnum):
    """FAILURE_TYPE (MAV_CMD_INJECT_FAILURE param2)."""

    OK = 0  # no failure: clears an injected one
    OFF = 1  # no data
    STUCK = 2  # the same value every time
    GARBAGE = 3  # random data
    WRONG = 4  # plausible but wrong data
    SLOW = 5  # data slower than nominal
    DELAYED = 6  # data delayed
    INTERMITTENT = 7  # data sometimes missing


class MissionState(IntEnum):
    """MISSION_STATE (MISSION_CURRENT.mission_state)."""

    UNKNOWN = 0
    NO_MISSION = 1
    NOT_STARTED = 2
    ACTIVE = 3
    PAUSED = 4
    COMPLETE = 5


#: Commands that move the vehicle (the executor waits for them to complete).
NAV_COMMANDS: frozenset[int] = frozenset(
    {
        MavCmd.NAV_WAYPOINT,
        MavCmd.NAV_LOITER_TIME,
        MavCmd.NAV_RETURN_TO_LAUNCH,
        MavCmd.NAV_LAND,
        MavCmd.NAV_TAKEOFF,
        MavCmd.NAV_DELAY,
    }
)
#: Commands that act at once (the executor runs them and moves on in the same step).
DO_COMMANDS: frozenset[int] = frozenset({MavCmd.DO_JUMP, MavCmd.DO_CHANGE_SPEED, MavCmd.DO_GRIPPER})
#: Every command accepted in a mission_type MISSION upload.
MISSION_COMMANDS: frozenset[int] = NAV_COMMANDS | DO_COMMANDS
#: Mission commands whose x/y/z are a position (lat = lon = 0 means "here" for the ones in CURRENT_POSITION_OK).
POSITION_COMMANDS: frozenset[int] = frozenset(
    {MavCmd.NAV_WAYPOINT, MavCmd.NAV_LOITER_TIME, MavCmd.NAV_LAND, MavCmd.NAV_TAKEOFF}
)
#: Position commands for which lat = lon = 0 means "at the current position".
CURRENT_POSITION_OK: frozenset[int] = frozenset({MavCmd.NAV_LOITER_TIME, MavCmd.NAV_LAND, MavCmd.NAV_TAKEOFF})
#: Commands accepted in a mission_type FENCE upload.
FENCE_COMMANDS: frozenset[int] = frozenset(
    {
        MavCmd.NAV_FENCE_POLYGON_VERTEX_INCLUSION,
        MavCmd.NAV_FENCE_POLYGON_VERTEX_EXCLUSION,
        MavCmd.NAV_FENCE_CIRCLE_INCLUSION,
        MavCmd.NAV_FENCE_CIRCLE_EXCLUSION,
    }
)
#: Frames whose z is metres above home.
RELATIVE_ALT_FRAMES: frozenset[int] = frozenset({MavFrame.GLOBAL_RELATIVE_ALT, MavFrame.GLOBAL_RELATIVE_ALT_INT})
#: Frames whose z is metres AMSL.
AMSL_FRAMES: frozenset[int] = frozenset({MavFrame.GLOBAL, MavFrame.GLOBAL_INT})
#: Global frames the executor understands for positions.
GLOBAL_FRAMES: frozenset[int] = RELATIVE_ALT_FRAMES | AMSL_FRAMES


def command_name(command: int) -> str:
    """``"NAV_WAYPOINT"`` for 16, ``"MAV_CMD 999"`` for an unknown number."""
    try:
        return MavCmd(command).name
    except ValueError:
        return f"MAV_CMD {command}"


def frame_name(frame: int) -> str:
    """``"GLOBAL_RELATIVE_ALT_INT"`` for 6, ``"MAV_FRAME 42"`` for an unknown number."""
    try:
        return MavFrame(frame).name
    except ValueError:
        return f"MAV_FRAME {frame}"
