"""A fake VehicleInterface and a threaded GcsServer harness for the GCS protocol tests (no sim needed)."""

from __future__ import annotations

import math
import os
import threading
import time
from collections import Counter
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, replace
from typing import Any

from conftest import free_udp_port

from autopilot.parameters.store import ParamError, ParamSpec, ParamStore
from mavlink_bridge.contract.vehicle_api import (
    CommandRequest,
    CommandResult,
    FlightMode,
    LandedState,
    ManualInput,
    MissionItem,
    MissionResult,
    MissionType,
    PositionTarget,
    TelemetrySnapshot,
    VelocityTarget,
)
from mavlink_bridge.gcs_server.server import GcsServer
from mavlink_bridge.wire.mission_items import GLOBAL_FRAMES

MAV_CMD_NAV_WAYPOINT = 16
MAV_CMD_NAV_RETURN_TO_LAUNCH = 20
MAV_CMD_NAV_LAND = 21
MAV_CMD_NAV_TAKEOFF = 22
MAV_CMD_DO_SET_MODE = 176
MAV_CMD_MISSION_START = 300
MAV_CMD_COMPONENT_ARM_DISARM = 400
FENCE_COMMANDS = frozenset({5001, 5002, 5003, 5004})
MISSION_COMMANDS = frozenset({16, 19, 20, 21, 22, 93, 177, 178, 211})
HOME_LAT_DEG, HOME_LON_DEG, HOME_ALT_M = 47.3977419, 8.5455938, 488.0

PARAM_SPECS = (
    ParamSpec("MC_ROLL_P", 8.0, 0.0, 50.0, "1/s", "roll angle gain"),
    ParamSpec("MPC_XY_VEL_MAX", 5.0, 0.5, 20.0, "m/s", "horizontal speed limit"),
    ParamSpec("NAV_ACC_RAD", 1.0, 0.1, 50.0, "m", "acceptance radius"),
)


def waypoint(seq: int, north_e7: int, east_e7: int, alt_m: float = 10.0) -> MissionItem:
    """A global waypoint whose lat/lon are exact in degE7 (so a round trip compares equal)."""
    return MissionItem(
        seq=seq,
        command=MAV_CMD_NAV_WAYPOINT,
        frame=6,
        param2=1.0,
        x_lat_deg=(round(HOME_LAT_DEG * 1e7) + north_e7) / 1e7,
        y_lon_deg=(round(HOME_LON_DEG * 1e7) + east_e7) / 1e7,
        z_alt_m=alt_m,
    )


def fence_circle(seq: int, radius_m: float) -> MissionItem:
    """MAV_CMD_NAV_FENCE_CIRCLE_EXCLUSION (5004) around a point near home."""
    return replace(waypoint(seq, 500, 100, 0.0), command=5004, param1=radius_m, param2=0.0)


class FakeVehicle:
    """Validates missions like an autopilot would, records commands, keeps params in a ParamStore."""

    def __init__(self) -> None:
        self.missions: dict[MissionType, list[MissionItem]] = {t: [] for t in MissionType}
        self.replace_calls = 0
        self.command_calls: Counter[int] = Counter()
        self.requests: list[CommandRequest] = []
        self.position_targets: list[PositionTarget] = []
        self.velocity_targets: list[VelocityTarget] = []
        self.manual_inputs: list[ManualInput] = []
        self.armed = False
        self.mode = FlightMode.AUTO_LOITER
        self.arming_refused = False
        self.params = ParamStore(PARAM_SPECS)
        self.current_seq = 0
        self.pending_reached: list[int] = []  # drained into the next snapshot
        self.item_period_us = 50_000  # in AUTO_MISSION and armed, one item is "reached" per this much sim time
        self._next_item_us: int | None = None
        self.not_ready_until_us = 0  # missions are refused ("no position fix yet") before this sim time
        self.time_us = 0

    # VehicleInterface ------------------------------------------------------------------------------------
    def handle_command(self, request: CommandRequest) -> CommandResult:
        self.command_calls[request.command] += 1
        self.requests.append(request)
        if request.command == MAV_CMD_COMPONENT_ARM_DISARM:
            if request.params[0] == 1.0:
                if self.arming_refused:
                    return CommandResult.DENIED
                self.armed = True
            else:
                self.armed = False
            return CommandResult.ACCEPTED
        if request.command == MAV_CMD_DO_SET_MODE:
            try:
                self.mode = FlightMode.from_px4(int(request.params[1]), int(request.params[2]))
            except ValueError:
                return CommandResult.DENIED
            return CommandResult.ACCEPTED
        if request.command in (MAV_CMD_NAV_TAKEOFF, MAV_CMD_NAV_LAND, MAV_CMD_NAV_RETURN_TO_LAUNCH):
            return CommandResult.ACCEPTED if self.armed else CommandResult.DENIED
        if request.command == MAV_CMD_MISSION_START:
            if not self.missions[MissionType.MISSION]:
                return CommandResult.DENIED
            self.mode = FlightMode.AUTO_MISSION
            return CommandResult.ACCEPTED
        return CommandResult.UNSUPPORTED

    def mission_items(self, mission_type: MissionType) -> list[MissionItem]:
        return list(self.missions[mission_type])

    def replace_mission(self, mission_type: MissionType, items: list[MissionItem]) -> tuple[MissionResult, str]:
        self.replace_calls += 1
        if self.time_us < self.not_ready_until_us:
            return MissionResult.ERROR, "no position fix yet"
        known = FENCE_COMMANDS if mission_type is MissionType.FENCE else MISSION_COMMANDS
        for item in items:
            if item.command not in known:
                return MissionResult.UNSUPPORTED, f"item {item.seq}: command {item.command} not supported"
            if item.frame in GLOBAL_FRAMES and not -90.0 <= item.x_lat_deg <= 90.0:
                return MissionResult.INVALID_PARAM5_X, f"item {item.seq}: latitude {item.x_lat_deg:g} out of range"
            if not math.isfinite(item.z_alt_m):
                return MissionResult.INVALID_PARAM7, f"item {item.seq}: altitude is not a number"
        self.missions[mission_type] = list(items)
        return MissionResult.ACCEPTED, ""

    def set_position_target(self, target: PositionTarget) -> bool:
        self.position_targets.append(target)
        return True

    def set_velocity_target(self, target: VelocityTarget) -> bool:
        self.velocity_targets.append(target)
        return True

    def set_manual_input(self, sticks: ManualInput) -> bool:
        self.manual_inputs.append(sticks)
        return True

    def set_current_mission_item(self, seq: int) -> bool:
        if 0 <= seq < len(self.missions[MissionType.MISSION]):
            self.current_seq = seq
            return True
        return False

    def param_names(self) -> list[str]:
        return self.params.names()

    def param_get(self, name: str) -> float | None:
        return self.params.get(name) if name in self.params else None

    def param_set(self, name: str, value: float) -> tuple[bool, float, str]:
        try:
            return True, self.params.set(name, value), ""
        except ParamError as exc:
            return False, self.params.get(name), str(exc)

    # telemetry -------------------------------------------------------------------------------------------
    def _fly(self, time_us: int) -> None:
        """Pretend to fly the mission: reach one item per ``item_period_us``, then land and disarm."""
        items = self.missions[MissionType.MISSION]
        if not (self.armed and self.mode is FlightMode.AUTO_MISSION and items):
            self._next_item_us = None
            return
        if self._next_item_us is None:
            self._next_item_us = time_us + self.item_period_us
        if time_us >= self._next_item_us:
            self.pending_reached.append(self.current_seq)
            self._next_item_us += self.item_period_us
            if self.current_seq + 1 < len(items):
                self.current_seq += 1
            else:
                self.armed = False
                self.mode = FlightMode.AUTO_LOITER

    def snapshot(self, time_us: int) -> TelemetrySnapshot:
        self.time_us = time_us
        self._fly(time_us)
        done = bool(self.missions[MissionType.MISSION]) and not self.armed and self.current_seq > 0
        return TelemetrySnapshot(
            time_us=time_us,
            armed=self.armed,
            mode=self.mode,
            landed_state=LandedState.IN_AIR if self.armed else LandedState.ON_GROUND,
            q_ned_frd=(1.0, 0.0, 0.0, 0.0),
            rate_frd_rad_s=(0.0, 0.0, 0.0),
            pos_ned_m=(1.0, 2.0, -3.0),
            vel_ned_m_s=(0.5, 0.0, 0.0),
            lat_deg=HOME_LAT_DEG,
            lon_deg=HOME_LON_DEG,
            alt_amsl_m=HOME_ALT_M + 3.0,
            alt_rel_m=3.0,
            home_lat_deg=HOME_LAT_DEG,
            home_lon_deg=HOME_LON_DEG,
            home_alt_amsl_m=HOME_ALT_M,
            home_valid=True,
            gps_fix_type=3,
            gps_satellites=12,
            gps_eph_m=0.8,
            gps_epv_m=1.2,
            battery_voltage_v=16.2,
            battery_current_a=12.0,
            battery_remaining_pct=87.0,
            throttle_pct=45.0,
            sensors_present=0x3F,
            sensors_enabled=0x3F,
            sensors_health=0x3F,
            mission_seq_current=self.current_seq,
            mission_count=len(self.missions[MissionType.MISSION]),
            mission_reached=self._drain_reached(),
            mission_state=5 if done else 2,
        )

    def _drain_reached(self) -> list[int]:
        reached, self.pending_reached = self.pending_reached, []
        return reached


@dataclass
class ServerHarness:
    """Runs ``server.poll`` + ``publish`` in a thread, sim time advancing ``sim_step_us`` per loop."""

    server: GcsServer
    vehicle: FakeVehicle
    sim_step_us: int = 4000
    loop_sleep_s: float = 0.0005
    sim_time_us: int = 0
    running: bool = True
    error: BaseException | None = None

    def __post_init__(self) -> None:
        self._lock = threading.Lock()
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()

    def _run(self) -> None:
        try:
            while self.running:
                with self._lock:
                    self.sim_time_us += self.sim_step_us
                    self.server.poll(self.sim_time_us, time.monotonic())
                    self.server.publish(self.vehicle.snapshot(self.sim_time_us))
                time.sleep(self.loop_sleep_s)
        except BaseException as exc:  # surfaced by stop()
            self.error = exc

    def locked(self) -> threading.Lock:
        """Hold to touch the vehicle or server from the test thread."""
        return self._lock

    def stop(self) -> None:
        self.running = False
        self._thread.join(timeout=5.0)
        self.server.close()
        if self.error is not None:
            raise self.error


@contextmanager
def served_fake_vehicle() -> Iterator[tuple[FakeVehicle, GcsServer, ServerHarness, Any]]:
    """A FakeVehicle behind a GcsServer on a free loopback port (its harness running) and a pymavlink GCS
    connection to it (system 255, component 190): ``(vehicle, server, harness, conn)``; all closed after."""
    os.environ.setdefault("MAVLINK20", "1")
    from pymavlink import mavutil

    port = free_udp_port()
    vehicle = FakeVehicle()
    server = GcsServer(f"udpin:127.0.0.1:{port}", vehicle, default_target_url=f"udpout:127.0.0.1:{free_udp_port()}")
    harness = ServerHarness(server, vehicle)
    conn = mavutil.mavlink_connection(f"udpout:127.0.0.1:{port}", source_system=255, source_component=190)
    try:
        yield vehicle, server, harness, conn
    finally:
        conn.close()
        harness.stop()
