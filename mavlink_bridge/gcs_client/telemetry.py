"""The ground station's view of the vehicle: telemetry messages folded into a frozen VehicleStatus."""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass

from pymavlink.dialects.v20 import common as mavlink2

from mavlink_bridge.contract.frames import GeoPoint, deg_from_deg_e7
from mavlink_bridge.contract.vehicle_api import FlightMode, LandedState, Severity, StatusText

Msg = mavlink2.MAVLink_message
M = mavlink2
_STATUSTEXT_KEEP = 200


@dataclass(frozen=True, slots=True)
class VehicleStatus:
    """The latest telemetry, decoded. ``None``/empty until the matching message has arrived."""

    heartbeat_received: bool
    armed: bool
    mode: FlightMode | None
    mode_name: str
    system_status: int
    landed_state: LandedState
    sim_time_s: float | None
    pos_ned_m: tuple[float, float, float] | None
    vel_ned_m_s: tuple[float, float, float] | None
    lat_deg: float | None
    lon_deg: float | None
    alt_rel_m: float | None
    home: GeoPoint | None
    gps_fix_type: int  # GPS_FIX_TYPE (0 = no GPS yet, 3 = 3D fix)
    battery_remaining_pct: float | None
    mission_seq_current: int
    mission_count: int
    mission_state: int  # MISSION_STATE: 0 unknown, 1 none, 2 not started, 3 active, 4 paused, 5 complete
    items_reached: tuple[int, ...]  # each reached item once, in the order first reported
    statustexts: tuple[StatusText, ...]


def _mode_from_custom(custom_mode: int) -> FlightMode | None:
    try:
        return FlightMode.from_px4((custom_mode >> 16) & 0xFF, (custom_mode >> 24) & 0xFF)
    except ValueError:
        return None


class TelemetryState:
    """The latest telemetry of one vehicle component, updated message by message (:meth:`update`)."""

    def __init__(self, target_component: int) -> None:
        self.target_component = target_component
        self._heartbeat = False
        self._armed = False
        self._mode: FlightMode | None = None
        self._mode_name = ""
        self._system_status = 0
        self._landed = LandedState.UNDEFINED
        self._sim_time_s: float | None = None
        self._pos: tuple[float, float, float] | None = None
        self._vel: tuple[float, float, float] | None = None
        self._lat: float | None = None
        self._lon: float | None = None
        self._alt_rel: float | None = None
        self._home: GeoPoint | None = None
        self._battery: float | None = None
        self._gps_fix_type = 0
        self._mission_seq = 0
        self._mission_count = 0
        self._mission_state = 0
        self._reached: list[int] = []
        self._reached_set: set[int] = set()
        self._texts: deque[StatusText] = deque(maxlen=_STATUSTEXT_KEEP)
        self._text_serial = 0  # counts every STATUSTEXT ever received (for "since" queries)
        self._chunks: dict[int, list[str]] = {}

    @property
    def home(self) -> GeoPoint | None:
        return self._home

    @property
    def text_serial(self) -> int:
        """Counts every STATUSTEXT ever received (for "since" queries)."""
        return self._text_serial

    def latest_text(self) -> str | None:
        """The text of the latest STATUSTEXT kept (None before the first)."""
        return self._texts[-1].text if self._texts else None

    def status(self) -> VehicleStatus:
        """The latest decoded state."""
        return VehicleStatus(
            heartbeat_received=self._heartbeat,
            armed=self._armed,
            mode=self._mode,
            mode_name=self._mode_name,
            system_status=self._system_status,
            landed_state=self._landed,
            sim_time_s=self._sim_time_s,
            pos_ned_m=self._pos,
            vel_ned_m_s=self._vel,
            lat_deg=self._lat,
            lon_deg=self._lon,
            alt_rel_m=self._alt_rel,
            home=self._home,
            gps_fix_type=self._gps_fix_type,
            battery_remaining_pct=self._battery,
            mission_seq_current=self._mission_seq,
            mission_count=self._mission_count,
            mission_state=self._mission_state,
            items_reached=tuple(self._reached),
            statustexts=tuple(self._texts),
        )

    def statustexts_since(self, serial: int) -> list[StatusText]:
        """STATUSTEXTs received after :attr:`statustext_serial` was ``serial``."""
        n = self._text_serial - serial
        return list(self._texts)[-n:] if n > 0 else []

    def update(self, msg: Msg) -> None:
        kind = msg.get_type()
        if kind == "HEARTBEAT":
            if msg.get_srcComponent() != self.target_component:
                return
            self._heartbeat = True
            self._armed = bool(msg.base_mode & M.MAV_MODE_FLAG_SAFETY_ARMED)
            self._mode = _mode_from_custom(int(msg.custom_mode))
            self._mode_name = self._mode.name if self._mode is not None else f"custom {msg.custom_mode:#x}"
            self._system_status = int(msg.system_status)
        elif kind == "EXTENDED_SYS_STATE":
            try:
                self._landed = LandedState(int(msg.landed_state))
            except ValueError:
                self._landed = LandedState.UNDEFINED
        elif kind in ("ATTITUDE", "LOCAL_POSITION_NED", "GLOBAL_POSITION_INT"):
            self._sim_time_s = msg.time_boot_ms / 1000.0
            if kind == "LOCAL_POSITION_NED":
                self._pos = (float(msg.x), float(msg.y), float(msg.z))
                self._vel = (float(msg.vx), float(msg.vy), float(msg.vz))
            elif kind == "GLOBAL_POSITION_INT":
                self._lat = deg_from_deg_e7(msg.lat)
                self._lon = deg_from_deg_e7(msg.lon)
                self._alt_rel = msg.relative_alt / 1000.0
        elif kind == "HOME_POSITION":
            self._home = GeoPoint(deg_from_deg_e7(msg.latitude), deg_from_deg_e7(msg.longitude), msg.altitude / 1000.0)
        elif kind == "GPS_RAW_INT":
            self._gps_fix_type = int(msg.fix_type)
        elif kind == "SYS_STATUS":
            self._battery = None if msg.battery_remaining < 0 else float(msg.battery_remaining)
        elif kind == "MISSION_CURRENT":
            self._mission_seq = int(msg.seq)
            self._mission_count = int(getattr(msg, "total", 0))
            self._mission_state = int(getattr(msg, "mission_state", 0))
        elif kind == "MISSION_ITEM_REACHED":
            seq = int(msg.seq)
            if seq not in self._reached_set:
                self._reached_set.add(seq)
                self._reached.append(seq)
        elif kind == "STATUSTEXT":
            self._on_statustext(msg)

    def _on_statustext(self, msg: Msg) -> None:
        text = msg.text if isinstance(msg.text, str) else msg.text.decode("utf-8", errors="replace")
        text = text.split("\x00", 1)[0]
        chunk_id = int(getattr(msg, "id", 0))
        if chunk_id:
            parts = self._chunks.setdefault(chunk_id, [])
            parts.append(text)
            if len(text) >= 50:
                return
            text = "".join(self._chunks.pop(chunk_id))
        try:
            severity = Severity(int(msg.severity))
        except ValueError:
            severity = Severity.INFO
        self._texts.append(StatusText(severity, text))
        self._text_serial += 1

    def forget_reached_items(self) -> None:
        """Start counting MISSION_ITEM_REACHED afresh (e.g. before flying a new mission)."""
        self._reached.clear()
        self._reached_set.clear()
