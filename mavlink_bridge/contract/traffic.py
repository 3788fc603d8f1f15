"""Traffic reports: what a vehicle's transponder receiver tells its autopilot (SPEC §13).

The simulator is every vehicle's receiver. It reports the other quadsitl vehicles as ``UTM_GLOBAL_POSITION``
and scripted manned aircraft as ``ADSB_VEHICLE`` on the vehicle's sim link; the bridge decodes either into one
``TrafficReport`` in SI units, so the autopilot's traffic avoidance never sees MAVLink. Positions are geodetic
(WGS-84, altitude above mean sea level), velocities NED.

Each autopilot also sends its own position, velocity and intent (``OwnPositionReport``) as ``UTM_GLOBAL_POSITION`` on
its sim link; the simulator relays it to the other vehicles' receivers as a UTM service would (SPEC §13), where it
comes back as a ``TrafficReport`` with the intent fields filled in.

Accuracies (``h_acc_m``, ``v_acc_m``, ``vel_acc_m_s``) are **1-sigma** (standard deviations), as MAVLink defines
UTM_GLOBAL_POSITION's ``h_acc``/``v_acc``/``vel_acc``; NaN when unknown (ADSB_VEHICLE carries none).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import IntEnum


class TrafficSource(IntEnum):
    """Where a report came from, which sets the separation volume the autopilot keeps."""

    UAV = 0  # UTM_GLOBAL_POSITION from another unmanned vehicle
    MANNED = 1  # ADSB_VEHICLE from a manned aircraft


class UtmFlightState(IntEnum):
    """MAVLink UTM_FLIGHT_STATE: what a UAS says it is doing (UTM_GLOBAL_POSITION ``flight_state``)."""

    UNKNOWN = 1  # the state cannot be determined (PX4: disarmed)
    GROUND = 2  # on the ground, armed
    AIRBORNE = 3  # in the air
    EMERGENCY = 16  # an emergency flight (a failsafe in force)
    NOCTRL = 32  # no control over the flight


class AdsbEmitterType(IntEnum):
    """MAVLink ADSB_EMITTER_TYPE (the values the simulator's scripted traffic uses)."""

    NO_INFO = 0
    LIGHT = 1
    SMALL = 2
    LARGE = 3
    HIGH_VORTEX_LARGE = 4
    HEAVY = 5
    HIGHLY_MANUV = 6
    ROTOCRAFT = 7
    UNASSIGNED = 8
    GLIDER = 9
    LIGHTER_AIR = 10
    PARACHUTE = 11
    ULTRA_LIGHT = 12
    UNASSIGNED2 = 13
    UAV = 14
    SPACE = 15
    UNASSGINED3 = 16
    EMERGENCY_SURFACE = 17
    SERVICE_SURFACE = 18
    POINT_OBSTACLE = 19


@dataclass(frozen=True, slots=True)
class TrafficReport:
    """One received traffic target at one time.

    ``target_id`` is the ICAO address (manned) or the sender's uas id (another vehicle's MAV_SYS_ID); a receiver
    never reports its own vehicle. ``t_us`` is the simulator time of the position fix as the report says it (a UTM
    report: the sender's estimate time; ADS-B carries no time: the frame it arrived with, so its latency is
    invisible to the receiver, as on a real 1090ES/UAT link).

    Intent and quality (UTM_GLOBAL_POSITION only; ADS-B reports keep the defaults): ``next_*`` is the sender's
    next waypoint (NaN: none announced), ``flight_state`` what it says it is doing, ``update_rate_hz`` how often it
    reports (NaN: unknown / data driven), ``h_acc_m``/``v_acc_m`` 1-sigma position accuracy of its own estimate
    (NaN: unknown).
    """

    source: TrafficSource
    target_id: int
    callsign: str
    emitter: AdsbEmitterType
    lat_deg: float
    lon_deg: float
    alt_amsl_m: float
    vel_n_m_s: float
    vel_e_m_s: float
    vel_d_m_s: float
    t_us: int
    next_lat_deg: float = math.nan
    next_lon_deg: float = math.nan
    next_alt_amsl_m: float = math.nan
    flight_state: UtmFlightState = UtmFlightState.UNKNOWN
    update_rate_hz: float = math.nan
    h_acc_m: float = math.nan
    v_acc_m: float = math.nan

    @property
    def has_next_waypoint(self) -> bool:
        """True when the report announces a finite next waypoint."""
        return (
            math.isfinite(self.next_lat_deg)
            and math.isfinite(self.next_lon_deg)
            and math.isfinite(self.next_alt_amsl_m)
        )


@dataclass(frozen=True, slots=True)
class OwnPositionReport:
    """What an autopilot says about itself on its traffic link (UTM_GLOBAL_POSITION; SPEC §13): its **estimate**
    (not the truth), at sim time ``t_us``, geodetic (altitude AMSL), NED velocity.

    ``h_acc_m``/``v_acc_m``/``vel_acc_m_s``: 1-sigma accuracies from the estimator (NaN: unknown); ``next_*``: the
    waypoint it is flying to (NaN: none, e.g. not in an autonomous mode); ``update_rate_hz``: how often it sends
    (the ``update_rate`` field says so).
    """

    t_us: int
    sys_id: int
    lat_deg: float
    lon_deg: float
    alt_amsl_m: float
    vel_n_m_s: float
    vel_e_m_s: float
    vel_d_m_s: float
    flight_state: UtmFlightState
    update_rate_hz: float
    h_acc_m: float = math.nan
    v_acc_m: float = math.nan
    vel_acc_m_s: float = math.nan
    relative_alt_m: float = math.nan  # height above home (NaN: unknown)
    next_lat_deg: float = math.nan
    next_lon_deg: float = math.nan
    next_alt_amsl_m: float = math.nan
