"""Telemetry streams of the GCS link: TelemetrySnapshot -> PX4-style MAVLink messages (SPEC §8).

Each stream has an interval in microseconds of SIM time (changed by SET_MESSAGE_INTERVAL,
0 = default, -1 = off). ``publish`` sends the streams that are due; ``send_now`` serves
REQUEST_MESSAGE. Optionally a stream is also capped at ``max_speedup`` times its rate in
wall time (events — HEARTBEAT on a mode/arming change, MISSION_CURRENT on a change,
MISSION_ITEM_REACHED, STATUSTEXT — are never capped).
The vehicle identifies as a PX4 quadrotor (system 1, component 1) with PX4 ``custom_mode``.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from pymavlink.dialects.v20 import common as mavlink2

from mavlink_bridge.contract.frames import deg_e7_from_deg, euler_from_quat
from mavlink_bridge.contract.vehicle_api import FlightMode, TelemetrySnapshot

M = mavlink2
#: Advertised in AUTOPILOT_VERSION.capabilities.
CAPABILITIES = (
    M.MAV_PROTOCOL_CAPABILITY_MISSION_FLOAT
    | M.MAV_PROTOCOL_CAPABILITY_PARAM_FLOAT
    | M.MAV_PROTOCOL_CAPABILITY_MISSION_INT
    | M.MAV_PROTOCOL_CAPABILITY_COMMAND_INT
    | M.MAV_PROTOCOL_CAPABILITY_MAVLINK2
    | M.MAV_PROTOCOL_CAPABILITY_MISSION_FENCE
)
#: PX4 v1.14.0, FIRMWARE_VERSION_TYPE_OFFICIAL: clients that gate features on the PX4 version accept it.
FLIGHT_SW_VERSION = (1 << 24) | (14 << 16) | (0 << 8) | 255
_UINT16_MAX = 65535
_INT16_MAX = 32767

#: Streams also sent with every arming/mode/landed-state change (before the HEARTBEAT that announces it).
_POSITION_STREAMS = (M.MAVLINK_MSG_ID_LOCAL_POSITION_NED, M.MAVLINK_MSG_ID_GLOBAL_POSITION_INT)

#: Default stream rates in Hz of sim time.
DEFAULT_RATES_HZ: dict[int, float] = {
    M.MAVLINK_MSG_ID_HEARTBEAT: 1.0,
    M.MAVLINK_MSG_ID_SYS_STATUS: 2.0,
    M.MAVLINK_MSG_ID_ATTITUDE: 50.0,
    M.MAVLINK_MSG_ID_LOCAL_POSITION_NED: 30.0,
    M.MAVLINK_MSG_ID_GLOBAL_POSITION_INT: 10.0,
    M.MAVLINK_MSG_ID_GPS_RAW_INT: 5.0,
    M.MAVLINK_MSG_ID_VFR_HUD: 10.0,
    M.MAVLINK_MSG_ID_EXTENDED_SYS_STATE: 2.0,
    M.MAVLINK_MSG_ID_HOME_POSITION: 0.5,
    M.MAVLINK_MSG_ID_BATTERY_STATUS: 1.0,
    M.MAVLINK_MSG_ID_MISSION_CURRENT: 1.0,
    M.MAVLINK_MSG_ID_ESTIMATOR_STATUS: 1.0,
}


def base_mode_for(mode: FlightMode, armed: bool) -> int:
    """HEARTBEAT base_mode as PX4 sets it: custom mode enabled, armed bit, and the mode class flags."""
    flags = M.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED
    if armed:
        flags |= M.MAV_MODE_FLAG_SAFETY_ARMED
    if mode is FlightMode.MANUAL:
        flags |= M.MAV_MODE_FLAG_MANUAL_INPUT_ENABLED
    elif mode is FlightMode.POSCTL:
        flags |= M.MAV_MODE_FLAG_MANUAL_INPUT_ENABLED | M.MAV_MODE_FLAG_STABILIZE_ENABLED
        flags |= M.MAV_MODE_FLAG_GUIDED_ENABLED
    elif mode is FlightMode.OFFBOARD:
        flags |= M.MAV_MODE_FLAG_STABILIZE_ENABLED | M.MAV_MODE_FLAG_GUIDED_ENABLED
    else:
        flags |= M.MAV_MODE_FLAG_STABILIZE_ENABLED | M.MAV_MODE_FLAG_GUIDED_ENABLED | M.MAV_MODE_FLAG_AUTO_ENABLED
    return flags


@dataclass(frozen=True, slots=True)
class VehicleIdentity:
    """AUTOPILOT_VERSION contents that do not change."""

    uid: int = 0x5153_4954_4C00_0001  # "QSITL" + 1
    vendor_id: int = 0
    product_id: int = 0


class TelemetryStreams:
    """Rate-limited telemetry in sim time; one encoder per message id."""

    def __init__(
        self,
        mav: mavlink2.MAVLink,
        identity: VehicleIdentity = VehicleIdentity(),
        *,
        max_speedup: float | None = None,
        wall_clock: Callable[[], float] = time.monotonic,
    ) -> None:
        """``max_speedup``: a stream is sent at most this many times faster than its rate in WALL time
        (None: no cap), so a simulation running many times faster than real time cannot flood the GCS."""
        self._mav = mav
        self._identity = identity
        self._min_wall_gap_scale = None if max_speedup is None else 1e-6 / max_speedup
        self._wall_clock = wall_clock
        self._encoders: dict[int, Callable[[TelemetrySnapshot], None]] = {
            M.MAVLINK_MSG_ID_HEARTBEAT: self._heartbeat,
            M.MAVLINK_MSG_ID_SYS_STATUS: self._sys_status,
            M.MAVLINK_MSG_ID_ATTITUDE: self._attitude,
            M.MAVLINK_MSG_ID_LOCAL_POSITION_NED: self._local_position,
            M.MAVLINK_MSG_ID_GLOBAL_POSITION_INT: self._global_position,
            M.MAVLINK_MSG_ID_GPS_RAW_INT: self._gps_raw,
            M.MAVLINK_MSG_ID_VFR_HUD: self._vfr_hud,
            M.MAVLINK_MSG_ID_EXTENDED_SYS_STATE: self._extended_sys_state,
            M.MAVLINK_MSG_ID_HOME_POSITION: self._home_position,
            M.MAVLINK_MSG_ID_BATTERY_STATUS: self._battery_status,
            M.MAVLINK_MSG_ID_MISSION_CURRENT: self._mission_current,
            M.MAVLINK_MSG_ID_ESTIMATOR_STATUS: self._estimator_status,
        }
        self._default_interval_us = {msg_id: round(1e6 / hz) for msg_id, hz in DEFAULT_RATES_HZ.items()}
        self.interval_us: dict[int, int] = dict(self._default_interval_us)
        self._next_due_us: dict[int, int] = dict.fromkeys(self._encoders, 0)
        self._next_wall_ok_s: dict[int, float] = dict.fromkeys(self._encoders, -math.inf)
        self._last_state: tuple[bool, int, int] | None = None
        self._last_mission: tuple[int, int, int] | None = None
        self.last_snapshot: TelemetrySnapshot | None = None
        self.sent_count: dict[int, int] = dict.fromkeys(self._encoders, 0)
        self._next_any_due_us = 0
        self._q = np.zeros(4)
        self._euler_time_us = -1
        self._euler_rad = (0.0, 0.0, 0.0)

    # ---- rates -------------------------------------------------------------------------------------------
    def supports(self, msg_id: int) -> bool:
        """Whether REQUEST_MESSAGE can serve ``msg_id``."""
        return msg_id in self._encoders or msg_id == M.MAVLINK_MSG_ID_AUTOPILOT_VERSION

    def set_interval(self, msg_id: int, interval_us: float) -> bool:
        """SET_MESSAGE_INTERVAL semantics: >0 interval, 0 default, -1 off. False if not a stream."""
        if msg_id not in self._encoders or not math.isfinite(interval_us):
            return False
        if interval_us == 0:
            self.interval_us[msg_id] = self._default_interval_us[msg_id]
        elif interval_us < 0:
            self.interval_us[msg_id] = 0
        else:
            self.interval_us[msg_id] = max(1, int(interval_us))
        self._next_due_us[msg_id] = 0
        self._update_next_any_due()
        return True

    # ---- sending -----------------------------------------------------------------------------------------
    def publish(self, snapshot: TelemetrySnapshot) -> None:
        """Send the streams due at ``snapshot.time_us`` (sim time); on any arming, mode or landed-state change
        also the positions (LOCAL_POSITION_NED, GLOBAL_POSITION_INT, each if its stream is on), then HEARTBEAT
        and EXTENDED_SYS_STATE at once: a GCS sees a change with where it happened, however far apart the
        wall-clock cap spaces the position samples at ``--speed max``."""
        self.last_snapshot = snapshot
        t_us = snapshot.time_us
        state = (snapshot.armed, int(snapshot.mode), int(snapshot.landed_state))
        if state != self._last_state:
            self._last_state = state
            for msg_id in _POSITION_STREAMS:
                if self.interval_us[msg_id] > 0:
                    self._encoders[msg_id](snapshot)
                    self.sent_count[msg_id] += 1
            self._heartbeat(snapshot)
            self._extended_sys_state(snapshot)
            self._next_due_us[M.MAVLINK_MSG_ID_HEARTBEAT] = t_us + self.interval_us[M.MAVLINK_MSG_ID_HEARTBEAT]
        # MISSION_ITEM_REACHED before the MISSION_CURRENT that moves past it, so progress never steps back
        for seq in snapshot.mission_reached:
            self._mav.mission_item_reached_send(seq)
        mission = (snapshot.mission_seq_current, snapshot.mission_count, snapshot.mission_state)
        if mission != self._last_mission:
            self._last_mission = mission
            self._mission_current(snapshot)
        if t_us < self._next_any_due_us:
            return  # most control steps: nothing due
        wall_s = self._wall_clock() if self._min_wall_gap_scale is not None else 0.0
        for msg_id, encode in self._encoders.items():
            interval = self.interval_us[msg_id]
            if interval <= 0:
                continue
            due = self._next_due_us[msg_id]
            if t_us >= due:
                if self._min_wall_gap_scale is None:
                    encode(snapshot)
                    self.sent_count[msg_id] += 1
                elif wall_s >= self._next_wall_ok_s[msg_id]:
                    encode(snapshot)
                    self.sent_count[msg_id] += 1
                    self._next_wall_ok_s[msg_id] = wall_s + interval * self._min_wall_gap_scale
                due += interval
                self._next_due_us[msg_id] = due if due > t_us else t_us + interval
        self._update_next_any_due()

    def _update_next_any_due(self) -> None:
        dues = [self._next_due_us[m] for m, interval in self.interval_us.items() if interval > 0]
        self._next_any_due_us = min(dues) if dues else 2**62

    def send_now(self, msg_id: int) -> bool:
        """Send one message (REQUEST_MESSAGE); False if unsupported or no snapshot yet."""
        if msg_id == M.MAVLINK_MSG_ID_AUTOPILOT_VERSION:
            self.send_autopilot_version()
            return True
        encode = self._encoders.get(msg_id)
        if encode is None or self.last_snapshot is None:
            return False
        encode(self.last_snapshot)
        return True

    def send_boot_heartbeat(self) -> None:
        """HEARTBEAT before the first snapshot: MAV_STATE_BOOT, so a GCS sees the vehicle early."""
        self._mav.heartbeat_send(
            M.MAV_TYPE_QUADROTOR,
            M.MAV_AUTOPILOT_PX4,
            M.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED,
            int(FlightMode.AUTO_LOITER),
            M.MAV_STATE_BOOT,
        )

    def send_autopilot_version(self) -> None:
        ident = self._identity
        zeros8 = [0] * 8
        self._mav.autopilot_version_send(
            CAPABILITIES,
            FLIGHT_SW_VERSION,
            0,
            0,
            0,
            zeros8,
            zeros8,
            zeros8,
            ident.vendor_id,
            ident.product_id,
            ident.uid,
        )

    # ---- encoders ----------------------------------------------------------------------------------------
    def _heartbeat(self, s: TelemetrySnapshot) -> None:
        status = M.MAV_STATE_ACTIVE if s.armed else M.MAV_STATE_STANDBY
        self._mav.heartbeat_send(
            M.MAV_TYPE_QUADROTOR, M.MAV_AUTOPILOT_PX4, base_mode_for(s.mode, s.armed), int(s.mode), status
        )

    def _sys_status(self, s: TelemetrySnapshot) -> None:
        self._mav.sys_status_send(
            s.sensors_present,
            s.sensors_enabled,
            s.sensors_health,
            0,
            _clamp_int(s.battery_voltage_v * 1000.0, 0, _UINT16_MAX),
            _clamp_int(s.battery_current_a * 100.0, -1, _INT16_MAX),
            _clamp_int(s.battery_remaining_pct, -1, 100),
            0,
            0,
            0,
            0,
            0,
            0,
        )

    def _euler(self, s: TelemetrySnapshot) -> tuple[float, float, float]:
        """(roll, pitch, yaw) in rad of ``s.q_ned_frd``, computed once per snapshot time."""
        if s.time_us != self._euler_time_us:
            self._q[:] = s.q_ned_frd
            roll, pitch, yaw = euler_from_quat(self._q)
            self._euler_rad = (float(roll), float(pitch), float(yaw))
            self._euler_time_us = s.time_us
        return self._euler_rad

    def _attitude(self, s: TelemetrySnapshot) -> None:
        roll, pitch, yaw = self._euler(s)
        p, q, r = s.rate_frd_rad_s
        self._mav.attitude_send(s.time_us // 1000 & 0xFFFFFFFF, roll, pitch, yaw, p, q, r)

    def _local_position(self, s: TelemetrySnapshot) -> None:
        x, y, z = s.pos_ned_m
        vx, vy, vz = s.vel_ned_m_s
        self._mav.local_position_ned_send(s.time_us // 1000 & 0xFFFFFFFF, x, y, z, vx, vy, vz)

    def _yaw_cdeg(self, s: TelemetrySnapshot) -> int:
        return int(math.degrees(self._euler(s)[2]) % 360.0 * 100.0) % 36000

    def _global_position(self, s: TelemetrySnapshot) -> None:
        vn, ve, vd = s.vel_ned_m_s
        self._mav.global_position_int_send(
            s.time_us // 1000 & 0xFFFFFFFF,
            deg_e7_from_deg(s.lat_deg),
            deg_e7_from_deg(s.lon_deg),
            _clamp_int(s.alt_amsl_m * 1000.0, -(2**31), 2**31 - 1),
            _clamp_int(s.alt_rel_m * 1000.0, -(2**31), 2**31 - 1),
            _clamp_int(vn * 100.0, -32768, _INT16_MAX),
            _clamp_int(ve * 100.0, -32768, _INT16_MAX),
            _clamp_int(vd * 100.0, -32768, _INT16_MAX),
            self._yaw_cdeg(s),
        )

    def _gps_raw(self, s: TelemetrySnapshot) -> None:
        vn, ve, _ = s.vel_ned_m_s
        ground_speed = math.hypot(vn, ve)
        cog = int(math.degrees(math.atan2(ve, vn)) % 360.0 * 100.0) % 36000 if ground_speed > 0.1 else _UINT16_MAX
        self._mav.gps_raw_int_send(
            s.time_us,
            s.gps_fix_type,
            deg_e7_from_deg(s.lat_deg),
            deg_e7_from_deg(s.lon_deg),
            _clamp_int(s.alt_amsl_m * 1000.0, -(2**31), 2**31 - 1),
            _clamp_int(s.gps_eph_m * 100.0, 0, _UINT16_MAX),
            _clamp_int(s.gps_epv_m * 100.0, 0, _UINT16_MAX),
            _clamp_int(ground_speed * 100.0, 0, _UINT16_MAX - 1),
            cog,
            max(0, min(255, s.gps_satellites)),
        )

    def _vfr_hud(self, s: TelemetrySnapshot) -> None:
        vn, ve, vd = s.vel_ned_m_s
        ground_speed = math.hypot(vn, ve)
        heading = self._yaw_cdeg(s) // 100
        throttle = _clamp_int(s.throttle_pct, 0, 100)
        self._mav.vfr_hud_send(ground_speed, ground_speed, heading, throttle, s.alt_amsl_m, -vd)

    def _extended_sys_state(self, s: TelemetrySnapshot) -> None:
        self._mav.extended_sys_state_send(M.MAV_VTOL_STATE_MC, int(s.landed_state))

    def _home_position(self, s: TelemetrySnapshot) -> None:
        if not s.home_valid:
            return
        self._mav.home_position_send(
            deg_e7_from_deg(s.home_lat_deg),
            deg_e7_from_deg(s.home_lon_deg),
            _clamp_int(s.home_alt_amsl_m * 1000.0, -(2**31), 2**31 - 1),
            0.0,
            0.0,
            0.0,
            [1.0, 0.0, 0.0, 0.0],
            0.0,
            0.0,
            0.0,
            s.time_us,
        )

    def _battery_status(self, s: TelemetrySnapshot) -> None:
        voltages = [_UINT16_MAX] * 10
        voltages[0] = _clamp_int(s.battery_voltage_v * 1000.0, 0, _UINT16_MAX - 1)
        self._mav.battery_status_send(
            0,
            M.MAV_BATTERY_FUNCTION_ALL,
            M.MAV_BATTERY_TYPE_LIPO,
            _INT16_MAX,
            voltages,
            _clamp_int(s.battery_current_a * 100.0, -1, _INT16_MAX),
            -1,
            -1,
            _clamp_int(s.battery_remaining_pct, -1, 100),
        )

    def _mission_current(self, s: TelemetrySnapshot) -> None:
        seq = max(0, min(_UINT16_MAX, s.mission_seq_current))
        self._mav.mission_current_send(
            seq, max(0, min(_UINT16_MAX, s.mission_count)), max(0, min(255, s.mission_state))
        )

    def _estimator_status(self, s: TelemetrySnapshot) -> None:
        """ESTIMATOR_STATUS from the snapshot's estimator report (nothing when the autopilot gave none)."""
        e = s.estimator
        if e is None:
            return
        self._mav.estimator_status_send(
            s.time_us,
            int(e.flags),
            _ratio(e.vel_ratio),
            _ratio(e.pos_horiz_ratio),
            _ratio(e.pos_vert_ratio),
            _ratio(e.mag_ratio),
            0.0,
            0.0,
            _ratio(e.pos_horiz_accuracy_m),
            _ratio(e.pos_vert_accuracy_m),
        )


def _ratio(value: float) -> float:
    """A test ratio or accuracy for the wire: 0 when unknown (not fused), capped at 1e6."""
    return min(value, 1e6) if math.isfinite(value) and value >= 0.0 else 0.0


def _clamp_int(value: float, lo: int, hi: int) -> int:
    """Round to int and clamp to the field's range; non-finite -> ``lo`` (the 'unknown' end for most fields)."""
    if not math.isfinite(value):
        return lo
    return max(lo, min(hi, round(value)))
