"""What the commander is given: the home position, the command context and the inputs of one step."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

from autopilot.estimation import EstimatorStatus, VehicleState
from autopilot.flight_tasks.setpoints import NavTarget
from mavlink_bridge.contract.frames import GeoPoint, LocalNedFrame
from mavlink_bridge.contract.vehicle_api import CommandRequest, CommandResult
from mavlink_bridge.contract.wire import Vec3, fast_frozen_init

#: A command handled outside the commander (e.g. MAV_CMD_INJECT_FAILURE): (result, reason when refused).
CommandHandler = Callable[[CommandRequest], tuple[CommandResult, str]]


@fast_frozen_init
@dataclass(frozen=True, slots=True)
class Home:
    """The home position: where the vehicle was armed (local NED about the origin, and geodetic)."""

    pos_ned_m: Vec3
    geo: GeoPoint
    yaw_rad: float


@dataclass(frozen=True, slots=True)
class CommandContext:
    """What the commander needs from outside to judge commands and modes (the runner builds it on change)."""

    mission_ready: bool = False  # a valid mission is loaded
    offboard_streaming: bool = False  # offboard setpoints arrived within COM_OF_LOSS_T
    manual_fresh: bool = False  # joystick input arrived within COM_RC_LOSS_T
    failsafe_reasons: frozenset[str] = frozenset()  # the failsafes in force (arming is refused meanwhile)
    estimator_status: EstimatorStatus | None = None  # arming waits until it is aligned and healthy (None: unchecked)


@fast_frozen_init
@dataclass(frozen=True, slots=True)
class CommanderInputs:
    """Everything the commander reads at one step: the estimate, the last thrust, the estimator's local frame,
    the :class:`CommandContext` and the navigator's target (about the origin): in AUTO_MISSION the mission's, in
    AUTO_RTL's return leg the routed point to fly toward (a via point, home, or the hold point with no route)."""

    state: VehicleState
    thrust_ratio: float  # last collective thrust / hover thrust (land detector)
    local_frame: LocalNedFrame | None
    context: CommandContext
    mission_target: NavTarget | None = None
