"""Traffic reports on the wire (SPEC §13): ``TrafficReport`` <-> ADSB_VEHICLE / UTM_GLOBAL_POSITION payloads.

The simulator is each vehicle's transponder receiver: manned aircraft go out as ADSB_VEHICLE (id 246) and other
quadsitl vehicles as UTM_GLOBAL_POSITION (id 340), from the receiver's component (MAV_COMP_ID_ADSB, 156), next to
its HEARTBEAT of type MAV_TYPE_ADSB. Units as MAVLink defines them:

- ADSB_VEHICLE: lat/lon degE7, altitude mm AMSL (``altitude_type`` GEOMETRIC), heading cdeg 0..35999 with 0 =
  north (course over ground; ArduPilot's SIM_ADSB convention, not PX4's receiver bug PX4#24780), horizontal speed
  cm/s, vertical speed cm/s positive UP, every valid-flag set plus SIMULATED, squawk 1200, ``tslc`` 0.
- UTM_GLOBAL_POSITION (a vehicle's own report, ``OwnPositionReport``, and the simulator's relay of it, a
  ``TrafficReport``): ``time`` = sim time (µs; the sim has no epoch), lat/lon degE7, alt mm AMSL (quadsitl has no
  geoid: MAVLink's WGS-84 height is taken as AMSL), vx/vy/vz cm/s NED (positive DOWN), ``h_acc``/``v_acc`` mm and
  ``vel_acc`` cm/s 1-sigma (UINT16_MAX: unknown), ``next_lat``/``next_lon``/``next_alt`` the next waypoint (flag
  NEXT_WAYPOINT_AVAILABLE), ``update_rate`` cs between reports (0: unknown), ``flight_state`` UTM_FLIGHT_STATE,
  ``uas_id`` = ``UAS_ID_PREFIX`` then the sender's MAV_SYS_ID big-endian in the last 4 bytes.

Decoding is the reverse; an ADSB_VEHICLE carries no time, so its report comes back with ``t_us = 0`` and the
lockstep client stamps it with the time of the frame it came in. A report that cannot be used (no valid
coordinates or altitude, latitude/longitude out of range) is dropped (None); ``utm_problem`` says why in one line.
A next waypoint out of range is dropped alone (the report stays, without intent). Only ``mavlink_bridge`` imports
this module.
"""

from __future__ import annotations

import math
import struct

from mavlink_bridge.contract.frames import DEG_E7
from mavlink_bridge.contract.traffic import (
    AdsbEmitterType,
    OwnPositionReport,
    TrafficReport,
    TrafficSource,
    UtmFlightState,
)
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
_UTM_TIME = _dialect.UTM_DATA_AVAIL_FLAGS_TIME_VALID
_UTM_UAS_ID = _dialect.UTM_DATA_AVAIL_FLAGS_UAS_ID_AVAILABLE
_UTM_POSITION = _dialect.UTM_DATA_AVAIL_FLAGS_POSITION_AVAILABLE
_UTM_ALTITUDE = _dialect.UTM_DATA_AVAIL_FLAGS_ALTITUDE_AVAILABLE
_UTM_RELATIVE_ALT = _dialect.UTM_DATA_AVAIL_FLAGS_RELATIVE_ALTITUDE_AVAILABLE
_UTM_VEL_H = _dialect.UTM_DATA_AVAIL_FLAGS_HORIZONTAL_VELO_AVAILABLE
_UTM_VEL_V = _dialect.UTM_DATA_AVAIL_FLAGS_VERTICAL_VELO_AVAILABLE
_UTM_NEXT_WP = _dialect.UTM_DATA_AVAIL_FLAGS_NEXT_WAYPOINT_AVAILABLE
#: UTM_GLOBAL_POSITION flags every quadsitl report sets: time, uas id, position, altitude, both velocities.
UTM_FLAGS_SIM = _UTM_TIME | _UTM_UAS_ID | _UTM_POSITION | _UTM_ALTITUDE | _UTM_VEL_H | _UTM_VEL_V
_UTM_NEEDED = _UTM_POSITION | _UTM_ALTITUDE
_U16_UNKNOWN = 0xFFFF
#: The first bytes of a quadsitl vehicle's 18-byte UAS id (the MAV_SYS_ID follows in the last 4 bytes).
UAS_ID_PREFIX = b"QSITL"
_UAS_ID_LEN = 18
_EMITTERS = {int(e): e for e in AdsbEmitterType}
_FLIGHT_STATES = {int(e): e for e in UtmFlightState}
_I32 = (-(2**31), 2**31 - 1)
_I16 = (-(2**15), 2**15 - 1)
_U16 = (0, _U16_UNKNOWN - 1)


def _sat(x: float, bounds: tuple[int, int]) -> int:
    lo, hi = bounds
    return lo if not x >= lo else hi if not x <= hi else round(x)  # NaN -> lo


def _u16_or_unknown(x: float) -> int:
    """A non-negative accuracy on the wire; NaN (unknown) -> UINT16_MAX."""
    return _U16_UNKNOWN if not math.isfinite(x) else _sat(x, _U16)


def _acc_from_u16(raw: int, scale: float) -> float:
    return math.nan if raw == _U16_UNKNOWN else raw / scale


def uas_id_bytes(sys_id: int) -> bytes:
    """The 18-byte UAS id of the quadsitl vehicle with MAV_SYS_ID ``sys_id``."""
    return UAS_ID_PREFIX + bytes(_UAS_ID_LEN - len(UAS_ID_PREFIX) - 4) + (sys_id & 0xFFFFFFFF).to_bytes(4, "big")


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


def _utm_pack(
    t_us: int,
    sys_id: int,
    lat_lon_alt: tuple[float, float, float],
    vel_ned: tuple[float, float, float],
    acc: tuple[float, float, float],
    relative_alt_m: float,
    next_wp: tuple[float, float, float],
    update_rate_hz: float,
    flight_state: int,
) -> bytes:
    lat, lon, alt = lat_lon_alt
    flags = UTM_FLAGS_SIM
    relative = 0
    if math.isfinite(relative_alt_m):
        relative = _sat(relative_alt_m * 1000.0, _I32)
        flags |= _UTM_RELATIVE_ALT
    next_lat = next_lon = next_alt = 0
    if all(math.isfinite(x) for x in next_wp):
        next_lat, next_lon = _sat(next_wp[0] * DEG_E7, _I32), _sat(next_wp[1] * DEG_E7, _I32)
        next_alt = _sat(next_wp[2] * 1000.0, _I32)
        flags |= _UTM_NEXT_WP
    rate_cs = _sat(100.0 / update_rate_hz, _U16) if update_rate_hz > 0.0 and math.isfinite(update_rate_hz) else 0
    return UTM_GLOBAL_POSITION.payload.pack(
        max(int(t_us), 0),
        _sat(lat * DEG_E7, _I32),
        _sat(lon * DEG_E7, _I32),
        _sat(alt * 1000.0, _I32),
        relative,
        next_lat,
        next_lon,
        next_alt,
        _sat(vel_ned[0] * 100.0, _I16),
        _sat(vel_ned[1] * 100.0, _I16),
        _sat(vel_ned[2] * 100.0, _I16),
        _u16_or_unknown(acc[0] * 1000.0),
        _u16_or_unknown(acc[1] * 1000.0),
        _u16_or_unknown(acc[2] * 100.0),
        rate_cs,
        *uas_id_bytes(sys_id),
        int(flight_state) & 0xFF,
        flags,
    )


def utm_payload(r: TrafficReport) -> bytes:
    """UTM_GLOBAL_POSITION payload of another vehicle's report as the simulator relays it (``target_id`` is its
    MAV_SYS_ID; its intent and accuracies as the vehicle sent them)."""
    return _utm_pack(
        r.t_us,
        r.target_id,
        (r.lat_deg, r.lon_deg, r.alt_amsl_m),
        (r.vel_n_m_s, r.vel_e_m_s, r.vel_d_m_s),
        (r.h_acc_m, r.v_acc_m, math.nan),
        math.nan,
        (r.next_lat_deg, r.next_lon_deg, r.next_alt_amsl_m),
        r.update_rate_hz,
        r.flight_state,
    )


def own_position_payload(r: OwnPositionReport) -> bytes:
    """UTM_GLOBAL_POSITION payload of an autopilot's own report (see the module docstring)."""
    return _utm_pack(
        r.t_us,
        r.sys_id,
        (r.lat_deg, r.lon_deg, r.alt_amsl_m),
        (r.vel_n_m_s, r.vel_e_m_s, r.vel_d_m_s),
        (r.h_acc_m, r.v_acc_m, r.vel_acc_m_s),
        r.relative_alt_m,
        (r.next_lat_deg, r.next_lon_deg, r.next_alt_amsl_m),
        r.update_rate_hz,
        r.flight_state,
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
_LAT_E7, _LON_E7 = 90 * 10**7, 180 * 10**7


def utm_problem(buf: bytes, at: int) -> str | None:
    """Why the UTM_GLOBAL_POSITION payload at ``buf[at:]`` cannot be used (one line), or None when it can."""
    t, lat, lon, *_ = _UTM_HEAD.unpack_from(buf, at)
    flags = buf[at + _UTM_HEAD.size + _UAS_ID_LEN + 1]
    if flags & _UTM_NEEDED != _UTM_NEEDED:
        return f"UTM_GLOBAL_POSITION: position or altitude not flagged available (flags 0x{flags:02x})"
    if not (-_LAT_E7 <= lat <= _LAT_E7 and -_LON_E7 <= lon <= _LON_E7):
        return f"UTM_GLOBAL_POSITION: latitude/longitude out of range ({lat / DEG_E7}, {lon / DEG_E7})"
    if t >= 2**53:
        return f"UTM_GLOBAL_POSITION: time {t} us is beyond any simulator time"
    return None


def decode_utm(buf: bytes, at: int) -> TrafficReport | None:
    """UTM_GLOBAL_POSITION -> a UAV report (``target_id`` from the last 4 bytes of ``uas_id``); None when
    ``utm_problem`` finds one. Velocities not flagged available are 0; a next waypoint out of range is left out."""
    if utm_problem(buf, at) is not None:
        return None
    t, lat, lon, alt, _rel, nlat, nlon, nalt, vx, vy, vz, h_acc, v_acc, _vel_acc, rate_cs = _UTM_HEAD.unpack_from(
        buf, at
    )
    uas_at = at + _UTM_HEAD.size
    uas_id = bytes(buf[uas_at : uas_at + _UAS_ID_LEN])
    state, flags = buf[uas_at + _UAS_ID_LEN], buf[uas_at + _UAS_ID_LEN + 1]
    vel_h, vel_v = (1.0 if flags & _UTM_VEL_H else 0.0), (1.0 if flags & _UTM_VEL_V else 0.0)
    next_wp = (math.nan, math.nan, math.nan)
    if flags & _UTM_NEXT_WP and -_LAT_E7 <= nlat <= _LAT_E7 and -_LON_E7 <= nlon <= _LON_E7:
        next_wp = (nlat / DEG_E7, nlon / DEG_E7, nalt / 1000.0)
    return TrafficReport(
        TrafficSource.UAV,
        int.from_bytes(uas_id[-4:], "big"),
        "",
        AdsbEmitterType.UAV,
        lat / DEG_E7,
        lon / DEG_E7,
        alt / 1000.0,
        vel_h * vx / 100.0,
        vel_h * vy / 100.0,
        vel_v * vz / 100.0,
        t,
        *next_wp,
        _FLIGHT_STATES.get(state, UtmFlightState.UNKNOWN),
        100.0 / rate_cs if rate_cs else math.nan,
        _acc_from_u16(h_acc, 1000.0),
        _acc_from_u16(v_acc, 1000.0),
    )
