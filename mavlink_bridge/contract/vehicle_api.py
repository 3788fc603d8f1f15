"""Typed contract between the autopilot and its GCS/API links (SPEC §3, §8).

The autopilot implements :class:`VehicleInterface` and hands :class:`TelemetrySnapshot`
to the GCS server in ``mavlink_bridge``; it never sees a MAVLink message. Numeric values
of enums are the MAVLink ones so the codec is a plain cast.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from enum import IntEnum, IntFlag
from typing import Protocol

from mavlink_bridge.contract.wire import Quat, Vec3


class FlightMode(IntEnum):
    """Flight modes with PX4 ``custom_mode`` encoding: ``main << 16 | sub << 24``."""

    MANUAL = 1 << 16
    POSCTL = 3 << 16
    OFFBOARD = 6 << 16
    AUTO_READY = (4 << 16) | (1 << 24)
    AUTO_TAKEOFF = (4 << 16) | (2 << 24)
    AUTO_LOITER = (4 << 16) | (3 << 24)  # "HOLD"
    AUTO_MISSION = (4 << 16) | (4 << 24)
    AUTO_RTL = (4 << 16) | (5 << 24)
    AUTO_LAND = (4 << 16) | (6 << 24)

    @property
    def px4_main_mode(self) -> int:
        return (self.value >> 16) & 0xFF

    @property
    def px4_sub_mode(self) -> int:
        return (self.value >> 24) & 0xFF

    @classmethod
    def from_px4(cls, main_mode: int, sub_mode: int) -> FlightMode:
        """Decode PX4 main/sub mode; AUTO without a sub mode means LOITER (HOLD). Raises ValueError."""
        if main_mode == 4 and sub_mode == 0:
            return cls.AUTO_LOITER
        value = (main_mode << 16) | ((sub_mode << 24) if main_mode == 4 else 0)
        return cls(value)


class LandedState(IntEnum):
    """MAV_LANDED_STATE."""

    UNDEFINED = 0
    ON_GROUND = 1
    IN_AIR = 2
    TAKEOFF = 3
    LANDING = 4


class CommandResult(IntEnum):
    """MAV_RESULT."""

    ACCEPTED = 0
    TEMPORARILY_REJECTED = 1
    DENIED = 2
    UNSUPPORTED = 3
    FAILED = 4
    IN_PROGRESS = 5
    CANCELLED = 6


class MissionType(IntEnum):
    """MAV_MISSION_TYPE."""

    MISSION = 0
    FENCE = 1
    RALLY = 2
    ALL = 255


class MissionResult(IntEnum):
    """MAV_MISSION_RESULT."""

    ACCEPTED = 0
    ERROR = 1
    UNSUPPORTED_FRAME = 2
    UNSUPPORTED = 3
    NO_SPACE = 4
    INVALID = 5
    INVALID_PARAM1 = 6
    INVALID_PARAM2 = 7
    INVALID_PARAM3 = 8
    INVALID_PARAM4 = 9
    INVALID_PARAM5_X = 10
    INVALID_PARAM6_Y = 11
    INVALID_PARAM7 = 12
    INVALID_SEQUENCE = 13
    DENIED = 14
    OPERATION_CANCELLED = 15


class Severity(IntEnum):
    """MAV_SEVERITY for STATUSTEXT."""

    EMERGENCY = 0
    ALERT = 1
    CRITICAL = 2
    ERROR = 3
    WARNING = 4
    NOTICE = 5
    INFO = 6
    DEBUG = 7


@dataclass(frozen=True, slots=True)
class MissionItem:
    """One mission item as MISSION_ITEM_INT carries it, in SI/degrees.

    ``x_lat_deg``/``y_lon_deg`` are degrees for global frames (local metres for local
    frames); ``z_alt_m`` is metres in ``frame`` (MAV_FRAME_GLOBAL_RELATIVE_ALT_INT = 6 is
    relative to home). ``command`` is the MAV_CMD number.
    """

    seq: int
    command: int
    frame: int = 6
    param1: float = 0.0
    param2: float = 0.0
    param3: float = 0.0
    param4: float = 0.0
    x_lat_deg: float = 0.0
    y_lon_deg: float = 0.0
    z_alt_m: float = 0.0
    autocontinue: bool = True
    mission_type: MissionType = MissionType.MISSION


@dataclass(frozen=True, slots=True)
class CommandRequest:
    """COMMAND_LONG or COMMAND_INT, decoded. For COMMAND_INT, x/y arrive as degrees."""

    command: int
    params: tuple[float, float, float, float, float, float, float]
    source_system: int
    source_component: int
    is_int: bool = False
    frame: int = 0


class AltitudeFrame(IntEnum):
    """What a global setpoint's altitude is measured from."""

    AMSL = 0
    ABOVE_HOME = 1


@dataclass(frozen=True, slots=True)
class LocalPositionTarget:
    """SET_POSITION_TARGET_LOCAL_NED (MAV_FRAME_LOCAL_NED): NED about the local origin, the frame of
    LOCAL_POSITION_NED. ``yaw_rad`` NaN = yaw not controlled (type_mask YAW_IGNORE)."""

    pos_ned_m: Vec3
    yaw_rad: float = math.nan


@dataclass(frozen=True, slots=True)
class GlobalPositionTarget:
    """SET_POSITION_TARGET_GLOBAL_INT: latitude/longitude and an altitude in ``alt_frame``."""

    lat_deg: float
    lon_deg: float
    alt_m: float
    alt_frame: AltitudeFrame
    yaw_rad: float = math.nan


PositionTarget = LocalPositionTarget | GlobalPositionTarget


@dataclass(frozen=True, slots=True)
class ManualInput:
    """MANUAL_CONTROL sticks, normalized: ``forward`` (pitch stick), ``right`` (roll stick) and ``yaw`` in [-1, 1],
    ``throttle`` in [0, 1] with 0.5 = centre (hold altitude in POSCTL)."""

    forward: float = 0.0
    right: float = 0.0
    throttle: float = 0.5
    yaw: float = 0.0


class VelocityFrame(IntEnum):
    """The axes of an offboard velocity setpoint."""

    LOCAL_NED = 0  # north, east, down (MAV_FRAME_LOCAL_NED)
    BODY = 1  # forward, right, down about the vehicle's heading (MAV_FRAME_BODY_NED, BODY_OFFSET_NED, BODY_FRD)


@dataclass(frozen=True, slots=True)
class VelocityTarget:
    """SET_POSITION_TARGET_LOCAL_NED with only its velocity used (MAVSDK ``set_velocity_ned``/``set_velocity_body``).

    ``vel_m_s`` in ``frame`` (the autopilot turns BODY into NED with the heading of each control step);
    ``yaw_rad`` (NaN = not given) takes precedence over ``yaw_rate_rad_s`` (NaN = not given).
    """

    vel_m_s: Vec3
    frame: VelocityFrame = VelocityFrame.LOCAL_NED
    yaw_rad: float = math.nan
    yaw_rate_rad_s: float = math.nan


@dataclass(frozen=True, slots=True)
class StatusText:
    """A STATUSTEXT event."""

    severity: Severity
    text: str


class EstimatorFlags(IntFlag):
    """MAVLink ESTIMATOR_STATUS_FLAGS: which parts of the estimate are good."""

    ATTITUDE = 1
    VELOCITY_HORIZ = 2
    VELOCITY_VERT = 4
    POS_HORIZ_REL = 8
    POS_HORIZ_ABS = 16
    POS_VERT_ABS = 32
    POS_VERT_AGL = 64
    CONST_POS_MODE = 128
    PRED_POS_HORIZ_REL = 256
    PRED_POS_HORIZ_ABS = 512
    GPS_GLITCH = 1024
    ACCEL_ERROR = 2048


@dataclass(frozen=True, slots=True)
class EstimatorReport:
    """What ESTIMATOR_STATUS (MAVLink 230) carries: flags, innovation test ratios (> 1: rejected), accuracies.

    Ratios are 0 for a source that is not fused (the wire has no NaN convention for them); accuracies are
    1-sigma in metres.
    """

    flags: EstimatorFlags
    vel_ratio: float
    pos_horiz_ratio: float
    pos_vert_ratio: float
    mag_ratio: float
    pos_horiz_accuracy_m: float
    pos_vert_accuracy_m: float


@dataclass(slots=True)
class TelemetrySnapshot:
    """What the autopilot publishes each control step; the GCS server rate-limits it per stream."""

    time_us: int
    armed: bool
    mode: FlightMode
    landed_state: LandedState
    q_ned_frd: Quat
    rate_frd_rad_s: Vec3
    pos_ned_m: Vec3
    vel_ned_m_s: Vec3
    lat_deg: float
    lon_deg: float
    alt_amsl_m: float
    alt_rel_m: float
    home_lat_deg: float
    home_lon_deg: float
    home_alt_amsl_m: float
    home_valid: bool
    gps_fix_type: int
    gps_satellites: int
    gps_eph_m: float
    gps_epv_m: float
    battery_voltage_v: float
    battery_current_a: float
    battery_remaining_pct: float
    throttle_pct: float
    sensors_present: int  # MAV_SYS_STATUS_SENSOR bitmask
    sensors_enabled: int
    sensors_health: int
    mission_seq_current: int
    mission_count: int
    mission_reached: list[int] = field(default_factory=list)  # items reached since the last snapshot
    mission_state: int = 0  # MISSION_STATE (MISSION_CURRENT): 0 unknown, 1 none, 2 idle, 3 active, 4 paused, 5 done
    estimator: EstimatorReport | None = None  # ESTIMATOR_STATUS (None: not streamed)


class VehicleInterface(Protocol):
    """What the GCS server asks of the autopilot. Every call returns at once (no I/O)."""

    def handle_command(self, request: CommandRequest) -> CommandResult: ...

    def mission_items(self, mission_type: MissionType) -> list[MissionItem]: ...

    def replace_mission(self, mission_type: MissionType, items: list[MissionItem]) -> tuple[MissionResult, str]:
        """Validate and install a complete uploaded list; on error keep the old one and say why."""
        ...

    def set_current_mission_item(self, seq: int) -> bool: ...

    def set_position_target(self, target: PositionTarget) -> bool:
        """An offboard position setpoint (OFFBOARD mode flies the latest); False if it cannot be used now."""
        ...

    def set_velocity_target(self, target: VelocityTarget) -> bool:
        """An offboard velocity setpoint (OFFBOARD mode flies the latest); False if it cannot be used now."""
        ...

    def set_manual_input(self, sticks: ManualInput) -> bool:
        """Joystick input (POSCTL flies it while it keeps coming); False if it cannot be used now."""
        ...

    def param_names(self) -> list[str]: ...

    def param_get(self, name: str) -> float | None: ...

    def param_set(self, name: str, value: float) -> tuple[bool, float, str]:
        """Set a parameter; returns (accepted, value now in force, reason if refused)."""
        ...
