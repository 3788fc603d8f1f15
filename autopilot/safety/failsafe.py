"""Failsafes: GCS link loss, offboard setpoint loss, low battery, geofence breach (SPEC §10); sensor loss (§5b).

:class:`FailsafeMonitor` is a pure function of its inputs per step: it raises a
:class:`FailsafeEvent` once when a condition starts (edge-triggered, like PX4's
commander) and forgets it when the condition clears. The commander applies the event's
:class:`FailsafeAction`; sim loss is not a flight failsafe here because without the
simulator there is no vehicle: the runner stops and reports it.

The lockstep wire carries no battery telemetry, so :class:`BatteryModel` estimates the
remaining charge from the commanded thrust: at hover thrust the pack lasts
``BAT_HOVER_ENDUR`` seconds and the drain scales with thrust^1.5 (momentum theory:
rotor power ∝ T^1.5). Voltage is a linear 4S curve (16.8 V full, 14.0 V empty).

:class:`SensorFailsafe` watches the estimator's :class:`EstimatorStatus` in sim time (PX4's commander and
EKF2 in spirit): GPS lost -> dead reckoning for ``COM_POS_FS_DELAY``, then the position-loss action
``COM_POS_LOSS_ACT`` (land on baro height without horizontal position control), recovery when GPS returns
first; baro lost -> height from GPS; mag lost -> heading from the gyro. Every transition is an event.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from enum import Enum, IntEnum
from typing import Protocol

from autopilot.estimation.state import EstimatorStatus
from autopilot.parameters.store import ParamStore
from mavlink_bridge.contract.status_texts import failsafe_text

BATTERY_FULL_V = 16.8
BATTERY_EMPTY_V = 14.0


class FailsafeAction(IntEnum):
    """What to do when a failsafe triggers (values of NAV_DLL_ACT, COM_LOW_BAT_ACT, GF_ACTION, ...)."""

    NONE = 0
    WARN = 1
    HOLD = 2
    RTL = 3
    LAND = 4


class FailsafeKind(Enum):
    """Which condition triggered."""

    GCS_LOSS = "gcs link lost"
    OFFBOARD_LOSS = "offboard setpoints lost"
    BATTERY_LOW = "battery low"
    BATTERY_CRITICAL = "battery critical"
    GEOFENCE = "geofence breach"
    GPS_LOSS = "GPS lost"
    POSITION_LOSS = "position lost"
    BARO_LOSS = "baro lost"
    MAG_LOSS = "mag lost"
    NO_ROUTE = "no route"  # the navigator found no route to the mission target for CA_NOROUTE_T (CA_NOROUTE_ACT)
    TRAFFIC = "traffic conflict"  # NAV_TRAFF_AVOID 2/3/4 (autopilot.traffic)


@dataclass(frozen=True, slots=True)
class FailsafeEvent:
    """A failsafe that just triggered (or, ``cleared``, whose condition just ended), the action to take and a
    message for STATUSTEXT."""

    kind: FailsafeKind
    action: FailsafeAction
    message: str
    cleared: bool = False


@dataclass(frozen=True, slots=True)
class FailsafeInputs:
    """One step of what the monitor looks at. Ages are wall-clock seconds (SPEC §3); None = not applicable."""

    armed: bool
    in_air: bool
    gcs_heartbeat_age_s: float | None  # None until a GCS has been heard
    offboard_setpoint_age_s: float | None  # None unless in OFFBOARD
    battery_remaining: float  # fraction 0..1
    pos_ned_m: tuple[float, float, float]  # about the local origin
    home_ned_m: tuple[float, float, float]  # home about the local origin
    geofence: FenceCheck | None = None  # the uploaded FENCE (about home), None without one


class BatteryModel:
    """Remaining charge estimated from commanded collective thrust (see module docstring)."""

    def __init__(self, hover_endurance_s: float) -> None:
        self.hover_endurance_s = hover_endurance_s
        self.remaining = 1.0

    def set_hover_endurance_s(self, hover_endurance_s: float) -> None:
        """BAT_HOVER_ENDUR changed: the charge left stays, the drain rate follows."""
        self.hover_endurance_s = hover_endurance_s

    def update(self, thrust_ratio: float, dt_s: float) -> float:
        """Drain for ``dt_s`` at ``thrust_ratio`` (collective thrust / hover thrust); returns the fraction left."""
        t = max(0.0, thrust_ratio)
        self.remaining = max(0.0, self.remaining - dt_s * t * math.sqrt(t) / self.hover_endurance_s)
        return self.remaining

    @property
    def voltage_v(self) -> float:
        return BATTERY_EMPTY_V + (BATTERY_FULL_V - BATTERY_EMPTY_V) * self.remaining

    def current_a(self, thrust_ratio: float) -> float:
        """Estimated current: 5000 mAh pack emptied in the endurance at that thrust."""
        t = max(0.0, thrust_ratio)
        return 5.0 * 3600.0 * t * math.sqrt(t) / self.hover_endurance_s


class FenceCheck(Protocol):
    """A geofence (``autopilot.geofence.fence.Geofence``): positions are local NED about home."""

    def violates(self, pos_ned: Sequence[float], margin_m: float = 0.0) -> bool: ...


class FailsafeMonitor:
    """Edge-triggered failsafe conditions, actions taken from parameters (see :mod:`autopilot.parameters.nav_decls`)."""

    def __init__(self, params: ParamStore) -> None:
        self._params = params
        self.active: set[FailsafeKind] = set()

    def _action(self, name: str) -> FailsafeAction:
        return FailsafeAction(round(self._params.get(name)))

    def _conditions(self, inp: FailsafeInputs) -> dict[FailsafeKind, tuple[str, str]]:
        """Conditions true now: kind -> (action parameter, message)."""
        p = self._params.get
        out: dict[FailsafeKind, tuple[str, str]] = {}
        if inp.gcs_heartbeat_age_s is not None and inp.gcs_heartbeat_age_s > p("COM_DL_LOSS_T"):
            out[FailsafeKind.GCS_LOSS] = ("NAV_DLL_ACT", f"no GCS heartbeat for {inp.gcs_heartbeat_age_s:.1f} s")
        if inp.offboard_setpoint_age_s is not None and inp.offboard_setpoint_age_s > p("COM_OF_LOSS_T"):
            out[FailsafeKind.OFFBOARD_LOSS] = ("COM_OBL_ACT", f"no setpoint for {inp.offboard_setpoint_age_s:.1f} s")
        pct = 100.0 * inp.battery_remaining
        if inp.battery_remaining < p("BAT_CRIT_THR"):
            out[FailsafeKind.BATTERY_CRITICAL] = ("COM_LOW_BAT_ACT", f"battery critical ({pct:.0f} %)")
        elif inp.battery_remaining < p("BAT_LOW_THR"):
            out[FailsafeKind.BATTERY_LOW] = ("", f"battery low ({pct:.0f} %)")
        n, e, d = (inp.pos_ned_m[i] - inp.home_ned_m[i] for i in range(3))
        reason = None
        max_hor, max_ver = p("GF_MAX_HOR_DIST"), p("GF_MAX_VER_DIST")
        if max_hor > 0.0 and math.hypot(n, e) > max_hor:
            reason = f"{math.hypot(n, e):.0f} m from home (max {max_hor:g})"
        elif max_ver > 0.0 and -d > max_ver:
            reason = f"{-d:.0f} m above home (max {max_ver:g})"
        elif inp.geofence is not None and inp.geofence.violates((n, e, d)):
            reason = "outside the uploaded geofence"
        if reason is not None:
            out[FailsafeKind.GEOFENCE] = ("GF_ACTION", reason)
        return out

    def update(self, inp: FailsafeInputs) -> list[FailsafeEvent]:
        """Events for conditions that started this step (only while armed and in the air)."""
        now = self._conditions(inp) if (inp.armed and inp.in_air) else {}
        events = []
        for kind, (param, message) in now.items():
            if kind not in self.active:
                action = self._action(param) if param else FailsafeAction.WARN
                events.append(FailsafeEvent(kind, action, failsafe_text(kind.value, message)))
        self.active = set(now)
        return events


class PositionLossAction(IntEnum):
    """COM_POS_LOSS_ACT: what to do once GPS has been lost for COM_POS_FS_DELAY."""

    WARN = 0  # keep flying on dead reckoning
    LAND = 1  # descend on baro height without horizontal position control (PX4's "descend")


_NO_EVENTS: tuple[FailsafeEvent, ...] = ()


class SensorFailsafe:
    """Sensor-loss failsafes from :class:`EstimatorStatus` (sim time; see the module docstring).

    A source counts as lost only once it has been fused since arming; everything resets at disarm. GPS is
    lost while ``gps_fused`` is false or the filter is ``dead_reckoning``. The position-loss action comes
    ``COM_POS_FS_DELAY`` after the loss, or at once when the filter reports the horizontal position invalid
    (it can no longer dead-reckon); it is taken only in the air. GPS back before that: the flight goes on
    (the mission continues); GPS back after it: a ``cleared`` POSITION_LOSS event (the commander lands with
    position control again).
    """

    def __init__(self, params: ParamStore) -> None:
        self._params = params
        self._status: EstimatorStatus | None = None
        self._armed = False
        self._seen = [False, False, False]  # GPS, baro, mag fused since arming
        self.gps_lost_since_us: int | None = None
        self.position_action_taken = False
        self._landing = False  # the position-loss action taken was LAND
        self.baro_lost = False
        self.mag_lost = False

    def _reset(self) -> None:
        self._seen = [False, False, False]
        self.gps_lost_since_us = None
        self.position_action_taken = self._landing = False
        self.baro_lost = self.mag_lost = False

    def update(self, time_us: int, status: EstimatorStatus, armed: bool, in_air: bool) -> Sequence[FailsafeEvent]:
        """Events for the transitions at ``time_us`` (an empty tuple, no allocation, while nothing changes)."""
        if not armed:
            if self._armed:
                self._reset()
            self._armed = False
            self._status = status
            return _NO_EVENTS
        if status is self._status and self._armed and self.gps_lost_since_us is None:
            return _NO_EVENTS  # the estimator hands out the same object while nothing changed
        self._armed = True
        self._status = status
        events: list[FailsafeEvent] = []
        self._gps(time_us, status, in_air, events)
        self._baro_mag(status, events)
        return events if events else _NO_EVENTS

    def _gps(self, time_us: int, status: EstimatorStatus, in_air: bool, events: list[FailsafeEvent]) -> None:
        p = self._params.get
        gps_ok = status.gps_fused and not status.dead_reckoning
        if gps_ok:
            self._seen[0] = True
            lost_since = self.gps_lost_since_us
            if lost_since is None:
                return
            self.gps_lost_since_us = None
            after_s = (time_us - lost_since) * 1e-6
            landing = self.position_action_taken and self._landing
            self.position_action_taken = self._landing = False
            if landing:
                message = f"GPS regained after {after_s:.1f} s: position control back, landing continues"
                events.append(FailsafeEvent(FailsafeKind.POSITION_LOSS, FailsafeAction.NONE, message, cleared=True))
            else:
                message = f"GPS regained after {after_s:.1f} s: flight continues"
                events.append(FailsafeEvent(FailsafeKind.GPS_LOSS, FailsafeAction.NONE, message, cleared=True))
            return
        if not self._seen[0]:
            return
        delay_s = p("COM_POS_FS_DELAY")
        if self.gps_lost_since_us is None:
            self.gps_lost_since_us = time_us
            action = "land" if round(p("COM_POS_LOSS_ACT")) == PositionLossAction.LAND else "warn"
            message = f"GPS lost: dead reckoning, position-loss action ({action}) in {delay_s:g} s unless it returns"
            events.append(FailsafeEvent(FailsafeKind.GPS_LOSS, FailsafeAction.WARN, message))
        if self.position_action_taken or not in_air:
            return
        lost_s = (time_us - self.gps_lost_since_us) * 1e-6
        if lost_s < delay_s and status.pos_horiz_valid:
            return
        self.position_action_taken = True
        why = f"no GPS for {lost_s:.1f} s" if lost_s >= delay_s else "horizontal position invalid"
        self._landing = round(p("COM_POS_LOSS_ACT")) == PositionLossAction.LAND
        if self._landing:
            height = "baro height" if status.baro_fused else "no height source"
            message = failsafe_text(f"position lost ({why})", f"landing without position control on {height}")
            events.append(FailsafeEvent(FailsafeKind.POSITION_LOSS, FailsafeAction.LAND, message))
        else:
            message = failsafe_text(f"position lost ({why})", "still dead reckoning (COM_POS_LOSS_ACT 0)")
            events.append(FailsafeEvent(FailsafeKind.POSITION_LOSS, FailsafeAction.WARN, message))

    def _baro_mag(self, status: EstimatorStatus, events: list[FailsafeEvent]) -> None:
        if status.baro_fused:
            self._seen[1] = True
            if self.baro_lost:
                self.baro_lost = False
                events.append(FailsafeEvent(FailsafeKind.BARO_LOSS, FailsafeAction.NONE, "Baro regained", cleared=True))
        elif self._seen[1] and not self.baro_lost:
            self.baro_lost = True
            source = "height from GPS" if status.gps_fused else "no height source left"
            events.append(FailsafeEvent(FailsafeKind.BARO_LOSS, FailsafeAction.WARN, f"Baro lost: {source}"))
        if status.mag_fused:
            self._seen[2] = True
            if self.mag_lost:
                self.mag_lost = False
                events.append(FailsafeEvent(FailsafeKind.MAG_LOSS, FailsafeAction.NONE, "Mag regained", cleared=True))
        elif self._seen[2] and not self.mag_lost:
            self.mag_lost = True
            message = "Mag lost: heading from the gyro only (it drifts)"
            events.append(FailsafeEvent(FailsafeKind.MAG_LOSS, FailsafeAction.WARN, message))
