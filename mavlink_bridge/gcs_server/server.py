"""The autopilot's GCS / API MAVLink endpoint (SPEC §3, §8, §10).

PX4-compatible so QGroundControl, MAVSDK, MAVProxy and pymavlink work unmodified: a
quadrotor with the PX4 autopilot id and ``custom_mode`` encoding, telemetry streams at
their rates in sim time, commands acked honestly, the mission protocol (MISSION and
FENCE), float parameters, offboard position and velocity setpoints, joystick input
(MANUAL_CONTROL), and MAVLink FTP over
an empty file system (each request refused at once, so a client falls back to the other
protocols without waiting). The autopilot runner owns the clock: it calls ``poll``
between lockstep frames (never blocks) and ``publish`` once per control step.

Streams run at their rates in sim time, capped at ``max_stream_speedup`` (default 1) times
those rates in wall time so a run at ``--speed max`` cannot flood a GCS; events are never capped.

GCS link timeouts are wall-clock (the GCS is a real-time peer). When the simulation runs
slower than real time (``speed_factor`` < 1) they stretch by ``1 / speed_factor``, so a
slow run is never timed out by its own pace; faster runs keep the real-time values.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable
from dataclasses import dataclass

from pymavlink.dialects.v20 import common as mavlink2

from mavlink_bridge.contract.vehicle_api import (
    CommandRequest,
    CommandResult,
    Severity,
    TelemetrySnapshot,
    VehicleInterface,
)
from mavlink_bridge.gcs_server.commands import (
    MAV_CMD_REQUEST_AUTOPILOT_CAPABILITIES,
    MAV_CMD_REQUEST_MESSAGE,
    MAV_CMD_SET_MESSAGE_INTERVAL,
    CommandProtocol,
    LocalHandler,
)
from mavlink_bridge.gcs_server.ftp import FtpProtocol
from mavlink_bridge.gcs_server.manual_control import ManualControlProtocol
from mavlink_bridge.gcs_server.missions import MissionProtocol, TransferTimeouts
from mavlink_bridge.gcs_server.params import ParamProtocol
from mavlink_bridge.gcs_server.setpoints import SetpointProtocol
from mavlink_bridge.gcs_server.telemetry_streams import TelemetryStreams
from mavlink_bridge.wire.gcs_link import MavlinkEndpoint

_log = logging.getLogger(__name__)
_STATUSTEXT_LEN = 50
_HEARTBEAT_WALL_PERIOD_S = 1.0


@dataclass(frozen=True, slots=True)
class GcsServerStats:
    """Counters since start (a copy: safe to keep)."""

    datagrams: int
    messages: int
    malformed: int
    unknown_message_ids: int
    rejected_unsigned: int
    rejected_bad_signature: int
    not_for_us: int
    handler_errors: int
    commands: int
    command_duplicates: int
    mission_uploads_accepted: int
    mission_uploads_refused: int
    mission_uploads_failed: int
    param_sets_refused: int
    setpoints_used: int
    setpoints_dropped: int
    ftp_requests: int
    manual_inputs_used: int


class GcsServer:
    """Serve one GCS or API link for ``vehicle`` (see module docstring)."""

    def __init__(
        self,
        url: str,
        vehicle: VehicleInterface,
        *,
        system_id: int = 1,
        component_id: int = 1,
        speed_factor: float = 1.0,
        require_signing: bool = False,
        signing_key: bytes | None = None,
        default_target_url: str | None = None,
        mission_timeouts: TransferTimeouts | None = None,
        max_mission_items: int = 5000,
        max_stream_speedup: float | None = 1.0,
    ) -> None:
        self._endpoint = MavlinkEndpoint(
            url,
            system_id=system_id,
            component_id=component_id,
            default_peer_url=default_target_url,
            signing_key=signing_key,
            require_signing=require_signing,
        )
        self.mav = self._endpoint.mav
        self.system_id = system_id
        self.component_id = component_id
        stretch = 1.0 / speed_factor if 0.0 < speed_factor < 1.0 else 1.0
        self.streams = TelemetryStreams(self.mav, max_speedup=max_stream_speedup)
        self.missions = MissionProtocol(
            self.mav,
            vehicle,
            self.statustext,
            timeouts=(mission_timeouts or TransferTimeouts()).scaled(stretch),
            max_items=max_mission_items,
        )
        self.params = ParamProtocol(self.mav, vehicle, self.statustext)
        self.setpoints = SetpointProtocol(vehicle)
        self.ftp = FtpProtocol(self.mav)
        self.manual = ManualControlProtocol(vehicle)
        local: dict[int, LocalHandler] = {
            MAV_CMD_SET_MESSAGE_INTERVAL: self._cmd_set_message_interval,
            MAV_CMD_REQUEST_MESSAGE: self._cmd_request_message,
            MAV_CMD_REQUEST_AUTOPILOT_CAPABILITIES: self._cmd_request_capabilities,
        }
        self.commands = CommandProtocol(self.mav, vehicle, local, dedupe_window_s=3.0 * stretch)
        self._statustext_id = 0
        self._wall_time_s = 0.0
        self._last_gcs_heartbeat_wall_s: float | None = None
        self._last_heartbeat_wall_s = -math.inf
        self._not_for_us = 0
        self._handler_errors = 0

    # ---- runner API --------------------------------------------------------------------------------------
    def poll(self, sim_time_us: int, wall_time_s: float, max_datagrams: int = 256) -> None:
        """Handle waiting datagrams and run protocol timers; never blocks. ``wall_time_s`` is monotonic seconds."""
        del sim_time_us  # protocol timing is wall-clock; streams use the snapshot's sim time
        self._wall_time_s = wall_time_s
        for msg in self._endpoint.receive(0.0, max_datagrams):
            self._dispatch(msg, wall_time_s)
        self.missions.tick(wall_time_s)
        self.params.tick()
        if wall_time_s - self._last_heartbeat_wall_s >= _HEARTBEAT_WALL_PERIOD_S:
            # At least 1 Hz of wall time even while the sim is paused, so the GCS never sees the link drop.
            self._last_heartbeat_wall_s = wall_time_s
            snapshot = self.streams.last_snapshot
            if snapshot is None:
                self.streams.send_boot_heartbeat()
            else:
                self.streams.send_now(mavlink2.MAVLINK_MSG_ID_HEARTBEAT)

    def publish(self, snapshot: TelemetrySnapshot) -> None:
        """Send the telemetry streams due at ``snapshot.time_us`` (sim time) and mission events."""
        self.missions.current_seq = snapshot.mission_seq_current
        self.streams.publish(snapshot)

    def statustext(self, severity: Severity, text: str) -> None:
        """STATUSTEXT; text longer than 50 characters goes out in chunks with a common id (MAVLink 2)."""
        data = text.encode("utf-8", errors="replace")
        if len(data) <= _STATUSTEXT_LEN:
            self.mav.statustext_send(int(severity), data)
            return
        self._statustext_id = self._statustext_id % 65535 + 1
        chunks = [data[i : i + _STATUSTEXT_LEN] for i in range(0, len(data), _STATUSTEXT_LEN)]
        if len(chunks[-1]) == _STATUSTEXT_LEN:
            chunks.append(b"")  # the last chunk must be NUL-terminated
        for seq, chunk in enumerate(chunks):
            self.mav.statustext_send(int(severity), chunk, self._statustext_id, seq)

    @property
    def gcs_heartbeat_age_s(self) -> float:
        """Wall seconds since the last GCS HEARTBEAT (inf if none yet), for the GCS-loss failsafe."""
        if self._last_gcs_heartbeat_wall_s is None:
            return math.inf
        return max(0.0, self._wall_time_s - self._last_gcs_heartbeat_wall_s)

    @property
    def peer_address(self) -> tuple[str, int] | None:
        """Where replies and telemetry go: the default target until a valid message arrives, then its sender."""
        return self._endpoint.link.peer

    @property
    def local_port(self) -> int:
        return self._endpoint.link.local_address[1]

    @property
    def stats(self) -> GcsServerStats:
        c = self._endpoint.counters
        m = self.missions.stats
        return GcsServerStats(
            datagrams=c.datagrams_in,
            messages=c.messages_in,
            malformed=c.malformed,
            unknown_message_ids=c.unknown_message_ids,
            rejected_unsigned=c.rejected_unsigned,
            rejected_bad_signature=c.rejected_bad_signature,
            not_for_us=self._not_for_us,
            handler_errors=self._handler_errors,
            commands=self.commands.stats.received,
            command_duplicates=self.commands.stats.duplicates,
            mission_uploads_accepted=m.uploads_accepted,
            mission_uploads_refused=m.uploads_refused,
            mission_uploads_failed=m.uploads_failed,
            param_sets_refused=self.params.stats.sets_refused,
            setpoints_used=self.setpoints.stats.used,
            setpoints_dropped=self.setpoints.stats.dropped,
            ftp_requests=self.ftp.stats.requests,
            manual_inputs_used=self.manual.stats.used,
        )

    def close(self) -> None:
        self._endpoint.close()

    # ---- dispatch ----------------------------------------------------------------------------------------
    def _for_us(self, msg: mavlink2.MAVLink_message) -> bool:
        # MANUAL_CONTROL names its system ``target`` (and has no component)
        target_system = getattr(msg, "target_system", None)
        if target_system is None:
            target_system = getattr(msg, "target", 0)
        target_component = getattr(msg, "target_component", 0)
        return target_system in (0, self.system_id) and target_component in (0, self.component_id)

    def _dispatch(self, msg: mavlink2.MAVLink_message, wall_time_s: float) -> None:
        kind = msg.get_type()
        if kind == "HEARTBEAT":
            if msg.type == mavlink2.MAV_TYPE_GCS or msg.autopilot == mavlink2.MAV_AUTOPILOT_INVALID:
                self._last_gcs_heartbeat_wall_s = wall_time_s
            return
        if not self._for_us(msg):
            self._not_for_us += 1
            return
        try:
            if kind in CommandProtocol.HANDLED:
                self.commands.handle(msg, wall_time_s)
            elif kind in MissionProtocol.HANDLED:
                self.missions.handle(msg, wall_time_s)
            elif kind in ParamProtocol.HANDLED:
                self.params.handle(msg)
            elif kind in SetpointProtocol.HANDLED:
                self.setpoints.handle(msg)
            elif kind in FtpProtocol.HANDLED:
                self.ftp.handle(msg)
            elif kind in ManualControlProtocol.HANDLED:
                self.manual.handle(msg)
        except Exception as exc:  # a vehicle bug or a message we mis-decode must not stop the autopilot
            self._handler_errors += 1
            _log.exception("GCS %s handling failed", kind)
            self.statustext(Severity.ERROR, f"{kind} not handled: {type(exc).__name__}")

    # ---- link-level commands -----------------------------------------------------------------------------
    def _cmd_set_message_interval(self, request: CommandRequest) -> tuple[CommandResult, None]:
        msg_id, interval_us = request.params[0], request.params[1]
        if not (math.isfinite(msg_id) and math.isfinite(interval_us)):
            return CommandResult.DENIED, None
        ok = self.streams.set_interval(int(msg_id), interval_us)
        return (CommandResult.ACCEPTED if ok else CommandResult.DENIED), None

    def _cmd_request_message(self, request: CommandRequest) -> tuple[CommandResult, Callable[[], object] | None]:
        msg_id = request.params[0]
        if not math.isfinite(msg_id) or not self.streams.supports(int(msg_id)):
            return CommandResult.DENIED, None
        if int(msg_id) != mavlink2.MAVLINK_MSG_ID_AUTOPILOT_VERSION and self.streams.last_snapshot is None:
            return CommandResult.TEMPORARILY_REJECTED, None
        return CommandResult.ACCEPTED, lambda: self.streams.send_now(int(msg_id))

    def _cmd_request_capabilities(self, request: CommandRequest) -> tuple[CommandResult, Callable[[], object] | None]:
        del request
        return CommandResult.ACCEPTED, self.streams.send_autopilot_version
