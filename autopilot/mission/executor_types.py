"""The mission executor's configuration, input sample and per-step output (the messages it trades)."""

from __future__ import annotations

from dataclasses import dataclass
from enum import IntEnum

import numpy as np

from autopilot.flight_tasks.rtl import return_alt_m
from autopilot.mission.param_decls import MISSION_PARAM_DEFAULTS
from autopilot.parameters.store import ParamStore
from mavlink_bridge.contract.frames import Vec3
from mavlink_bridge.contract.mav_enums import MissionState
from mavlink_bridge.contract.wire import fast_frozen_init

_NAN = float("nan")


@dataclass(frozen=True, slots=True)
class ExecutorConfig:
    """Executor settings (MIS_ACC_RAD, MIS_ALT_ACC_RAD, MIS_CRUISE_SPD, MIS_RTL_ALT capped below GF_MAX_VER_DIST;
    defaults: theirs)."""

    accept_radius_m: float = MISSION_PARAM_DEFAULTS["MIS_ACC_RAD"]
    alt_accept_m: float = MISSION_PARAM_DEFAULTS["MIS_ALT_ACC_RAD"]
    cruise_speed_m_s: float = MISSION_PARAM_DEFAULTS["MIS_CRUISE_SPD"]
    rtl_alt_m: float = MISSION_PARAM_DEFAULTS["MIS_RTL_ALT"]

    @classmethod
    def from_params(cls, params: ParamStore) -> ExecutorConfig:
        return cls(
            accept_radius_m=params.get("MIS_ACC_RAD"),
            alt_accept_m=params.get("MIS_ALT_ACC_RAD"),
            cruise_speed_m_s=params.get("MIS_CRUISE_SPD"),
            rtl_alt_m=return_alt_m(params.get),  # MIS_RTL_ALT, below the fence ceiling
        )


@fast_frozen_init  # built every control step
@dataclass(frozen=True, slots=True)
class VehicleSample:
    """What the executor needs of the vehicle each step: sim time, local NED state about home, landed flag."""

    time_us: int
    pos_ned_m: Vec3
    vel_ned_m_s: Vec3
    landed: bool


class NavKind(IntEnum):
    """What the setpoint generator is asked to do."""

    IDLE = 0  # nothing to fly (on the ground, no mission running)
    TAKEOFF = 1  # climb vertically to pos_ned_m
    WAYPOINT = 2  # fly to pos_ned_m (pass-through when pass_through)
    LOITER = 3  # hold at pos_ned_m (loiter, delay, waypoint hold, pause, mission complete)
    RETURN = 4  # RTL transit: climb, then fly home at pos_ned_m's altitude
    LAND = 5  # descend at pos_ned_m's horizontal position until landed


@dataclass(frozen=True, slots=True)
class NavTarget:
    """A navigation setpoint target in local NED (m). ``yaw_deg`` NaN: the vehicle chooses (along the path)."""

    kind: NavKind
    seq: int  # mission item it serves; -1 when not from an item (pause, complete)
    pos_ned_m: Vec3
    yaw_deg: float
    speed_m_s: float
    accept_radius_m: float
    pass_through: bool = False
    next_pos_ned_m: Vec3 | None = None


class ActionKind(IntEnum):
    """One-shot actions the autopilot turns into actuator channels."""

    GRIPPER_RELEASE = 0  # payload release -> wire.GRIPPER_CHANNEL = 1
    GRIPPER_GRAB = 1


@dataclass(frozen=True, slots=True)
class MissionAction:
    """An action raised by a DO item at ``time_us``."""

    kind: ActionKind
    seq: int
    time_us: int
    gripper_instance: int = 1


@fast_frozen_init  # built every control step
@dataclass(frozen=True, slots=True)
class ExecutorOutput:
    """Result of one step: the MISSION_CURRENT values, the target, and this step's events."""

    state: MissionState
    current_seq: int
    target: NavTarget | None
    reached: tuple[int, ...]
    actions: tuple[MissionAction, ...]
    speed_m_s: float
    bypassed: tuple[int, ...] = ()  # positional items ``skip_to`` passed over (flown around, not reached)


@dataclass(frozen=True, slots=True)
class MissionRoute:
    """Positional items from the current one on, in execution order (local NED about home, m).

    ``seqs[k]`` is the item at ``pos_ned_m[k]`` (row 0: the current item). ``next_seq`` is the
    non-positional NAV item the route stops at (e.g. RTL or LAND), -1 when it was cut by length or
    count or the mission ends after its last point. Empty when the current item is not positional.
    """

    seqs: tuple[int, ...]
    pos_ned_m: np.ndarray  # (n, 3), read-only
    next_seq: int = -1
