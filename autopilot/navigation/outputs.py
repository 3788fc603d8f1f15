"""What the navigator emits each step (targets about the estimator origin): :class:`NavOutput` for the commander
and, while a detour is flown, :class:`ReferenceOverride` for flight control."""

from __future__ import annotations

from dataclasses import dataclass

from autopilot.flight_tasks.setpoints import NavTarget
from autopilot.safety.failsafe import FailsafeEvent
from mavlink_bridge.contract.frames import Vec3
from mavlink_bridge.contract.wire import fast_frozen_init


@fast_frozen_init
@dataclass(frozen=True, slots=True)
class NavOutput:
    """What the navigator asks for at one step (targets about the estimator origin)."""

    mission_target: NavTarget | None  # None: the mission flies nothing now; in AUTO_RTL the return's routed point
    reached: tuple[int, ...] = ()  # items reached at this step
    gripper_release: bool | None = None  # a DO_GRIPPER action at this step: True release, False grab
    bypassed: tuple[int, ...] = ()  # items flown around (a detour rejoined past them), never reached
    failsafe: FailsafeEvent | None = None  # no route for CA_NOROUTE_T: CA_NOROUTE_ACT (once)


@fast_frozen_init
@dataclass(frozen=True, slots=True)
class ReferenceOverride:
    """The avoidance planner's reference for this step (about the estimator origin), replacing the route's."""

    pos_ned_m: Vec3
    vel_ned_m_s: Vec3
    acc_ned_m_s2: Vec3


#: Nothing to fly and nothing happened (the same object every such step).
NOTHING = NavOutput(None)
