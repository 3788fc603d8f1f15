"""Standard telemetry of ANY MAVLink vehicle, decoded into typed events (for ``tools/monitor.py``).

Nothing here is specific to quadsitl: HEARTBEAT (type, autopilot, mode string as pymavlink
names it for PX4 and ArduPilot, armed), ATTITUDE, LOCAL_POSITION_NED, GLOBAL_POSITION_INT,
MISSION_CURRENT, MISSION_ITEM_REACHED and STATUSTEXT. The listener binds or sends per a
pymavlink-style URL (``udpin:HOST:PORT`` / ``udpout:HOST:PORT``), announces itself with a GCS
heartbeat once a second (some vehicles only stream to a GCS they have heard), and never
raises on what arrives: malformed datagrams are counted and dropped.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

from pymavlink import mavutil

from mavlink_bridge.wire.codec import make_mavlink
from mavlink_bridge.wire.link import UdpLink

GCS_SYSTEM_ID = 255
GCS_COMPONENT_ID = 190  # MAV_COMP_ID_MISSIONPLANNER
_MAV_TYPE_GCS = 6
_MAV_AUTOPILOT_INVALID = 8
_MAV_MODE_FLAG_SAFETY_ARMED = 128


@dataclass(frozen=True, slots=True)
class VehicleHeartbeat:
    """HEARTBEAT of a vehicle: ``mode`` is pymavlink's name for its base/custom mode (e.g. ``AUTO.MISSION``)."""

    system_id: int
    component_id: int
    mav_type: int
    autopilot: int
    base_mode: int
    custom_mode: int
    system_status: int
    armed: bool
    mode: str


@dataclass(frozen=True, slots=True)
class Attitude:
    """ATTITUDE: ZYX Euler angles (rad) and body rates (rad/s), ``time_boot_ms`` of the vehicle."""

    system_id: int
    time_boot_ms: int
    roll_rad: float
    pitch_rad: float
    yaw_rad: float
    rate_frd_rad_s: tuple[float, float, float]


@dataclass(frozen=True, slots=True)
class LocalPosition:
    """LOCAL_POSITION_NED (m, m/s)."""

    system_id: int
    time_boot_ms: int
    pos_ned_m: tuple[float, float, float]
    vel_ned_m_s: tuple[float, float, float]


@dataclass(frozen=True, slots=True)
class GlobalPosition:
    """GLOBAL_POSITION_INT in SI units (degrees, metres, m/s); ``heading_deg`` NaN when unknown."""

    system_id: int
    time_boot_ms: int
    lat_deg: float
    lon_deg: float
    alt_amsl_m: float
    alt_rel_m: float
    vel_ned_m_s: tuple[float, float, float]
    heading_deg: float


@dataclass(frozen=True, slots=True)
class MissionCurrent:
    """MISSION_CURRENT: the active item (``total``/``mission_state`` 0 when the sender omits them)."""

    system_id: int
    seq: int
    total: int
    mission_state: int


@dataclass(frozen=True, slots=True)
class MissionItemReached:
    """MISSION_ITEM_REACHED."""

    system_id: int
    seq: int


@dataclass(frozen=True, slots=True)
class StatusTextEvent:
    """STATUSTEXT (MAV_SEVERITY 0 emergency .. 7 debug)."""

    system_id: int
    severity: int
    text: str


TelemetryEvent = (
    VehicleHeartbeat | Attitude | LocalPosition | GlobalPosition | MissionCurrent | MissionItemReached | StatusTextEvent
)


def _opt(msg: object, name: str, default: int = 0) -> int:
    value = getattr(msg, name, default)
    return int(value) if value is not None else default


def decode_message(msg: object) -> TelemetryEvent | None:
    """The typed event for one pymavlink message (None for anything else, including GCS heartbeats)."""
    kind = msg.get_type()  # type: ignore[attr-defined]
    sysid = msg.get_srcSystem()  # type: ignore[attr-defined]
    m = msg
    if kind == "HEARTBEAT":
        if m.type == _MAV_TYPE_GCS:  # type: ignore[attr-defined]
            return None
        return VehicleHeartbeat(
            sysid,
            msg.get_srcComponent(),  # type: ignore[attr-defined]
            m.type,  # type: ignore[attr-defined]
            m.autopilot,  # type: ignore[attr-defined]
            m.base_mode,  # type: ignore[attr-defined]
            m.custom_mode,  # type: ignore[attr-defined]
            m.system_status,  # type: ignore[attr-defined]
            bool(m.base_mode & _MAV_MODE_FLAG_SAFETY_ARMED),  # type: ignore[attr-defined]
            mavutil.mode_string_v10(m),
        )
    if kind == "ATTITUDE":
        return Attitude(
            sysid,
            m.time_boot_ms,  # type: ignore[attr-defined]
            m.roll,  # type: ignore[attr-defined]
            m.pitch,  # type: ignore[attr-defined]
            m.yaw,  # type: ignore[attr-defined]
            (m.rollspeed, m.pitchspeed, m.yawspeed),  # type: ignore[attr-defined]
        )
    if kind == "LOCAL_POSITION_NED":
        return LocalPosition(
            sysid,
            m.time_boot_ms,  # type: ignore[attr-defined]
            (m.x, m.y, m.z),  # type: ignore[attr-defined]
            (m.vx, m.vy, m.vz),  # type: ignore[attr-defined]
        )
    if kind == "GLOBAL_POSITION_INT":
        hdg = m.hdg  # type: ignore[attr-defined]
        return GlobalPosition(
            sysid,
            m.time_boot_ms,  # type: ignore[attr-defined]
            m.lat / 1e7,  # type: ignore[attr-defined]
            m.lon / 1e7,  # type: ignore[attr-defined]
            m.alt / 1000.0,  # type: ignore[attr-defined]
            m.relative_alt / 1000.0,  # type: ignore[attr-defined]
            (m.vx / 100.0, m.vy / 100.0, m.vz / 100.0),  # type: ignore[attr-defined]
            math.nan if hdg == 65535 else hdg / 100.0,
        )
    if kind == "MISSION_CURRENT":
        return MissionCurrent(sysid, m.seq, _opt(m, "total"), _opt(m, "mission_state"))  # type: ignore[attr-defined]
    if kind == "MISSION_ITEM_REACHED":
        return MissionItemReached(sysid, m.seq)  # type: ignore[attr-defined]
    if kind == "STATUSTEXT":
        text = m.text  # type: ignore[attr-defined]
        if isinstance(text, bytes):
            text = text.decode("utf-8", "replace")
        return StatusTextEvent(sysid, m.severity, text.rstrip("\x00"))  # type: ignore[attr-defined]
    return None


class TelemetryListener:
    """Receives any vehicle's standard telemetry on a UDP link and yields typed events."""

    def __init__(self, url: str, *, heartbeat_period_s: float = 1.0) -> None:
        self._link = UdpLink.from_url(url)
        self._mav = make_mavlink(GCS_SYSTEM_ID, GCS_COMPONENT_ID)
        self._heartbeat_period_s = heartbeat_period_s
        self._next_heartbeat_s = 0.0
        self.datagrams = 0
        self.messages = 0
        self.bad_datagrams = 0

    @property
    def local_address(self) -> tuple[str, int]:
        return self._link.local_address

    def _heartbeat(self) -> None:
        now = time.monotonic()
        if now >= self._next_heartbeat_s:
            self._next_heartbeat_s = now + self._heartbeat_period_s
            msg = self._mav.heartbeat_encode(_MAV_TYPE_GCS, _MAV_AUTOPILOT_INVALID, 0, 0, 0)
            self._link.send(msg.pack(self._mav))

    def poll(self, timeout_s: float) -> list[TelemetryEvent]:
        """Events from the datagrams that arrive within ``timeout_s`` (at most one wait, then drain)."""
        self._heartbeat()
        events: list[TelemetryEvent] = []
        wait = timeout_s
        while True:
            data = self._link.recv(wait)
            if data is None:
                return events
            wait = 0.0
            self.datagrams += 1
            mav = self._mav
            try:
                msgs = mav.parse_buffer(data) or []
            except Exception:  # pymavlink raises assorted errors on garbage: drop the datagram
                msgs = []
                self.bad_datagrams += 1
            # A datagram carries whole packets: drop any partial tail so it cannot swallow the next one.
            mav.buf = bytearray()
            mav.buf_index = 0
            mav.expected_length = mavutil.mavlink.HEADER_LEN_V1 + 2
            mav.have_prefix_error = False
            for msg in msgs:
                if msg.get_type() == "BAD_DATA":
                    self.bad_datagrams += 1
                    continue
                self.messages += 1
                event = decode_message(msg)
                if event is not None:
                    events.append(event)

    def close(self) -> None:
        self._link.close()

    def __enter__(self) -> TelemetryListener:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
