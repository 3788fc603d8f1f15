"""The ground-station script against a GcsServer with a fake flying vehicle: fly + summary, upload/download
in every file format, params, and exit codes."""

from __future__ import annotations

import json
import textwrap

import pytest
from conftest import free_udp_port
from gcs_fakes import FakeVehicle, ServerHarness

from autopilot.mission.files import load_mission_file
from mavlink_bridge.contract.vehicle_api import MissionType
from mavlink_bridge.gcs_server.server import GcsServer
from tools.gcs import cli as gcs

MISSION_YAML = textwrap.dedent(
    """
    name: script_test
    home: {lat_deg: 47.3977419, lon_deg: 8.5455938, alt_m: 488.0}
    speed_m_s: 4.0
    mission:
      - takeoff: {alt_m: 10}
      - waypoint: {north_m: 30, east_m: 0, alt_m: 10}
      - payload_release: {}
      - waypoint: {north_m: 30, east_m: 20, alt_m: 12}
      - return_to_launch: {}
    fence:
      - exclusion_circle: {north_m: 60, east_m: 10, radius_m: 8}
    """
)


def _assert_same_items(got_items: list, want_items: list) -> None:
    """Equal up to the wire's resolution: degE7 positions, float32 parameters (NaN equals NaN)."""
    assert [(i.command, i.frame) for i in got_items] == [(i.command, i.frame) for i in want_items]
    for got, want in zip(got_items, want_items, strict=True):
        assert got.x_lat_deg == pytest.approx(want.x_lat_deg, abs=1e-7)
        assert got.y_lon_deg == pytest.approx(want.y_lon_deg, abs=1e-7)
        assert got.z_alt_m == pytest.approx(want.z_alt_m, abs=1e-4)
        params = (got.param1, got.param2, got.param3, got.param4)
        assert params == pytest.approx((want.param1, want.param2, want.param3, want.param4), nan_ok=True)


@pytest.fixture
def vehicle_link(tmp_path):
    server_port, gcs_port = free_udp_port(), free_udp_port()
    vehicle = FakeVehicle()
    server = GcsServer(f"udpin:127.0.0.1:{server_port}", vehicle, default_target_url=f"udpout:127.0.0.1:{gcs_port}")
    harness = ServerHarness(server, vehicle)
    mission = tmp_path / "mission.yaml"
    mission.write_text(MISSION_YAML)
    yield harness, ["--connect", f"udpin:127.0.0.1:{gcs_port}", "--wait-s", "5"], mission
    harness.stop()


def test_fly_uploads_arms_starts_and_waits_for_landing(vehicle_link, tmp_path, capsys) -> None:
    harness, connect, mission = vehicle_link
    with harness.locked():
        harness.vehicle.not_ready_until_us = harness.sim_time_us + 3_000_000  # refuses uploads for 3 s of sim
    summary_path = tmp_path / "out" / "gcs_summary.json"
    rc = gcs.main([*connect, "fly", str(mission), "--summary", str(summary_path), "--no-progress", "--timeout-s", "30"])
    assert rc == 0, capsys.readouterr().err
    summary = json.loads(summary_path.read_text())
    plan = load_mission_file(mission)
    assert summary["ok"] is True
    assert summary["items_total"] == summary["items_reached"] == len(plan.items)
    assert summary["landed"] is True and summary["disarmed"] is True
    assert summary["sim_time_s"] > 0 and summary["wall_time_s"] > 0
    _assert_same_items(harness.vehicle.missions[MissionType.MISSION], plan.items)
    assert len(harness.vehicle.missions[MissionType.FENCE]) == len(plan.fence) > 0
    assert harness.vehicle.replace_calls > 2  # the first refused uploads were retried


def test_fly_reports_failure_when_arming_is_refused(vehicle_link, tmp_path, capsys) -> None:
    harness, connect, mission = vehicle_link
    harness.vehicle.arming_refused = True
    summary_path = tmp_path / "s.json"
    rc = gcs.main([*connect, "fly", str(mission), "--summary", str(summary_path), "--no-progress", "--timeout-s", "1"])
    err = capsys.readouterr().err
    assert rc == 1
    errors = [line for line in err.splitlines() if line.startswith("gcs: error:")]  # the rest: what it waited for
    assert len(errors) == 1 and "arming refused" in errors[0]
    assert json.loads(summary_path.read_text())["ok"] is False


@pytest.mark.parametrize("suffix", [".plan", ".yaml", ".waypoints"])
def test_upload_then_download_round_trip(vehicle_link, tmp_path, suffix, capsys) -> None:
    _harness, connect, mission = vehicle_link
    assert gcs.main([*connect, "upload", str(mission)]) == 0
    out = tmp_path / f"downloaded{suffix}"
    assert gcs.main([*connect, "download", str(out)]) == 0
    downloaded = load_mission_file(out)
    original = load_mission_file(mission)
    _assert_same_items(downloaded.items, original.items)
    if suffix == ".waypoints":
        assert "fence items not saved" in capsys.readouterr().out
    else:
        assert len(downloaded.fence) == len(original.fence)


def test_upload_of_a_missing_file_fails(vehicle_link, tmp_path, capsys) -> None:
    _harness, connect, _ = vehicle_link
    assert gcs.main([*connect, "upload", str(tmp_path / "none.yaml")]) == 1
    assert capsys.readouterr().err.count("\n") == 1


def test_clear_and_simple_commands(vehicle_link, capsys) -> None:
    harness, connect, mission = vehicle_link
    assert gcs.main([*connect, "upload", str(mission)]) == 0
    assert gcs.main([*connect, "clear"]) == 0
    assert harness.vehicle.missions[MissionType.MISSION] == []
    assert harness.vehicle.missions[MissionType.FENCE] == []
    assert gcs.main([*connect, "arm"]) == 0
    assert gcs.main([*connect, "mode", "rtl"]) == 0
    assert gcs.main([*connect, "mode", "sideways"]) == 1
    assert gcs.main([*connect, "land"]) == 0
    assert gcs.main([*connect, "disarm"]) == 0
    assert gcs.main([*connect, "start"]) == 1  # no mission: refused, exit code says so
    assert "MISSION_START" in capsys.readouterr().err


def test_params_and_exit_codes(vehicle_link, capsys) -> None:
    _harness, connect, _ = vehicle_link
    assert gcs.main([*connect, "param", "set", "NAV_ACC_RAD", "2.5"]) == 0
    assert gcs.main([*connect, "param", "get", "NAV_ACC_RAD"]) == 0
    assert "NAV_ACC_RAD = 2.5" in capsys.readouterr().out
    assert gcs.main([*connect, "param", "set", "NAV_ACC_RAD", "1000"]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "refused" in err and "still 2.5" in err
    assert gcs.main([*connect, "param", "list"]) == 0
    assert "MC_ROLL_P" in capsys.readouterr().out
    assert gcs.main([*connect, "param", "get", "NOPE"]) == 1


def test_no_vehicle_is_a_one_line_error(capsys) -> None:
    port = free_udp_port()
    assert gcs.main(["--connect", f"udpin:127.0.0.1:{port}", "--wait-s", "0.3", "arm"]) == 1
    err = capsys.readouterr().err
    errors = [line for line in err.splitlines() if line.startswith("gcs: error:")]
    assert len(errors) == 1 and "no vehicle heard" in errors[0]
    assert gcs.connect_url(None, 3) == "udpin:127.0.0.1:14553"  # the default port follows --instance
    assert gcs.connect_url("udpin:127.0.0.1:24550", 3) == "udpin:127.0.0.1:24550"  # a typed URL is used as typed


def test_a_udpout_link_talks_first_and_flies(tmp_path, capsys) -> None:
    """``--connect udpout:`` (the vehicle's own port): the ground station speaks first and is answered there."""
    server_port, unused_port = free_udp_port(), free_udp_port()
    vehicle = FakeVehicle()
    server = GcsServer(f"udpin:127.0.0.1:{server_port}", vehicle, default_target_url=f"udpout:127.0.0.1:{unused_port}")
    harness = ServerHarness(server, vehicle)
    mission = tmp_path / "mission.yaml"
    mission.write_text(MISSION_YAML)
    connect = ["--connect", f"udpout:127.0.0.1:{server_port}", "--wait-s", "5"]
    try:
        assert gcs.main([*connect, "status"]) == 0, capsys.readouterr().err
        assert gcs.main([*connect, "fly", str(mission), "--no-progress", "--timeout-s", "30"]) == 0
    finally:
        harness.stop()
    assert "mission complete: 6/6 items" in capsys.readouterr().out
