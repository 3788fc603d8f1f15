"""Loopback SITL missions (issue 5 "Must show"): sim and autopilot as two processes, a ground station over UDP.

The delivery mission flown by ``python -m tools.gcs fly`` (items reached in order, payload released at the
gripper item), RTL and LAND commanded in flight, a speed parameter changed in flight, invalid missions
refused in flight while the old one completes, and upload/download round trips with the real autopilot.
"""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
import time
from collections.abc import Callable, Iterator
from dataclasses import replace
from pathlib import Path

import pytest
from conftest import REPO_ROOT
from sitl_procs import (
    STARTUP_TIMEOUT_S,
    SitlRun,
    connect_gcs,
    landed_disarmed,
    logs,
    read_json,
    sitl_pair,
    upload_arm_start,
)

from autopilot.mission.files import load_mission_file
from autopilot.telemetry.recording_reader import read_recording
from mavlink_bridge.contract.mav_enums import MavCmd
from mavlink_bridge.contract.vehicle_api import FlightMode, MissionItem, MissionResult
from mavlink_bridge.gcs_client.client import GcsClient, MissionUploadError, VehicleStatus
from tools.gcs import cli as gcs_script

pytestmark = [pytest.mark.sitl, pytest.mark.slow]

MISSIONS = REPO_ROOT / "missions"
CONTROL_STEP_S = 0.004  # 250 Hz lockstep
MISSION_STATE_NOT_STARTED = 2
HOME = "home: {lat_deg: 30.2635, lon_deg: 120.1233, alt_m: 12.0}"
# Short routes for the command/parameter/refusal flights (x500, no wind: the point is the protocol).
SHORT_ROUTE = f"""\
name: short_route
{HOME}
vehicle: x500
speed_m_s: 5.0
mission:
  - takeoff: {{alt_m: 8}}
  - waypoint: {{north_m: 40, east_m: 0, alt_m: 8, accept_radius_m: 1.0}}
  - waypoint: {{north_m: 40, east_m: 25, alt_m: 8, accept_radius_m: 1.0}}
  - land: {{}}
"""
LONG_LEG = f"""\
name: long_leg
{HOME}
vehicle: x500
speed_m_s: 8.0
mission:
  - takeoff: {{alt_m: 8}}
  - waypoint: {{north_m: 130, east_m: 0, alt_m: 8, accept_radius_m: 1.0}}
  - land: {{}}
"""


def _write(tmp_path: Path, text: str, name: str = "mission.yaml") -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


def _north(s: VehicleStatus) -> float:
    return s.pos_ned_m[0] if s.pos_ned_m is not None else -math.inf


def _gripper_seq(items: list[MissionItem]) -> int:
    return next(i for i, item in enumerate(items) if item.command == MavCmd.DO_GRIPPER)


def _assert_same_items(got: list[MissionItem], want: list[MissionItem]) -> None:
    """Equal at the wire's resolution: degE7 positions, float32 altitudes and parameters (NaN equals NaN)."""
    assert [(i.command, i.frame, i.autocontinue) for i in got] == [(i.command, i.frame, i.autocontinue) for i in want]
    for g, w in zip(got, want, strict=True):
        assert (g.x_lat_deg, g.y_lon_deg) == pytest.approx((w.x_lat_deg, w.y_lon_deg), abs=1e-7)
        assert g.z_alt_m == pytest.approx(w.z_alt_m, abs=1e-4)
        assert (g.param1, g.param2, g.param3, g.param4) == pytest.approx(
            (w.param1, w.param2, w.param3, w.param4), nan_ok=True
        )


# ---- the delivery mission through the ground-station script ---------------------------------------------------
def test_delivery_mission_through_gcs_fly(tmp_path: Path) -> None:
    """``tools.gcs fly`` a delivery mission (the default's items and wind, its drop point 36 m out instead of 144 m:
    ``make run``'s test flies the default itself): exit 0, every item reached in order, payload at the gripper
    item."""
    default = (MISSIONS / "delivery.yaml").read_text()
    short = default.replace("north_m: 60, east_m: 40", "north_m: 15, east_m: 10").replace(
        "north_m: 120, east_m: 80", "north_m: 30, east_m: 20"
    )
    assert short.count("north_m: 30, east_m: 20") == 3, "missions/delivery.yaml changed: update this test"
    mission = _write(tmp_path, short, "delivery_short.yaml")
    plan = load_mission_file(mission)
    rrd, summary_path = tmp_path / "flight.rrd", tmp_path / "gcs_summary.json"
    with sitl_pair(tmp_path, mission, seed=2, api=True, ap_extra=("--rerun", f"save:{rrd}")) as s:
        assert s.api_url is not None
        with connect_gcs(s.api_url) as observer:  # a second client on the API link sees what the GCS sees
            cmd = [sys.executable, "-m", "tools.gcs", "--connect", s.gcs_url, "fly", str(mission)]
            cmd += ["--summary", str(summary_path), "--no-progress", "--timeout-s", "240"]
            with open(tmp_path / "gcs.log", "wb") as out:
                env = dict(os.environ, PYTHONUNBUFFERED="1")
                fly = subprocess.Popen(cmd, cwd=REPO_ROOT, env=env, stdout=out, stderr=subprocess.STDOUT)
            try:
                deadline = time.monotonic() + 260.0
                while fly.poll() is None and time.monotonic() < deadline:
                    observer.pump(0.1)
            finally:
                if fly.poll() is None:
                    fly.kill()
                fly_rc = fly.wait()
            observer.pump(0.5)
            seen = observer.telemetry()
    assert fly_rc == 0, (tmp_path / "gcs.log").read_text() + logs(tmp_path)
    summary = json.loads(summary_path.read_text())
    n = len(plan.items)
    assert summary["ok"] is True and summary["landed"] is True and summary["disarmed"] is True
    assert summary["items_total"] == summary["items_reached"] == n
    assert seen.items_reached == tuple(range(n))  # MISSION_ITEM_REACHED, each once, in mission order
    assert landed_disarmed(seen)

    ap, sim = read_json(tmp_path / "autopilot_summary.json"), read_json(tmp_path / "sim_summary.json")
    assert ap["reached_seqs"] == list(range(n))  # the autopilot's own log: no item twice, none skipped
    assert ap["landed"] and ap["disarmed"] and ap["payload_released"]
    assert sim["collisions"] == 0 and sim["end_reason"] == "STOPPED"
    assert ap["frames"] == sim["frames"]

    # the payload leaves when the gripper item is reached: sim time of the drop vs the reached event
    gripper = _gripper_seq(plan.items)
    texts = read_recording(rrd).text_log()
    reached_at_s = {int(text.split()[-1]): t_us * 1e-6 for t_us, _, text in texts if text.startswith("Reached item")}
    assert list(reached_at_s) == list(range(n))
    released_s = sim["payload_released_at_s"]
    assert isinstance(released_s, float)
    assert abs(released_s - reached_at_s[gripper]) <= CONTROL_STEP_S + 1e-9
    assert released_s > reached_at_s[gripper - 1] - CONTROL_STEP_S  # not before the drop point was reached
    final_ned = sim["final_pos_ned_m"]
    assert isinstance(final_ned, list) and math.hypot(final_ned[0], final_ned[1]) < 2.0  # landed back at home


# ---- commands in flight -----------------------------------------------------------------------------------
@pytest.mark.parametrize(
    ("command", "mode"), [("rtl", FlightMode.AUTO_RTL), ("land", FlightMode.AUTO_LAND)], ids=["rtl", "land"]
)
def test_rtl_and_land_commanded_in_flight(tmp_path: Path, command: str, mode: FlightMode) -> None:
    """Mid-way along the first leg: RTL flies home and lands there, LAND lands where it is; both disarm."""
    mission = _write(tmp_path, SHORT_ROUTE)
    plan = load_mission_file(mission)
    with sitl_pair(tmp_path, mission) as s, connect_gcs(s.gcs_url) as client:
        client.set_param("MIS_RTL_ALT", 8.0)  # return at the cruise altitude (no climb): a shorter flight
        upload_arm_start(client, plan)
        client.wait_until(lambda st: _north(st) > 20.0, 120.0)
        if command == "rtl":
            client.rtl()
        else:
            client.land()
        client.wait_until(lambda st: st.mode is mode, 20.0)
        end = client.wait_until(landed_disarmed, 180.0)
    assert plan.items and len(plan.items) - 1 not in end.items_reached  # the mission was cut short
    ap, sim = read_json(tmp_path / "autopilot_summary.json"), read_json(tmp_path / "sim_summary.json")
    assert mode.name in [m["mode"] for m in ap["mode_history"]]  # type: ignore[union-attr]
    assert ap["landed"] and ap["disarmed"] and sim["collisions"] == 0
    final_ned = sim["final_pos_ned_m"]
    assert isinstance(final_ned, list)
    off_home_m = math.hypot(final_ned[0], final_ned[1])
    if command == "rtl":
        assert off_home_m < 1.5
    else:  # landed on the first leg, past where LAND was sent, short of the first waypoint (north 40 m, 1 m radius):
        # how far past 20 m depends on wall-clock latency at --speed max (stale telemetry, the command's trip)
        assert 20.0 < final_ned[0] < 39.0 and abs(final_ned[1]) < 2.0


# ---- a parameter changed in flight ---------------------------------------------------------------------------
def _ground_speeds(client: GcsClient, until: Callable[[VehicleStatus], bool], timeout_s: float) -> list[float]:
    """Horizontal speeds seen in telemetry until ``until`` holds."""
    speeds: list[float] = []
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        client.pump(0.05)
        st = client.telemetry()
        if st.vel_ned_m_s is not None:
            speeds.append(math.hypot(st.vel_ned_m_s[0], st.vel_ned_m_s[1]))
        if until(st):
            return speeds
    raise AssertionError(f"condition not met within {timeout_s} s")


def test_speed_limit_changed_in_flight_takes_effect(tmp_path: Path) -> None:
    """MPC_XY_VEL_MAX lowered from 12 to 3 m/s on a leg flown at 8 m/s: the ground speed follows it."""
    mission = _write(tmp_path, LONG_LEG)
    plan = load_mission_file(mission)
    with sitl_pair(tmp_path, mission) as s, connect_gcs(s.gcs_url) as client:
        upload_arm_start(client, plan)
        client.wait_until(lambda st: _north(st) > 15.0, 120.0)
        before = _ground_speeds(client, lambda st: _north(st) > 40.0, 60.0)
        assert client.set_param("MPC_XY_VEL_MAX", 3.0) == 3.0
        t_set = client.telemetry().sim_time_s or 0.0
        client.wait_until(lambda st: (st.sim_time_s or 0.0) > t_set + 3.0, 60.0)  # braking from 8 to 3 m/s
        after = _ground_speeds(client, lambda st: _north(st) > 100.0, 120.0)
        assert client.get_param("MPC_XY_VEL_MAX") == 3.0
    assert max(before) > 7.0  # cruising at the mission's 8 m/s
    assert max(after) < 3.4 and min(after) > 2.5  # at the new limit, not stopped


# ---- an invalid mission uploaded in flight -------------------------------------------------------------------
BAD_ITEMS: list[tuple[str, Callable[[MissionItem], MissionItem], MissionResult]] = [
    ("latitude 95", lambda it: replace(it, x_lat_deg=95.0), MissionResult.INVALID_PARAM5_X),
    ("unknown command", lambda it: replace(it, command=31999), MissionResult.UNSUPPORTED),
    ("NaN altitude", lambda it: replace(it, z_alt_m=math.nan), MissionResult.INVALID_PARAM7),
]


def test_invalid_mission_in_flight_is_refused_and_the_old_one_completes(tmp_path: Path) -> None:
    mission = _write(tmp_path, SHORT_ROUTE)
    plan = load_mission_file(mission)
    n = len(plan.items)
    with sitl_pair(tmp_path, mission) as s, connect_gcs(s.gcs_url) as client:
        upload_arm_start(client, plan)
        client.wait_until(lambda st: _north(st) > 5.0, 120.0)  # airborne, on the first leg
        for what, corrupt, result in BAD_ITEMS:
            new = [*plan.items, replace(plan.items[2], x_lat_deg=plan.items[2].x_lat_deg + 1e-4)]
            new[3] = corrupt(new[3])
            with pytest.raises(MissionUploadError) as err:
                client.upload_mission(new)
            assert err.value.result is result, what
        _assert_same_items(client.download_mission(), plan.items)  # the old mission is still the mission
        end = client.wait_until(landed_disarmed, 240.0)
        client.pump(0.5)
        end = client.telemetry()
    assert end.items_reached == tuple(range(n)), logs(tmp_path)
    ap = read_json(tmp_path / "autopilot_summary.json")
    assert ap["reached_seqs"] == list(range(n)) and ap["items_total"] == n
    assert [m["mode"] for m in ap["mode_history"]] == ["AUTO_MISSION"]  # type: ignore[union-attr]


# ---- upload / download round trips with the real autopilot ---------------------------------------------------
@pytest.fixture(scope="module")
def idle_sitl(tmp_path_factory: pytest.TempPathFactory) -> Iterator[SitlRun]:
    """One idle pair for the round trips (nothing flies)."""
    log_dir = tmp_path_factory.mktemp("round_trip")
    with sitl_pair(log_dir, MISSIONS / "delivery.yaml") as s:
        with connect_gcs(s.gcs_url) as client:
            client.wait_until(lambda st: st.gps_fix_type >= 3 and st.home is not None, STARTUP_TIMEOUT_S)
        yield s


@pytest.mark.parametrize("name", ["delivery.yaml", "delivery.waypoints", "delivery.plan"])
def test_upload_download_round_trip(idle_sitl: SitlRun, tmp_path: Path, name: str) -> None:
    """``tools.gcs upload FILE`` then ``download OUT`` (same format): the file read back equals the original."""
    src = MISSIONS / name
    out = tmp_path / f"downloaded{src.suffix}"
    connect = ["--connect", idle_sitl.gcs_url, "--wait-s", "60", "--timeout-step-s", "20"]
    assert gcs_script.main([*connect, "clear"]) == 0
    assert gcs_script.main([*connect, "upload", str(src)]) == 0
    assert gcs_script.main([*connect, "download", str(out)]) == 0
    sent, got = load_mission_file(src), load_mission_file(out)
    _assert_same_items(got.items, sent.items)
    if src.suffix != ".waypoints":  # QGC WPL has no fence
        _assert_same_items(got.fence, sent.fence)
        assert got.fence
    # home is the EKF's estimate at the first fix (GPS noise): within a metre (1e-5 deg) of the world's home
    assert (got.home.lat_deg, got.home.lon_deg) == pytest.approx((sent.home.lat_deg, sent.home.lon_deg), abs=1e-5)


def test_mission_current_reports_the_mission_state(idle_sitl: SitlRun) -> None:
    """After an upload and before MISSION_START: MISSION_CURRENT says NOT_STARTED with the item count."""
    plan = load_mission_file(MISSIONS / "delivery.yaml")
    with connect_gcs(idle_sitl.gcs_url) as client:
        client.upload_mission(plan.items)
        status = client.wait_until(lambda st: st.mission_count == len(plan.items), 30.0)
        client.pump(1.5)  # MISSION_CURRENT is streamed (PX4: 1 Hz) besides being sent on change
        status = client.telemetry()
    assert status.mission_count == len(plan.items)
    assert status.mission_state == MISSION_STATE_NOT_STARTED


def test_600_item_upload_and_download(idle_sitl: SitlRun) -> None:
    with connect_gcs(idle_sitl.gcs_url) as client:
        home = client.wait_until(lambda st: st.home is not None, 60.0).home
        assert home is not None
        lat_e7, lon_e7 = round(home.lat_deg * 1e7), round(home.lon_deg * 1e7)
        takeoff = MissionItem(seq=0, command=MavCmd.NAV_TAKEOFF, frame=6, z_alt_m=10.0)
        route = [
            MissionItem(
                seq=i,
                command=MavCmd.NAV_WAYPOINT,
                frame=6,
                x_lat_deg=(lat_e7 + 50 * (i % 40)) / 1e7,
                y_lon_deg=(lon_e7 + 50 * (i // 40)) / 1e7,
                z_alt_m=10.0 + (i % 7),
            )
            for i in range(1, 600)
        ]
        items = [takeoff, *route]
        client.upload_mission(items)
        got = client.download_mission()
    assert len(got) == 600
    _assert_same_items(got, items)
