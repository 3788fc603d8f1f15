"""GCS link benchmark: mission upload throughput over loopback and the per-step cost of telemetry publishing.

``python -m tools.benchmarks --only gcs``. The server is polled in a thread the way the
autopilot runner polls it between lockstep frames.
"""

from __future__ import annotations

import socket
import threading
import time

from mavlink_bridge.contract.vehicle_api import (
    CommandRequest,
    CommandResult,
    FlightMode,
    LandedState,
    MissionItem,
    MissionResult,
    MissionType,
    TelemetrySnapshot,
)
from mavlink_bridge.gcs_client.client import GcsClient
from mavlink_bridge.gcs_server.server import GcsServer
from tools.benchmarks import BenchResult


class _StoreVehicle:
    """Stores missions, knows no commands or parameters: the protocol cost alone."""

    def __init__(self) -> None:
        self.missions: dict[MissionType, list[MissionItem]] = {t: [] for t in MissionType}

    def handle_command(self, request: CommandRequest) -> CommandResult:
        del request
        return CommandResult.UNSUPPORTED

    def mission_items(self, mission_type: MissionType) -> list[MissionItem]:
        return list(self.missions[mission_type])

    def replace_mission(self, mission_type: MissionType, items: list[MissionItem]) -> tuple[MissionResult, str]:
        self.missions[mission_type] = list(items)
        return MissionResult.ACCEPTED, ""

    def set_current_mission_item(self, seq: int) -> bool:
        del seq
        return False

    def param_names(self) -> list[str]:
        return []

    def param_get(self, name: str) -> float | None:
        del name
        return None

    def param_set(self, name: str, value: float) -> tuple[bool, float, str]:
        return False, value, f"unknown parameter {name}"


def _snapshot(time_us: int) -> TelemetrySnapshot:
    return TelemetrySnapshot(
        time_us=time_us,
        armed=True,
        mode=FlightMode.AUTO_MISSION,
        landed_state=LandedState.IN_AIR,
        q_ned_frd=(0.99, 0.01, 0.02, 0.1),
        rate_frd_rad_s=(0.01, 0.0, 0.02),
        pos_ned_m=(10.0, 5.0, -12.0),
        vel_ned_m_s=(3.0, 1.0, -0.2),
        lat_deg=47.3978,
        lon_deg=8.5456,
        alt_amsl_m=500.0,
        alt_rel_m=12.0,
        home_lat_deg=47.3977,
        home_lon_deg=8.5455,
        home_alt_amsl_m=488.0,
        home_valid=True,
        gps_fix_type=3,
        gps_satellites=12,
        gps_eph_m=0.8,
        gps_epv_m=1.2,
        battery_voltage_v=16.0,
        battery_current_a=15.0,
        battery_remaining_pct=80.0,
        throttle_pct=50.0,
        sensors_present=0x3F,
        sensors_enabled=0x3F,
        sensors_health=0x3F,
        mission_seq_current=3,
        mission_count=10,
    )


def _free_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def _upload_s(n_items: int) -> float:
    server_port, gcs_port = _free_port(), _free_port()
    vehicle = _StoreVehicle()
    server = GcsServer(f"udpin:127.0.0.1:{server_port}", vehicle, default_target_url=f"udpout:127.0.0.1:{gcs_port}")
    stop = threading.Event()

    def serve() -> None:
        t_us = 0
        while not stop.is_set():
            t_us += 4000
            server.poll(t_us, time.monotonic())
            server.publish(_snapshot(t_us))
            time.sleep(0.0002)

    thread = threading.Thread(target=serve, daemon=True)
    thread.start()
    client = GcsClient(f"udpin:127.0.0.1:{gcs_port}", timeout_s=10.0, retry_s=0.3)
    try:
        client.wait_heartbeat(5.0)
        items = [
            MissionItem(seq=i, command=16, x_lat_deg=(473_900_000 + 100 * i) / 1e7, y_lon_deg=8.54, z_alt_m=10.0)
            for i in range(n_items)
        ]
        t0 = time.perf_counter()
        client.upload_mission(items)
        elapsed = time.perf_counter() - t0
        if vehicle.missions[MissionType.MISSION] != items:
            raise RuntimeError("benchmark upload did not arrive intact")
        return elapsed
    finally:
        client.close()
        stop.set()
        thread.join(timeout=2.0)
        server.close()


def _publish_us_per_step(steps: int, max_stream_speedup: float | None) -> float:
    sink_port = _free_port()
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sink:
        sink.bind(("127.0.0.1", sink_port))
        server = GcsServer(
            f"udpin:127.0.0.1:{_free_port()}",
            _StoreVehicle(),
            default_target_url=f"udpout:127.0.0.1:{sink_port}",
            max_stream_speedup=max_stream_speedup,
        )
        snapshot = _snapshot(0)
        t0 = time.process_time()  # CPU time (user + sys): robust to other load on a shared machine
        for k in range(steps):
            snapshot.time_us = (k + 1) * 4000  # 250 Hz control steps
            server.poll(snapshot.time_us, time.monotonic())
            server.publish(snapshot)
        elapsed = time.process_time() - t0
        server.close()
    return elapsed / steps * 1e6


def run(quick: bool) -> list[BenchResult]:
    n_items = 200 if quick else 600
    upload_s = _upload_s(n_items)
    steps = 2500 if quick else 25000
    uncapped_us = _publish_us_per_step(steps, None)
    capped_us = _publish_us_per_step(steps, 1.0)
    return [
        BenchResult(f"gcs_mission_upload_{n_items}_s", upload_s, note="loopback, server polled like the runner"),
        BenchResult("gcs_mission_upload_items_per_s", n_items / upload_s),
        BenchResult(
            "gcs_poll_publish_us_per_step",
            uncapped_us,
            target="<= 100",
            met=uncapped_us <= 100.0,
            note="CPU per 250 Hz step, default rates in sim time; pymavlink CRC ~25 us/msg",
        ),
        BenchResult(
            "gcs_poll_publish_capped_us_per_step",
            capped_us,
            note="same, tight loop (>> real time) with the default 1x wall-time stream cap",
        ),
    ]
