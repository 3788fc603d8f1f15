"""Traffic reports on the wire (SPEC §13): ``TrafficReport`` <-> ADSB_VEHICLE / UTM_GLOBAL_POSITION payloads.

The simulator is each vehicle's transponder receiver: manned aircraft go out as ADSB_VEHICLE (id 246) and other
quadsitl vehicles as UTM_GLOBAL_POSITION (id 340), from the receiver's component (MAV_COMP_ID_ADSB, 156), next to
its HEARTBEAT of type MAV_TYPE_ADSB. Units as MAVLink defines them:

- ADSB_VEHICLE: lat/lon degE7, altitude mm AMSL (``altitude_type`` GEOMETRIC), heading cdeg 0..35999 with 0 =
  north (course over ground; ArduPilot's SIM_ADSB convention, not PX4's receiver bug PX4#24780), horizontal speed
  cm/s, vertical speed cm/s positive UP, every valid-flag set plus SIMULATED, squawk 1200, ``tslc`` 0.
- UTM_GLOBAL_POSITION: ``time`` = sim time (µs; the sim has no epoch), lat/lon degE7, alt mm AMSL, vx/vy/vz cm/s
  NED (positive DOWN), ``uas_id`` = ``UAS_ID_PREFIX`` then the sender's MAV_SYS_ID big-endian in the last 4 bytes.

Decoding is the reverse; an ADSB_VEHICLE carries no time, so its report comes back with ``t_us = 0`` and the
lockstep client stamps it with the time of the frame it came in. Reports without valid coordinates or altitude
are dropped (None). Only ``mavlink_bridge`` imports this module.
"""

from __future__ import annotations

import math
import struct

from mavlink_bridge.contract.frames import DEG_E7
from mavlink_bridge.contract.traffic import AdsbEmitterType, TrafficReport, TrafficSource
from mavlink_bridge.wire.framing import _dialect, _layout

ADSB_VEHICLE = _layout(_dialect.MAVLink_adsb_vehicle_message)
UTM_GLOBAL_POSITION = _layout(_dialect.MAVLink_utm_global_position_message)
MAV_TYPE_ADSB = _dialect.MAV_TYPE_ADSB  # 27
MAV_COMP_ID_ADSB = _dialect.MAV_COMP_ID_ADSB  # 156
#: ADSB_VEHICLE flags the simulator sets: coords, altitude, heading, velocity, callsign, squawk, SIMULATED,
#: vertical velocity.
ADSB_FLAGS_SIM = (
    _dialect.ADSB_FLAGS_VALID_COORDS
    | _dialect.ADSB_FLAGS_VALID_ALTITUDE
    | _dialect.ADSB_FLAGS_VALID_HEADING
    | _dialect.ADSB_FLAGS_VALID_VELOCITY
    | _dialect.ADSB_FLAGS_VALID_CALLSIGN
    | _dialect.ADSB_FLAGS_VALID_SQUAWK
    | _dialect.ADSB_FLAGS_SIMULATED
    | _dialect.ADSB_FLAGS_VERTICAL_VELOCITY_VALID
)
ADSB_FLAGS_SIMULATED = _dialect.ADSB_FLAGS_SIMULATED
_ADSB_NEEDED = _dialect.ADSB_FLAGS_VALID_COORDS | _dialect.ADSB_FLAGS_VALID_ALTITUDE
_ADSB_MOTION = _dialect.ADSB_FLAGS_VALID_HEADING | _dialect.ADSB_FLAGS_VALID_VELOCITY
_ADSB_ALT_GEOMETRIC = _dialect.ADSB_ALTITUDE_TYPE_GEOMETRIC
_SQUAWK_VFR = 1200
#: UTM_GLOBAL_POSITION flags: time, uas id, position, altitude, horizontal and vertical velocity.
UTM_FLAGS_SIM = (
    _dialect.UTM_DATA_AVAIL_FLAGS_TIME_VALID
    | _dialect.UTM_DATA_AVAIL_FLAGS_UAS_ID_AVAILABLE
    | _dialect.UTM_DATA_AVAIL_FLAGS_POSITION_AVAILABLE
    | _dialect.UTM_DATA_AVAIL_FLAGS_ALTITUDE_AVAILABLE
    | _dialect.UTM_DATA_AVAIL_FLAGS_HORIZONTAL_VELO_AVAILABLE
    | _dialect.UTM_DATA_AVAIL_FLAGS_VERTICAL_VELO_AVAILABLE
)
_UTM_NEEDED = _dialect.UTM_DATA_AVAIL_FLAGS_POSITION_AVAILABLE | _dialect.UTM_DATA_AVAIL_FLAGS_ALTITUDE_AVAILABLE
_UTM_STATE_AIRBORNE = _dialect.UTM_FLIGHT_STATE_AIRBORNE
_UTM_UPDATE_RATE_CS = 100  # one report a second
#: The first bytes of a quadsitl vehicle's 18-byte UAS id (the MAV_SYS_ID follows in the last 4 bytes).
UAS_ID_PREFIX = b"QSITL"
_UAS_ID_LEN = 18
_EMITTERS = {int(e): e for e in AdsbEmitterType}
_I32 = (-(2**31), 2**31 - 1)
_I16 = (-(2**15), 2**15 - 1)


def _sat(x: float, bounds: tuple[int, int]) -> int:
    lo, hi = bounds
    return lo if not x >= lo else hi if not x <= hi else round(x)  # NaN -> lo


def uas_id_bytes(sys_id: int) -> bytes:
    """The 18-byte UAS id of the quadsitl vehicle with MAV_SYS_ID ``sys_id``."""
    return UAS_ID_PREFIX + bytes(_UAS_ID_LEN - len(UAS_ID_PREFIX) - 4) + sys_id.to_bytes(4, "big")


def adsb_payload(r: TrafficReport) -> bytes:
    """ADSB_VEHICLE payload of a manned-traffic report (see the module docstring for units and flags)."""
    vn, ve = r.vel_n_m_s, r.vel_e_m_s
    heading_cdeg = round(math.degrees(math.atan2(ve, vn)) * 100.0) % 36000
    callsign = r.callsign.encode("ascii", "replace")[:8].ljust(9, b"\x00")
    return ADSB_VEHICLE.payload.pack(
        r.target_id & 0xFFFFFFFF,
        _sat(r.lat_deg * DEG_E7, _I32),
        _sat(r.lon_deg * DEG_E7, _I32),
        _sat(r.alt_amsl_m * 1000.0, _I32),
        heading_cdeg,
        _sat(math.hypot(vn, ve) * 100.0, (0, 0xFFFF)),
        _sat(-r.vel_d_m_s * 100.0, _I16),
        ADSB_FLAGS_SIM,
        _SQUAWK_VFR,
        _ADSB_ALT_GEOMETRIC,
        callsign,
        int(r.emitter),
        0,
    )


def utm_payload(r: TrafficReport) -> bytes:
    """UTM_GLOBAL_POSITION payload of another vehicle's report (``target_id`` is its MAV_SYS_ID)."""
    return UTM_GLOBAL_POSITION.payload.pack(
        r.t_us,
        _sat(r.lat_deg * DEG_E7, _I32),
        _sat(r.lon_deg * DEG_E7, _I32),
        _sat(r.alt_amsl_m * 1000.0, _I32),
        0,  # relative_alt (not flagged available)
        0,  # next_lat, next_lon, next_alt: no next waypoint (flag not set)
        0,
        0,
        _sat(r.vel_n_m_s * 100.0, _I16),
        _sat(r.vel_e_m_s * 100.0, _I16),
        _sat(r.vel_d_m_s * 100.0, _I16),
        0,  # h_acc, v_acc, vel_acc: unknown
        0,
        0,
        _UTM_UPDATE_RATE_CS,
        *uas_id_bytes(r.target_id),
        _UTM_STATE_AIRBORNE,
        UTM_FLAGS_SIM,
    )


def decode_adsb(buf: bytes, at: int) -> TrafficReport | None:
    """ADSB_VEHICLE -> a MANNED report (``t_us`` 0: stamped by the receiver), None without a usable position."""
    icao, lat, lon, alt, heading, hor, ver, flags, _squawk, _alt_type, callsign, emitter, _tslc = (
        ADSB_VEHICLE.payload.unpack_from(buf, at)
    )
    if flags & _ADSB_NEEDED != _ADSB_NEEDED:
        return None
    speed = hor / 100.0 if flags & _ADSB_MOTION == _ADSB_MOTION else 0.0
    course = math.radians(heading / 100.0)
    vel_d = -ver / 100.0 if flags & _dialect.ADSB_FLAGS_VERTICAL_VELOCITY_VALID else 0.0
    name = callsign.split(b"\x00", 1)[0].decode("ascii", "replace").strip()
    return TrafficReport(
        TrafficSource.MANNED,
        icao,
        name,
        _EMITTERS.get(emitter, AdsbEmitterType.NO_INFO),
        lat / DEG_E7,
        lon / DEG_E7,
        alt / 1000.0,
        speed * math.cos(course),
        speed * math.sin(course),
        vel_d,
        0,
    )


_UTM_HEAD = struct.Struct("<QiiiiiiihhhHHHH")


def decode_utm(buf: bytes, at: int) -> TrafficReport | None:
    """UTM_GLOBAL_POSITION -> a UAV report (``target_id`` from the last 4 bytes of ``uas_id``)."""
    t, lat, lon, alt, _rel, _nlat, _nlon, _nalt, vx, vy, vz, _h, _v, _va, _rate = _UTM_HEAD.unpack_from(buf, at)
    uas_at = at + _UTM_HEAD.size
    uas_id = bytes(buf[uas_at : uas_at + _UAS_ID_LEN])
    flags = buf[uas_at + _UAS_ID_LEN + 1]
    if flags & _UTM_NEEDED != _UTM_NEEDED:
        return None
    return TrafficReport(
        TrafficSource.UAV,
        int.from_bytes(uas_id[-4:], "big"),
        "",
        AdsbEmitterType.UAV,
        lat / DEG_E7,
        lon / DEG_E7,
        alt / 1000.0,
        vx / 100.0,
        vy / 100.0,
        vz / 100.0,
        t,
    )
