"""Test helpers for the autopilot unit tests: vehicle states and a kinematic closed loop (no sim, no sockets)."""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

from autopilot.commander.inputs import CommanderInputs
from autopilot.commander.state_machine import Commander
from autopilot.estimation import VehicleState
from autopilot.flight_tasks.setpoints import NavTarget, SetpointGenerator, SetpointLimits, TargetKind
from autopilot.mission.param_decls import mission_param_specs
from autopilot.parameters.nav_decls import nav_param_specs
from autopilot.parameters.store import ParamStore
from mavlink_bridge.contract.frames import GRAVITY_M_S2, GeoPoint, LocalNedFrame
from mavlink_bridge.contract.vehicle_api import CommandRequest

HOME = GeoPoint(47.397742, 8.545594, 488.0)
FRAME = LocalNedFrame(HOME)


def make_state(
    pos_ned_m: tuple[float, float, float] = (0.0, 0.0, 0.0),
    vel_ned_m_s: tuple[float, float, float] = (0.0, 0.0, 0.0),
    time_us: int = 0,
    gps_fix_type: int = 3,
    valid: bool = True,
    yaw_rad: float = 0.0,
) -> VehicleState:
    geo = FRAME.geodetic_from_ned(*pos_ned_m)
    q = (math.cos(yaw_rad / 2), 0.0, 0.0, math.sin(yaw_rad / 2))
    return VehicleState(
        time_us=time_us,
        pos_ned_m=pos_ned_m,
        vel_ned_m_s=vel_ned_m_s,
        q_ned_frd=q,
        rate_frd_rad_s=(0.0, 0.0, 0.0),
        roll_rad=0.0,
        pitch_rad=0.0,
        yaw_rad=yaw_rad,
        lat_deg=geo.lat_deg,
        lon_deg=geo.lon_deg,
        alt_amsl_m=geo.alt_amsl_m,
        gps_fix_type=gps_fix_type,
        gps_satellites=10 if gps_fix_type >= 3 else 0,
        gps_eph_m=0.5,
        gps_epv_m=0.8,
        valid=valid,
    )


def command(cmd: int, *params: float, is_int: bool = False, frame: int = 0) -> CommandRequest:
    full = (*params, *([0.0] * (7 - len(params))))
    return CommandRequest(cmd, tuple(full), 255, 190, is_int=is_int, frame=frame)  # type: ignore[arg-type]


def update(
    commander: Commander, state: VehicleState, thrust_ratio: float = 0.0, mission_target: NavTarget | None = None
) -> NavTarget:
    """One commander step with the context it has (tests change it with :func:`set_context`)."""
    return commander.update(CommanderInputs(state, thrust_ratio, FRAME, commander.context, mission_target))


def set_context(commander: Commander, **changes: object) -> None:
    """What the runner would tell the commander (mission loaded, streams fresh, failsafes in force)."""
    commander.context = replace(commander.context, **changes)  # type: ignore[arg-type]


def make_commander() -> Commander:
    commander = Commander(ParamStore(nav_param_specs() + mission_param_specs()))
    commander.local_frame = FRAME
    return commander


@dataclass
class KinematicLoop:
    """Commander + setpoint generator + a vehicle that follows the reference with a first-order lag.

    The vehicle rests on flat ground at down = 0; ``thrust_ratio`` is what a PD position loop
    (kp = 5, kd = 4) would ask for, so the land detector sees low thrust when the reference
    is pushed below the ground.
    """

    commander: Commander
    dt_s: float = 0.004
    time_us: int = 0
    pos: tuple[float, float, float] = (0.0, 0.0, 0.0)
    vel: tuple[float, float, float] = (0.0, 0.0, 0.0)
    thrust_ratio: float = 0.0
    mission_target: NavTarget | None = None  # what the navigator would hand over in AUTO_MISSION

    def __post_init__(self) -> None:
        self.gen = SetpointGenerator(SetpointLimits())
        self.last_kind = TargetKind.IDLE

    def state(self) -> VehicleState:
        return make_state(self.pos, self.vel, self.time_us)

    def step(self) -> None:
        state = self.state()
        target = update(self.commander, state, self.thrust_ratio, self.mission_target)
        if target.kind is not TargetKind.IDLE and self.last_kind is TargetKind.IDLE:
            self.gen.reset(state.pos_ned_m, state.vel_ned_m_s, state.yaw_rad)
        self.last_kind = target.kind
        self.gen.update(target, self.dt_s, state.pos_ned_m)
        if target.kind is TargetKind.IDLE:
            self.thrust_ratio = 0.1
            new_pos = (self.pos[0], self.pos[1], min(0.0, self.pos[2] + self.vel[2] * self.dt_s))
            self.vel = (0.0, 0.0, 0.0) if new_pos[2] >= 0.0 else (0.0, 0.0, self.vel[2] + GRAVITY_M_S2 * self.dt_s)
            self.pos = new_pos
        else:
            gen = self.gen
            az = gen.acc_ned[2] + 5.0 * (gen.pos_ned[2] - self.pos[2]) + 4.0 * (gen.vel_ned[2] - self.vel[2])
            self.thrust_ratio = max(0.0, 1.0 - az / GRAVITY_M_S2)
            alpha = self.dt_s / 0.1  # the vehicle tracks the reference with a 0.1 s lag
            pos = [p + alpha * (sp - p) for p, sp in zip(self.pos, self.gen.pos_ned, strict=True)]
            pos[2] = min(0.0, pos[2])  # the ground
            self.vel = tuple((a - b) / self.dt_s for a, b in zip(pos, self.pos, strict=True))  # type: ignore[assignment]
            self.pos = tuple(pos)  # type: ignore[assignment]
        self.time_us += round(self.dt_s * 1e6)

    def run_s(self, seconds: float) -> None:
        for _ in range(round(seconds / self.dt_s)):
            self.step()

    def run_until(self, predicate, timeout_s: float) -> bool:  # type: ignore[no-untyped-def]
        for _ in range(round(timeout_s / self.dt_s)):
            self.step()
            if predicate():
                return True
        return False
