"""The ground-station script says why: the vehicle's reason for a refusal, what it is waiting for, a status
screen, one range error said once, no success after a failsafe, the flight's own sim time, the vehicle name
of a download."""

from __future__ import annotations

import re
import textwrap
import threading
import time
from pathlib import Path

import pytest
from conftest import free_udp_port
from gcs_fakes import FakeVehicle, ServerHarness

from mavlink_bridge.contract.vehicle_api import CommandRequest, CommandResult, Severity
from mavlink_bridge.gcs_server.server import GcsServer
from tools.gcs import cli as gcs

MISSION_YAML = textwrap.dedent(
    """
    name: says_why
    home: {lat_deg: 47.3977419, lon_deg: 8.5455938, alt_m: 488.0}
    mission:
      - takeoff: {alt_m: 10}
      - waypoint: {north_m: 30, east_m: 0, alt_m: 10}
      - waypoint: {north_m: 30, east_m: 20, alt_m: 12}
      - return_to_launch: {}
    """
)


class SayingVehicle(FakeVehicle):
    """A FakeVehicle that says why it refuses a landing (as the commander does: STATUSTEXT after the ack)."""

    server: GcsServer | None = None

    def handle_command(self, request: CommandRequest) -> CommandResult:
        result = super().handle_command(request)
        if result is CommandResult.DENIED and self.server is not None and request.command == 21:
            self.server.statustext(Severity.WARNING, "LAND: not flying")
        return result


@pytest.fixture
def link(tmp_path: Path):
    server_port, gcs_port = free_udp_port(), free_udp_port()
    vehicle = SayingVehicle()
    server = GcsServer(f"udpin:127.0.0.1:{server_port}", vehicle, default_target_url=f"udpout:127.0.0.1:{gcs_port}")
    harness = ServerHarness(server, vehicle)
    mission = tmp_path / "mission.yaml"
    mission.write_text(MISSION_YAML)
    yield harness, ["--connect", f"udpin:127.0.0.1:{gcs_port}", "--wait-s", "5"], mission
    harness.stop()


def _err_line(capsys: pytest.CaptureFixture[str]) -> str:
    err = capsys.readouterr().err
    errors = [line for line in err.splitlines() if line.startswith("gcs: error:")]
    assert len(errors) == 1 and "Traceback" not in err, err
    return errors[0]


def test_a_refusal_carries_the_vehicles_statustext(link, capsys) -> None:
    harness, connect, _ = link
    harness.vehicle.server = harness.server
    assert gcs.main([*connect, "land"]) == 1
    assert _err_line(capsys) == "gcs: error: MAV_CMD_NAV_LAND -> DENIED: LAND: not flying"


def test_a_silent_refusal_says_what_the_ack_means(link, capsys) -> None:
    _, connect, _ = link
    assert gcs.main([*connect, "rtl"]) == 1
    assert _err_line(capsys) == (
        "gcs: error: MAV_CMD_NAV_RETURN_TO_LAUNCH -> DENIED: the vehicle refused it in its present state and gave "
        "no reason"
    )


def test_a_range_error_is_said_once(link, capsys) -> None:
    _, connect, _ = link
    assert gcs.main([*connect, "param", "set", "NAV_ACC_RAD", "999"]) == 1
    line = _err_line(capsys)
    assert line.count("NAV_ACC_RAD") == 1 and line.count("999") == 2, line  # asked 999; "999 m is outside"
    assert "[0.1, 50]" in line


def test_status_shows_what_the_vehicle_reports(link, capsys) -> None:
    _, connect, _ = link
    assert gcs.main([*connect, "status"]) == 0
    out = capsys.readouterr().out
    assert re.search(r"^mode\s+AUTO_LOITER \(disarmed, on_ground\)$", out, re.M), out
    assert re.search(r"^battery\s+87 %$", out, re.M) and re.search(r"^gps\s+fix type 3 \(3D\)$", out, re.M)
    assert re.search(r"^home\s+47\.397742, 8\.545594, 488\.0 m AMSL$", out, re.M)


def test_no_vehicle_says_what_it_waits_for_and_gives_up_clearly(capsys) -> None:
    port = free_udp_port()
    t0 = time.monotonic()
    assert gcs.main(["--connect", f"udpin:127.0.0.1:{port}", "--wait-s", "2", "status"]) == 1
    assert time.monotonic() - t0 < 10.0
    err = capsys.readouterr().err
    assert f"gcs: waiting for a vehicle on udpin:127.0.0.1:{port} (up to 2 s" in err
    assert err.strip().splitlines()[-1].startswith(f"gcs: error: no vehicle heard on udpin:127.0.0.1:{port} within 2 s")


def test_fly_counts_sim_time_from_the_flights_start(link, capsys) -> None:
    harness, connect, mission = link
    with harness.locked():
        harness.sim_time_us = 900_000_000  # the simulator has run 900 s before this flight
    assert gcs.main([*connect, "fly", str(mission), "--no-progress", "--timeout-s", "30"]) == 0
    out = capsys.readouterr().out
    flown = re.search(r"mission complete: 4/4 items, ([0-9.]+) s sim time in ([0-9.]+) s wall", out)
    assert flown is not None, out
    assert float(flown.group(1)) < 60.0


def test_fly_fails_after_a_failsafe_took_over(link, tmp_path, capsys) -> None:
    harness, connect, mission = link

    def failsafe_once_armed() -> None:
        deadline = time.monotonic() + 20.0
        while not harness.vehicle.armed and time.monotonic() < deadline:
            time.sleep(0.01)
        with harness.locked():
            harness.server.statustext(Severity.CRITICAL, "Failsafe: battery_critical: battery critical (9 %)")

    thread = threading.Thread(target=failsafe_once_armed, daemon=True)
    thread.start()
    harness.vehicle.item_period_us = 400_000  # a flight long enough for the message to arrive before the end
    summary = tmp_path / "s.json"
    rc = gcs.main([*connect, "fly", str(mission), "--summary", str(summary), "--no-progress", "--timeout-s", "30"])
    thread.join(5.0)
    assert rc == 1
    assert "failsafe during the mission: Failsafe: battery_critical" in _err_line(capsys)
    assert '"ok": false' in summary.read_text()


def test_download_writes_the_vehicle_asked_for_and_never_a_wrong_default(link, tmp_path, capsys) -> None:
    _, connect, mission = link
    assert gcs.main([*connect, "upload", str(mission)]) == 0
    named, unnamed = tmp_path / "named.yaml", tmp_path / "unnamed.yaml"
    assert gcs.main([*connect, "download", str(named), "--vehicle", "delivery650"]) == 0
    assert gcs.main([*connect, "download", str(unnamed)]) == 0
    assert "vehicle: delivery650" in named.read_text()
    assert "vehicle:" not in unnamed.read_text()
    assert "add --vehicle NAME" in capsys.readouterr().out
