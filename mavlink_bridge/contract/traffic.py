"""Traffic reports: what a vehicle's transponder receiver tells its autopilot (SPEC §13).

The simulator is every vehicle's receiver. It reports the other quadsitl vehicles as ``UTM_GLOBAL_POSITION``
and scripted manned aircraft as ``ADSB_VEHICLE`` on the vehicle's sim link; the bridge decodes either into one
``TrafficReport`` in SI units, so the autopilot's traffic avoidance never sees MAVLink. Positions are geodetic
(WGS-84, altitude above mean sea level), velocities NED.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import IntEnum


class TrafficSource(IntEnum):
    """Where a report came from, which sets the separation volume the autopilot keeps."""

    UAV = 0  # UTM_GLOBAL_POSITION from another unmanned vehicle
    MANNED = 1  # ADSB_VEHICLE from a manned aircraft


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
    never reports its own vehicle. ``t_us`` is the simulator time of the position fix.
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
