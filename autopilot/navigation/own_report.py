"""What the vehicle says about itself on its traffic link (SPEC §13): its own UTM_GLOBAL_POSITION.

Once a second (``OWN_REPORT_RATE_HZ``, the 1 Hz minimum refresh of ASTM F3411 network remote ID; the report's
``update_rate`` says so) the autopilot hands the bridge an :class:`OwnPositionReport` of its **estimate** (never the
truth): the estimator's geodetic position and NED velocity with its 1-sigma accuracies, the point it is flying to
in an autonomous mode as its next waypoint (the target about the estimator origin, made geodetic; a landing's is
the touchdown point at home's altitude), and its flight state (UTM_FLIGHT_STATE: GROUND on the ground, AIRBORNE in
the air, EMERGENCY in the air with a failsafe in force). The simulator relays it to the other vehicles as a UTM
service would. Pure: the caller gives the state and the time.
"""

from __future__ import annotations

import math
from typing import Protocol

from autopilot.estimation import Estimator, VehicleState
from autopilot.flight_tasks.setpoints import NavTarget, TargetKind
from mavlink_bridge.contract.frames import LocalNedFrame, Vec3
from mavlink_bridge.contract.traffic import OwnPositionReport, UtmFlightState
from mavlink_bridge.contract.vehicle_api import FlightMode, LandedState

#: Reports per second (ASTM F3411-22a network remote ID: NetMinUasLocRefreshFrequencyHz = 1).
OWN_REPORT_RATE_HZ = 1.0
_PERIOD_US = round(1e6 / OWN_REPORT_RATE_HZ)
#: Vehicle k's reports are offset by k x this within the period (a fleet's reports do not all land in one frame).
_PHASE_STEP_US = 100_000
#: Modes whose target is the vehicle's intent (PX4 fills next_lat/lon/alt in its auto modes).

AUTONOMOUS_MODES = frozenset(
    (
        FlightMode.AUTO_TAKEOFF,
        FlightMode.AUTO_LOITER,
        FlightMode.AUTO_MISSION,
        FlightMode.AUTO_RTL,
        FlightMode.AUTO_LAND,
    )
)


class OwnReportSchedule:
    """When the next own report is due: every ``1 / OWN_REPORT_RATE_HZ`` of sim time, vehicle ``sys_id``'s at an
    offset of ``(sys_id - 1) x 100 ms`` within the period."""

    def __init__(self, sys_id: int) -> None:
        self._next_us = ((sys_id - 1) * _PHASE_STEP_US) % _PERIOD_US

    def due(self, t_us: int) -> bool:
        """True once per period (at the first step at or after the due time); advances the schedule."""
        if t_us < self._next_us:
            return False
        self._next_us += _PERIOD_US * (1 + (t_us - self._next_us) // _PERIOD_US)
        return True


def next_waypoint_ned(target: NavTarget, mode: FlightMode, home_ned_m: Vec3) -> Vec3 | None:
    """The point the vehicle is flying to, about the estimator origin (None: no autonomous target)."""
    if mode not in AUTONOMOUS_MODES:
        return None
    if target.kind is TargetKind.POSITION:
        return target.pos_ned_m
    if target.kind is TargetKind.LAND:
        return (target.pos_ned_m[0], target.pos_ned_m[1], home_ned_m[2])  # touchdown at home's level
    return None


def flight_state(on_ground: bool, failsafe_active: bool) -> UtmFlightState:
    """UTM_FLIGHT_STATE of the vehicle (PX4 sends UNKNOWN while disarmed; quadsitl says GROUND: it is)."""
    if on_ground:
        return UtmFlightState.GROUND
    return UtmFlightState.EMERGENCY if failsafe_active else UtmFlightState.AIRBORNE


def own_position_report(
    state: VehicleState,
    sys_id: int,
    frame: LocalNedFrame,
    next_ned_m: Vec3 | None,
    state_now: UtmFlightState,
    h_acc_m: float,
    v_acc_m: float,
) -> OwnPositionReport | None:
    """The report of the estimate ``state`` (None while it is not valid); ``frame``: the estimator's local frame
    (for the next waypoint), ``h_acc_m``/``v_acc_m``: the estimator's 1-sigma accuracies (NaN: unknown)."""
    if not state.valid or not (math.isfinite(state.lat_deg) and math.isfinite(state.lon_deg)):
        return None
    next_lat = next_lon = next_alt = math.nan
    if next_ned_m is not None and all(math.isfinite(x) for x in next_ned_m):
        w = frame.geodetic_from_ned(*next_ned_m)
        next_lat, next_lon, next_alt = w.lat_deg, w.lon_deg, w.alt_amsl_m
    vn, ve, vd = state.vel_ned_m_s
    return OwnPositionReport(
        t_us=state.time_us,
        sys_id=sys_id,
        lat_deg=state.lat_deg,
        lon_deg=state.lon_deg,
        alt_amsl_m=state.alt_amsl_m,
        vel_n_m_s=vn,
        vel_e_m_s=ve,
        vel_d_m_s=vd,
        flight_state=state_now,
        update_rate_hz=OWN_REPORT_RATE_HZ,
        h_acc_m=h_acc_m,
        v_acc_m=v_acc_m,
        next_lat_deg=next_lat,
        next_lon_deg=next_lon,
        next_alt_amsl_m=next_alt,
    )


class CommanderLike(Protocol):
    """What :meth:`OwnReporter.step` reads of the commander."""

    @property
    def mode(self) -> FlightMode: ...
    @property
    def landed_state(self) -> LandedState: ...


class ContextLike(Protocol):
    """What :meth:`OwnReporter.step` reads of the commander's context."""

    @property
    def failsafe_reasons(self) -> frozenset[str]: ...


class OwnReporter:
    """The runner's side: :meth:`step` every control step; :meth:`report_for` gives the I/O edge the report of a
    step (None on the steps none is due)."""

    def __init__(self, sys_id: int) -> None:
        self.sys_id = sys_id
        self.schedule = OwnReportSchedule(sys_id)
        self.latest: OwnPositionReport | None = None

    def step(self, state: VehicleState, estimator: Estimator, target: NavTarget, commander: CommanderLike,
             home_ned_m: Vec3, context: ContextLike) -> None:  # fmt: skip
        """Make the report due at ``state.time_us``: the estimate with ``estimator``'s 1-sigma accuracies,
        ``target`` (in an autonomous mode) as the next waypoint, EMERGENCY while a failsafe is in force."""
        frame = estimator.local_frame
        if not self.schedule.due(state.time_us) or frame is None:
            return
        status = estimator.status
        next_ned = next_waypoint_ned(target, commander.mode, home_ned_m)
        now = flight_state(commander.landed_state is LandedState.ON_GROUND, bool(context.failsafe_reasons))
        report = own_position_report(state, self.sys_id, frame, next_ned, now, status.pos_horiz_accuracy_m,
                                     status.pos_vert_accuracy_m)  # fmt: skip
        self.latest = report or self.latest

    def report_for(self, t_us: int) -> OwnPositionReport | None:
        """The report made at the step of sim time ``t_us`` (send it with that step's answer), else None."""
        latest = self.latest
        return latest if latest is not None and latest.t_us == t_us else None
