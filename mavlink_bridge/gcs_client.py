"""Ground-station client library: missions, commands, parameters and telemetry as typed calls (SPEC §8).

Callers never see a MAVLink message. Every protocol step has a retry interval and a
bounded number of retries; failures are typed exceptions carrying the vehicle's
MAVLink result and the reason it gave in STATUSTEXT. Single-threaded: every blocking
call pumps the link, keeps :meth:`GcsClient.telemetry` current and sends the GCS
HEARTBEAT at 1 Hz.
"""

from __future__ import annotations

import math
import struct
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import TypeVar

from pymavlink.dialects.v20 import common as mavlink2

from mavlink_bridge.contract.frames import GeoPoint, deg_from_deg_e7
from mavlink_bridge.contract.vehicle_api import (
    CommandResult,
    FlightMode,
    LandedState,
    MissionItem,
    MissionResult,
    MissionType,
    Severity,
    StatusText,
)
from mavlink_bridge.gcs_link import MavlinkEndpoint
from mavlink_bridge.mission_items import MissionItemEncodeError, item_from_msg, send_item, xy_to_int
from mavlink_bridge.param_protocol import PARAM_TYPE_REAL32, decode_param_id

Msg = mavlink2.MAVLink_message
T = TypeVar("T")
M = mavlink2
MAV_COMP_ID_MISSIONPLANNER = 190
_FORCE_ARM_MAGIC = 21196.0  # PX4/ArduPilot: param2 of COMPONENT_ARM_DISARM that bypasses pre-arm checks
_STATUSTEXT_KEEP = 200


class GcsError(Exception):
    """Base of every error the client raises."""


class GcsTimeoutError(GcsError, TimeoutError):
    """The vehicle did not answer within the retries, or a wait condition did not come true in time."""


class MissionUploadError(GcsError):
    """The vehicle refused or did not complete an upload; its previous mission is still in force."""

    def __init__(self, result: MissionResult, text: str) -> None:
        super().__init__(f"mission upload failed ({result.name}): {text}")
        self.result = result
        self.text = text


class MissionDownloadError(GcsError):
    """A download was refused or did not complete."""


#: What a COMMAND_ACK result means, for a refusal the vehicle sent no STATUSTEXT about.
RESULT_MEANING = {
    CommandResult.TEMPORARILY_REJECTED: "not now: the vehicle is not ready for it yet (try again in a moment)",
    CommandResult.DENIED: "the vehicle refused it in its present state and gave no reason",
    CommandResult.UNSUPPORTED: "the vehicle does not support this command",
    CommandResult.FAILED: "the vehicle accepted it but could not carry it out",
    CommandResult.CANCELLED: "cancelled by the vehicle",
}
#: Wall seconds to wait after a refusal for the STATUSTEXT that says why (the vehicle sends it after the ack).
REASON_WAIT_S = 0.5


class CommandFailedError(GcsError):
    """A command was acked with something other than ACCEPTED; ``text`` is the vehicle's reason."""

    def __init__(self, command: int, result: CommandResult, text: str = "") -> None:
        name = M.enums["MAV_CMD"][command].name if command in M.enums["MAV_CMD"] else str(command)
        super().__init__(f"{name} -> {result.name}" + (f": {text}" if text else ""))
        self.command = command
        self.result = result
        self.text = text


class ParamNotFoundError(GcsError):
    """The vehicle has no parameter of that name."""


class ParamRefusedError(GcsError):
    """A PARAM_SET was refused; ``value_in_force`` is what the vehicle kept."""

    def __init__(self, name: str, requested: float, value_in_force: float, reason: str) -> None:
        said = reason
        for prefix in (f"{name} refused: ", f"{name}: "):  # the vehicle's text names the parameter too: once is enough
            said = said.removeprefix(prefix)
        super().__init__(f"{name} = {requested:g} refused (still {value_in_force:g}): {said}")
        self.name = name
        self.requested = requested
        self.value_in_force = value_in_force
        self.reason = reason


#: The name the brief uses for a refused PARAM_SET.
ParamRefused = ParamRefusedError


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


def _float32(value: float) -> float:
    """``value`` as it survives a float32 MAVLink field."""
    return struct.unpack("<f", struct.pack("<f", value))[0]


def _mode_from_custom(custom_mode: int) -> FlightMode | None:
    try:
        return FlightMode.from_px4((custom_mode >> 16) & 0xFF, (custom_mode >> 24) & 0xFF)
    except ValueError:
        return None


class GcsClient:
    """A ground station on one link (``udpin:`` waits for the vehicle to talk, ``udpout:`` talks first)."""

    def __init__(
        self,
        url: str = "udpin:127.0.0.1:14550",
        *,
        target_system: int = 1,
        target_component: int = 1,
        system_id: int = 255,
        component_id: int = MAV_COMP_ID_MISSIONPLANNER,
        signing_key: bytes | None = None,
        timeout_s: float = 5.0,
        retry_s: float = 0.3,
    ) -> None:
        self._endpoint = MavlinkEndpoint(
            url, system_id=system_id, component_id=component_id, signing_key=signing_key, require_signing=False
        )
        self.mav = self._endpoint.mav
        self.target_system = target_system
        self.target_component = target_component
        self.timeout_s = timeout_s
        self.retry_s = retry_s
        self._pending: deque[Msg] = deque()
        self._last_heartbeat_sent_s = -math.inf
        # telemetry state
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
        if self._endpoint.link.peer is not None:
            self._send_heartbeat()

    # ---- lifecycle ---------------------------------------------------------------------------------------
    def close(self) -> None:
        self._endpoint.close()

    def __enter__(self) -> GcsClient:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # ---- telemetry ---------------------------------------------------------------------------------------
    def telemetry(self) -> VehicleStatus:
        """The latest decoded state (call :meth:`pump` or any blocking call to refresh it)."""
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

    def pump(self, duration_s: float = 0.0) -> None:
        """Process incoming messages for ``duration_s`` (0: only what is waiting)."""
        self._wait(lambda _m: None, duration_s)

    def wait_heartbeat(self, timeout_s: float | None = None) -> VehicleStatus:
        """Block until a HEARTBEAT from the vehicle; GcsTimeoutError otherwise."""
        return self.wait_until(lambda s: s.heartbeat_received, self.timeout_s if timeout_s is None else timeout_s)

    def wait_until(
        self, predicate: Callable[[VehicleStatus], bool], timeout_s: float, poll_s: float = 0.05
    ) -> VehicleStatus:
        """Pump until ``predicate(telemetry())`` holds; GcsTimeoutError after ``timeout_s`` of wall time."""
        deadline = time.monotonic() + timeout_s
        while True:
            status = self.telemetry()
            if predicate(status):
                return status
            remaining = deadline - time.monotonic()
            if remaining <= 0.0:
                raise GcsTimeoutError(f"condition not met within {timeout_s:g} s")
            self.pump(min(poll_s, remaining))

    def statustexts_since(self, serial: int) -> list[StatusText]:
        """STATUSTEXTs received after :attr:`statustext_serial` was ``serial``."""
        n = self._text_serial - serial
        return list(self._texts)[-n:] if n > 0 else []

    @property
    def statustext_serial(self) -> int:
        return self._text_serial

    # ---- missions ----------------------------------------------------------------------------------------
    def upload_mission(self, items: list[MissionItem], mission_type: MissionType = MissionType.MISSION) -> None:
        """Upload ``items`` (renumbered 0..n-1) as ``mission_type``; MissionUploadError if not accepted."""
        items = [replace(item, seq=i, mission_type=mission_type) for i, item in enumerate(items)]
        for item in items:
            try:
                xy_to_int(item.x_lat_deg, item.frame, "x/lat")
            except MissionItemEncodeError as exc:
                raise MissionUploadError(MissionResult.INVALID_PARAM5_X, f"item {item.seq}: {exc}") from exc
            try:
                xy_to_int(item.y_lon_deg, item.frame, "y/lon")
            except MissionItemEncodeError as exc:
                raise MissionUploadError(MissionResult.INVALID_PARAM6_Y, f"item {item.seq}: {exc}") from exc
        serial = self._text_serial
        count = len(items)
        mtype = int(mission_type)
        ts, tc = self.target_system, self.target_component

        def send_count() -> None:
            self.mav.mission_count_send(ts, tc, count, mtype)

        resend: Callable[[], None] = send_count
        resend()
        sent_last = count == 0
        retries = 0
        max_retries = max(1, round(self.timeout_s / self.retry_s))
        while True:
            msg = self._wait(
                self._mission_reply_matcher(mtype, ("MISSION_REQUEST_INT", "MISSION_REQUEST")), self.retry_s
            )
            if msg is None:
                retries += 1
                if retries > max_retries:
                    self.mav.mission_ack_send(ts, tc, int(MissionResult.OPERATION_CANCELLED), mtype)
                    raise MissionUploadError(MissionResult.OPERATION_CANCELLED, "the vehicle stopped answering")
                resend()
                continue
            retries = 0
            if msg.get_type() == "MISSION_ACK":
                result = _mission_result(msg.type)
                if result is MissionResult.ACCEPTED:
                    if sent_last:
                        return
                    continue  # a stale ACK of an earlier transfer
                raise MissionUploadError(result, self._reason(serial, result.name))
            seq = int(msg.seq)
            if not 0 <= seq < count:
                continue
            use_int = msg.get_type() == "MISSION_REQUEST_INT"

            def send_item_seq(seq: int = seq, use_int: bool = use_int) -> None:
                send_item(self.mav, items[seq], seq=seq, target_system=ts, target_component=tc, use_int=use_int)

            resend = send_item_seq
            resend()
            sent_last = sent_last or seq == count - 1

    def download_mission(self, mission_type: MissionType = MissionType.MISSION) -> list[MissionItem]:
        """The vehicle's current ``mission_type`` list."""
        mtype = int(mission_type)
        ts, tc = self.target_system, self.target_component

        def is_count(msg: Msg) -> Msg | None:
            if msg.get_type() == "MISSION_COUNT" and int(getattr(msg, "mission_type", 0)) == mtype:
                return msg
            return None

        reply = self._exchange(lambda: self.mav.mission_request_list_send(ts, tc, mtype), is_count, "MISSION_COUNT")
        items: list[MissionItem] = []
        for seq in range(int(reply.count)):

            def is_item(msg: Msg, seq: int = seq) -> Msg | None:
                kind = msg.get_type()
                if kind == "MISSION_ACK" and int(getattr(msg, "mission_type", 0)) == mtype:
                    if msg.type == int(MissionResult.ACCEPTED):
                        return None  # a late or duplicated ACK of an earlier upload: not about this download
                    raise MissionDownloadError(f"download refused at item {seq}: {_mission_result(msg.type).name}")
                if kind == "MISSION_ITEM_INT" and int(msg.seq) == seq and int(msg.mission_type) == mtype:
                    return msg
                return None

            msg = self._exchange(
                lambda seq=seq: self.mav.mission_request_int_send(ts, tc, seq, mtype), is_item, f"mission item {seq}"
            )
            items.append(item_from_msg(msg))
        self.mav.mission_ack_send(ts, tc, int(MissionResult.ACCEPTED), mtype)
        return items

    def clear_mission(self, mission_type: MissionType = MissionType.MISSION) -> None:
        """MISSION_CLEAR_ALL; MissionUploadError if the vehicle refuses."""
        mtype = int(mission_type)
        serial = self._text_serial
        ts, tc = self.target_system, self.target_component
        ack = self._exchange(
            lambda: self.mav.mission_clear_all_send(ts, tc, mtype),
            self._mission_reply_matcher(mtype, ()),
            "MISSION_ACK",
        )
        result = _mission_result(ack.type)
        if result is not MissionResult.ACCEPTED:
            raise MissionUploadError(result, self._reason(serial, result.name))

    def set_current_item(self, seq: int) -> None:
        """MISSION_SET_CURRENT; waits for MISSION_CURRENT to report ``seq``."""
        ts, tc = self.target_system, self.target_component

        def is_current(msg: Msg) -> Msg | None:
            return msg if msg.get_type() == "MISSION_CURRENT" and int(msg.seq) == seq else None

        self._exchange(lambda: self.mav.mission_set_current_send(ts, tc, seq), is_current, "MISSION_CURRENT")

    # ---- commands ----------------------------------------------------------------------------------------
    def command(self, command: int, *params: float, timeout_s: float | None = None) -> CommandResult:
        """COMMAND_LONG (up to 7 params, rest 0); retried with rising ``confirmation``; returns the final result."""
        if len(params) > 7:
            raise ValueError("COMMAND_LONG has 7 parameters")
        p = [float(v) for v in params] + [0.0] * (7 - len(params))
        ts, tc = self.target_system, self.target_component
        confirmation = 0
        deadline = time.monotonic() + (self.timeout_s if timeout_s is None else timeout_s)

        def is_ack(msg: Msg) -> Msg | None:
            if msg.get_type() == "COMMAND_ACK" and int(msg.command) == command:
                target = int(getattr(msg, "target_system", 0))
                if target in (0, self.mav.srcSystem):
                    return msg
            return None

        in_progress = False
        while time.monotonic() < deadline:
            if not in_progress:
                self.mav.command_long_send(ts, tc, command, confirmation, *p)
            ack = self._wait(is_ack, min(self.retry_s, max(0.0, deadline - time.monotonic())))
            if ack is None:
                confirmation = min(255, confirmation + 1)
                continue
            result = CommandResult(int(ack.result))
            if result is not CommandResult.IN_PROGRESS:
                return result
            in_progress = True
        raise GcsTimeoutError(f"no COMMAND_ACK for command {command}")

    def _command_ok(self, command: int, *params: float) -> None:
        serial = self._text_serial
        result = self.command(command, *params)
        if result is not CommandResult.ACCEPTED:
            raise CommandFailedError(command, result, self.refusal_reason(serial, result))

    def refusal_reason(self, serial: int, result: CommandResult) -> str:
        """Why the vehicle refused: its warning STATUSTEXT since ``serial`` (waited for up to
        :data:`REASON_WAIT_S`, as it may follow the ack), else what ``result`` means."""
        deadline = time.monotonic() + REASON_WAIT_S
        reason = self._reason(serial, "")
        while not reason and time.monotonic() < deadline:
            self.pump(0.05)
            reason = self._reason(serial, "")
        return reason or RESULT_MEANING.get(result, result.name)

    def arm(self, force: bool = False) -> None:
        self._command_ok(M.MAV_CMD_COMPONENT_ARM_DISARM, 1.0, _FORCE_ARM_MAGIC if force else 0.0)

    def disarm(self, force: bool = False) -> None:
        self._command_ok(M.MAV_CMD_COMPONENT_ARM_DISARM, 0.0, _FORCE_ARM_MAGIC if force else 0.0)

    def set_mode(self, mode: FlightMode) -> None:
        """MAV_CMD_DO_SET_MODE with the PX4 custom main/sub mode."""
        self._command_ok(
            M.MAV_CMD_DO_SET_MODE,
            float(M.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED),
            float(mode.px4_main_mode),
            float(mode.px4_sub_mode),
        )

    def takeoff(self, alt_m: float) -> None:
        """MAV_CMD_NAV_TAKEOFF to ``alt_m`` above home; param7 is AMSL as PX4 expects (needs HOME_POSITION)."""
        if self._home is None:
            self.wait_until(lambda s: s.home is not None, self.timeout_s)
        assert self._home is not None
        nan = math.nan
        self._command_ok(M.MAV_CMD_NAV_TAKEOFF, -1.0, 0.0, 0.0, nan, nan, nan, self._home.alt_amsl_m + alt_m)

    def land(self) -> None:
        nan = math.nan
        self._command_ok(M.MAV_CMD_NAV_LAND, 0.0, 0.0, 0.0, nan, nan, nan, nan)

    def rtl(self) -> None:
        self._command_ok(M.MAV_CMD_NAV_RETURN_TO_LAUNCH)

    def start_mission(self, first_item: int = 0, last_item: int = 0) -> None:
        """MAV_CMD_MISSION_START (PX4 switches to AUTO.MISSION)."""
        self._command_ok(M.MAV_CMD_MISSION_START, float(first_item), float(last_item))

    def set_message_interval(self, message_id: int, interval_s: float) -> None:
        """SET_MESSAGE_INTERVAL: ``interval_s`` > 0, 0 = default rate, < 0 = off."""
        interval_us = -1.0 if interval_s < 0 else interval_s * 1e6
        self._command_ok(M.MAV_CMD_SET_MESSAGE_INTERVAL, float(message_id), interval_us)

    # ---- parameters --------------------------------------------------------------------------------------
    def get_param(self, name: str) -> float:
        """The value in force; ParamNotFoundError if the vehicle does not know ``name``."""
        ts, tc = self.target_system, self.target_component
        msg = self._exchange(
            lambda: self.mav.param_request_read_send(ts, tc, name.encode("ascii"), -1),
            self._param_matcher(name),
            f"parameter {name}",
        )
        return float(msg.param_value)

    def set_param(self, name: str, value: float) -> float:
        """Set ``name``; returns the value in force, ParamRefusedError if the vehicle kept another one."""
        ts, tc = self.target_system, self.target_component
        serial = self._text_serial
        msg = self._exchange(
            lambda: self.mav.param_set_send(ts, tc, name.encode("ascii"), float(value), PARAM_TYPE_REAL32),
            self._param_matcher(name),
            f"parameter {name}",
        )
        in_force = float(msg.param_value)
        if in_force != _float32(float(value)) and not (math.isnan(in_force) and math.isnan(value)):
            raise ParamRefusedError(name, float(value), in_force, self._reason(serial, "refused by the vehicle"))
        return in_force

    def list_params(self) -> dict[str, float]:
        """Every parameter (PARAM_REQUEST_LIST; missing indices re-read one by one)."""
        ts, tc = self.target_system, self.target_component
        values: dict[int, tuple[str, float]] = {}
        total: int | None = None

        def collect(msg: Msg) -> None:
            nonlocal total
            if msg.get_type() == "PARAM_VALUE" and msg.get_srcSystem() == ts:
                total = int(msg.param_count)
                if 0 <= int(msg.param_index) < total:
                    values[int(msg.param_index)] = (decode_param_id(msg.param_id), float(msg.param_value))

        def complete(msg: Msg) -> bool | None:
            collect(msg)
            return True if total is not None and len(values) >= total else None

        self.mav.param_request_list_send(ts, tc)
        deadline = time.monotonic() + self.timeout_s
        while time.monotonic() < deadline:
            before = len(values)
            if self._wait(complete, self.retry_s) is not None:
                break
            if len(values) > before:
                deadline = time.monotonic() + self.timeout_s  # still streaming: the limit is on silence
                continue
            if total is None:
                self.mav.param_request_list_send(ts, tc)
            else:
                for index in [i for i in range(total) if i not in values][:20]:
                    self.mav.param_request_read_send(ts, tc, b"", index)
        if total is None or len(values) < total:
            raise GcsTimeoutError(f"parameter list incomplete: {len(values)}/{total if total is not None else '?'}")
        return {name: value for _, (name, value) in sorted(values.items())}

    # ---- internals ---------------------------------------------------------------------------------------
    def _param_matcher(self, name: str) -> Callable[[Msg], Msg | None]:
        def match(msg: Msg) -> Msg | None:
            kind = msg.get_type()
            if kind == "PARAM_VALUE" and decode_param_id(msg.param_id) == name:
                return msg
            if kind == "STATUSTEXT" and self._texts and self._texts[-1].text == f"unknown parameter {name}":
                raise ParamNotFoundError(f"the vehicle has no parameter {name}")
            return None

        return match

    def _mission_reply_matcher(self, mtype: int, kinds: tuple[str, ...]) -> Callable[[Msg], Msg | None]:
        def match(msg: Msg) -> Msg | None:
            kind = msg.get_type()
            wanted = (kind == "MISSION_ACK" or kind in kinds) and int(getattr(msg, "mission_type", 0)) == mtype
            if wanted and int(getattr(msg, "target_system", 0)) in (0, self.mav.srcSystem):
                return msg
            return None

        return match

    def _exchange(self, send: Callable[[], None], match: Callable[[Msg], T | None], what: str) -> T:
        """Send, wait ``retry_s`` for a match, resend; GcsTimeoutError after ``timeout_s``."""
        deadline = time.monotonic() + self.timeout_s
        while True:
            send()
            found = self._wait(match, min(self.retry_s, max(0.0, deadline - time.monotonic())))
            if found is not None:
                return found
            if time.monotonic() >= deadline:
                raise GcsTimeoutError(f"no answer for {what} within {self.timeout_s:g} s")

    def _wait(self, match: Callable[[Msg], T | None], timeout_s: float) -> T | None:
        deadline = time.monotonic() + timeout_s
        while True:
            while self._pending:
                msg = self._pending.popleft()
                found = match(msg)
                if found is not None:
                    return found
            self._maybe_heartbeat()
            remaining = deadline - time.monotonic()
            if remaining < 0.0:
                return None
            msgs = self._endpoint.receive_datagram(min(remaining, 0.1))
            for msg in msgs or ():
                if msg.get_srcSystem() == self.target_system:
                    self._update(msg)
                    self._pending.append(msg)

    def _maybe_heartbeat(self) -> None:
        now = time.monotonic()
        if now - self._last_heartbeat_sent_s >= 1.0 and self._endpoint.link.peer is not None:
            self._send_heartbeat()

    def _send_heartbeat(self) -> None:
        self._last_heartbeat_sent_s = time.monotonic()
        self.mav.heartbeat_send(M.MAV_TYPE_GCS, M.MAV_AUTOPILOT_INVALID, 0, 0, M.MAV_STATE_ACTIVE)

    def _reason(self, serial: int, default: str) -> str:
        """The latest warning/error STATUSTEXT since ``serial`` (the vehicle's reason), else ``default``."""
        for text in reversed(self.statustexts_since(serial)):
            if text.severity <= Severity.WARNING:
                return text.text
        return default

    def _update(self, msg: Msg) -> None:
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


def _mission_result(raw: int) -> MissionResult:
    try:
        return MissionResult(int(raw))
    except ValueError:
        return MissionResult.ERROR
