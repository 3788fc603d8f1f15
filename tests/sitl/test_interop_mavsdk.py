"""Interoperability with MAVSDK-Python 4.x (issue 5): a raw mission uploaded, flown and completed.

Sim and autopilot run as two processes on free loopback ports; the project's GcsClient waits on the
GCS link until the vehicle is ready and downloads the mission at the end; MAVSDK talks to the API link
(SPEC §3) from ``interop_clients/mavsdk_fly_mission.py`` in a separate interpreter with a hard
timeout, so a hang in the native library cannot hang pytest. MAVSDK's ``Param`` downloads every
parameter and sets MIS_RTL_ALT; ``MissionRaw`` uploads the items and downloads them back;
``Action.arm`` arms and ``MissionRaw.start_mission`` switches to AUTO.MISSION; the flight must
reach the last item, land and disarm. A second session (``interop_clients/mavsdk_offboard_velocity.py``)
flies OFFBOARD on ``Offboard.set_velocity_ned`` / ``set_velocity_body`` alone, from takeoff to landing, and a
third (``mavsdk_manual_control.py``) flies POSCTL on ``ManualControl`` joystick input.
MAVSDK is a pinned dev dependency (installed by ``make test``): its absence fails the tests, it never skips them
(``interop_clients`` also looks in ``QUADSITL_INTEROP_PYTHON``).
"""

from __future__ import annotations

import json
import math
import subprocess
import time
from contextlib import AbstractContextManager
from dataclasses import dataclass
from itertools import pairwise
from pathlib import Path
from typing import Any

import pytest
from conftest import REPO_ROOT
from interop_clients import MAVSDK_DRIVER, MAVSDK_MANUAL_DRIVER, MAVSDK_OFFBOARD_DRIVER, MISSING_CLIENT, mavsdk4_python
from interop_clients.missions import short_delivery
from sitl_procs import logs, read_json

from autopilot.mission.files import load_mission_file
from autopilot.param_schema import make_param_store
from mavlink_bridge.contract.frames import GeoPoint, LocalNedFrame
from mavlink_bridge.contract.vehicle_api import MissionItem
from mavlink_bridge.gcs_client.client import GcsClient
from tools.sitl import SitlRun, sitl_run

pytestmark = [pytest.mark.sitl, pytest.mark.slow]

#: Lockstep silence tolerated (wall s): a cold numba cache makes the first control step compile for
#: several seconds, which the 3 s defaults take for a dead peer (the sim's side: ``sitl_run``'s 30 s).
AUTOPILOT_PATIENCE = ("--sim-timeout-s", "30")
WORLD = REPO_ROOT / "missions" / "delivery.yaml"  # home, wind and the 1 kg payload the sim carries
READY_WAIT_S = 240.0  # failure deadline for the autopilot's first home position (a cold numba cache compiles)
DRIVER_TIMEOUT_S = 75.0  # the MAVSDK session's own limit; the process is killed 15 s later
SET_PARAM = ("MIS_RTL_ALT", 12.0)  # set through MAVSDK before the flight: a lower RTL climb


def _mission_item_int(item: MissionItem) -> dict[str, Any]:
    """MISSION_ITEM_INT fields as MAVSDK's MissionRaw.MissionItem takes them (x/y in degE7, seq 0 current)."""
    return {
        "seq": item.seq,
        "frame": int(item.frame),
        "command": int(item.command),
        "current": int(item.seq == 0),
        "autocontinue": int(item.autocontinue),
        "param1": item.param1,
        "param2": item.param2,
        "param3": item.param3,
        "param4": item.param4,
        "x": round(item.x_lat_deg * 1e7),
        "y": round(item.y_lon_deg * 1e7),
        "z": item.z_alt_m,
        "mission_type": 0,
    }


def _run_driver(driver: list[str], log: Path, gcs: GcsClient, tmp_path: Path) -> subprocess.Popen[bytes]:
    """Run a MAVSDK driver once the vehicle has a home, pumping ``gcs`` meanwhile; killed (and the test failed)
    15 s after its own timeout."""
    gcs.wait_until(lambda s: s.home is not None, READY_WAIT_S)
    with open(log, "wb") as out:
        proc = subprocess.Popen(driver, cwd=tmp_path, stdout=out, stderr=subprocess.STDOUT)
    deadline = time.monotonic() + DRIVER_TIMEOUT_S + 15.0
    while proc.poll() is None:
        if time.monotonic() > deadline:
            proc.kill()
            proc.wait()
            pytest.fail(f"MAVSDK driver hung past its own timeout\n{logs(tmp_path)}")
        gcs.pump(0.2)
    return proc


def _pair(tmp_path: Path, seed: int) -> AbstractContextManager[SitlRun]:
    """Sim (with WORLD) and autopilot on free ports, the GCS and API links open (``tools.sitl.sitl_run``)."""
    return sitl_run(tmp_path, WORLD, seed=seed, api=True, autopilot_args=AUTOPILOT_PATIENCE)


def _driver_result(path: Path, proc: subprocess.Popen[bytes], log: Path) -> dict[str, Any]:
    """The driver's JSON result, once its success is checked (the processes' clean exits: ``sitl_run``)."""
    result = read_json(path)
    context = f"{result.get('error')}\n{log.read_text(errors='replace')[-3000:]}\n{logs(path.parent)}"
    assert proc.returncode == 0 and result["ok"], context
    return result


@dataclass(frozen=True)
class Flight:
    """What one MAVSDK session observed, what it was given, and both processes' summaries."""

    sent: list[dict[str, Any]]
    result: dict[str, Any]
    held: list[dict[str, Any]]  # downloaded after the flight by the project's GcsClient
    home: GeoPoint
    autopilot: dict[str, Any]
    sim: dict[str, Any]


@pytest.fixture(scope="module")
def flight(tmp_path_factory: pytest.TempPathFactory) -> Flight:
    """Fly the short delivery once with MAVSDK (module scope: the tests below read the same flight)."""
    python = mavsdk4_python()
    if python is None:
        pytest.fail(MISSING_CLIENT.format(client="mavsdk>=4 is"))
    tmp_path = tmp_path_factory.mktemp("mavsdk")
    plan = load_mission_file(WORLD)
    sent = [_mission_item_int(item) for item in short_delivery(plan.home)]
    (tmp_path / "items.json").write_text(json.dumps(sent))
    driver_log = tmp_path / "mavsdk_driver.log"
    # The project's client on the GCS link: readiness before MAVSDK's clock starts, and a second witness.
    with _pair(tmp_path, 5) as run, GcsClient(str(run.gcs_url), timeout_s=20.0) as gcs:
        driver = [
            python, str(MAVSDK_DRIVER), "--connect", f"udpin://127.0.0.1:{run.api_port}",
            "--items", str(tmp_path / "items.json"), "--result", str(tmp_path / "mavsdk.json"),
            "--set-param", SET_PARAM[0], repr(SET_PARAM[1]), "--timeout-s", str(DRIVER_TIMEOUT_S),
        ]  # fmt: skip
        proc = _run_driver(driver, driver_log, gcs, tmp_path)
        held = gcs.download_mission()
    result = _driver_result(tmp_path / "mavsdk.json", proc, driver_log)
    held_items = [_mission_item_int(item) for item in held]
    return Flight(sent, result, held_items, plan.home, run.autopilot_summary, run.sim_summary)


def test_mavsdk_mission_raw_upload_arm_start_complete(flight: Flight) -> None:
    result, sent, total = flight.result, flight.sent, len(flight.sent)
    steps = {s["step"]: s for s in result["steps"]}
    assert steps["discovered"]["autopilot"] == "PX4" and steps["discovered"]["vehicle"] == "MULTICOPTER"
    downloaded = result["downloaded"]
    key = ("seq", "command", "frame", "current", "autocontinue", "x", "y", "mission_type")
    assert [[d[k] for k in key] for d in downloaded] == [[s[k] for k in key] for s in sent]
    held_key = ("seq", "command", "frame", "autocontinue", "x", "y", "mission_type")
    assert [[h[k] for k in held_key] for h in flight.held] == [[s[k] for k in held_key] for s in sent]
    for got, want in zip(downloaded, sent, strict=True):
        fields = ("param1", "param2", "param3", "param4", "z")
        assert [got[f] for f in fields] == pytest.approx([want[f] for f in fields], nan_ok=True, abs=1e-5)
    assert "MISSION" in result["flight_modes"]
    assert "HOLD" in result["flight_modes"]  # AUTO.LOITER on the ground, PX4's "Hold"
    progress = result["progress"]
    assert progress[-1] == [total, total]
    assert {current for current, _ in progress} == set(range(total + 1))  # every item became current
    assert "Payload released" in result["status_texts"]
    assert flight.autopilot["reached_seqs"] == list(range(total))
    assert flight.autopilot["landed"] and flight.autopilot["disarmed"] and flight.autopilot["payload_released"]
    assert flight.sim["collisions"] == 0 and flight.sim["payload_released_at_s"] is not None
    landed = steps["landed"]
    north_m, east_m, _ = LocalNedFrame(flight.home).ned_from_geodetic(landed["lat_deg"], landed["lon_deg"], 0.0)
    assert math.hypot(north_m, east_m) < 1.5  # RTL brought it home, in MAVSDK's own position telemetry
    assert abs(landed["rel_alt_m"]) < 0.15  # on the ground it reads altitude 0 (the EKF's height datum, issue 22)


def test_mavsdk_param_download_and_set(flight: Flight) -> None:
    params = next(s for s in flight.result["steps"] if s["step"] == "params")
    assert params["float_count"] == len(make_param_store().names())  # float-only parameters (SPEC §3)
    assert params["int_count"] == 0 and params["custom_count"] == 0
    name, value = SET_PARAM
    assert params["name"] == name and params["before"] == make_param_store().get(name)
    assert params["after"] == pytest.approx(value)


def test_mavsdk_mission_progress_never_steps_back(flight: Flight) -> None:
    progress = flight.result["progress"]
    assert all(a[0] <= b[0] for a, b in pairwise(progress)), progress


def _fly_session(tmp_path: Path, script: Path, seed: int) -> tuple[dict[str, Any], dict[str, Any]]:
    """One MAVSDK driver session (``--connect``, ``--result``, ``--timeout-s``) against a fresh pair; its result
    with the phases' telemetry samples by name (``by_phase``), and the autopilot's summary."""
    python = mavsdk4_python()
    if python is None:
        pytest.fail(MISSING_CLIENT.format(client="mavsdk>=4 is"))
    result_path, driver_log = tmp_path / f"{script.stem}.json", tmp_path / f"{script.stem}.log"
    with _pair(tmp_path, seed) as run, GcsClient(str(run.gcs_url), timeout_s=20.0) as gcs:
        driver = [
            python, str(script), "--connect", f"udpin://127.0.0.1:{run.api_port}",
            "--result", str(result_path), "--timeout-s", str(DRIVER_TIMEOUT_S),
        ]  # fmt: skip
        proc = _run_driver(driver, driver_log, gcs, tmp_path)
    result = _driver_result(result_path, proc, driver_log)
    result["by_phase"] = {sample["phase"]: sample for sample in result["samples"]}
    summary = run.autopilot_summary
    assert summary["landed"] and summary["disarmed"]
    return result, summary


def test_mavsdk_offboard_velocity_takeoff_cruise_turn_land(tmp_path: Path) -> None:
    """MAVSDK's Offboard plugin on velocity setpoints: a climbing setpoint takes off, 2 m/s north is flown,
    a body-frame velocity with a yaw speed turns the vehicle, a descending setpoint lands it and it disarms."""
    result, summary = _fly_session(tmp_path, MAVSDK_OFFBOARD_DRIVER, 6)
    samples = result["by_phase"]
    assert samples["climb"]["vel_ned_m_s"][2] == pytest.approx(-1.5, abs=0.3)
    assert samples["cruise"]["vel_ned_m_s"] == pytest.approx([2.0, 0.0, 0.0], abs=0.3)
    turn = samples["turn"]
    course_deg = math.degrees(math.atan2(turn["vel_ned_m_s"][1], turn["vel_ned_m_s"][0]))
    # Body forward follows the turn: sampled when the heading has turned 80 deg at 30 deg/s, the course lags the
    # heading by about the yaw rate times the velocity loop's lag (0.3-1 s: 10-30 deg, by when the wall-clock
    # sample lands); a velocity held in the world frame would lag by the whole 80 deg.
    assert abs((course_deg - turn["heading_deg"] + 180.0) % 360.0 - 180.0) < 40.0
    assert samples["landed"]["down_m"] == pytest.approx(0.0, abs=0.3)
    assert "OFFBOARD" in [m["mode"] for m in summary["mode_history"]]


def test_mavsdk_manual_control_position_mode_flight(tmp_path: Path) -> None:
    """MAVSDK's ManualControl plugin streaming sticks in POSCTL: full throttle climbs at MPC_Z_VEL_MAX_UP, half
    forward stick flies 5 m/s along the heading, centred sticks stop and hold, throttle down lands and disarms."""
    result, summary = _fly_session(tmp_path, MAVSDK_MANUAL_DRIVER, 7)
    samples = result["by_phase"]
    params = make_param_store()
    assert samples["climb"]["vel_ned_m_s"][2] == pytest.approx(-params.get("MPC_Z_VEL_MAX_UP"), abs=0.3)
    forward = samples["forward"]
    heading = math.radians(forward["heading_deg"])
    along = (5.0 * math.cos(heading), 5.0 * math.sin(heading), 0.0)  # (0.55 - 0.1) / 0.9 of MPC_VEL_MANUAL 10 m/s
    assert forward["vel_ned_m_s"] == pytest.approx(along, abs=0.4)
    stopped, held = samples["stopped"], samples["held"]
    drift = math.dist(
        [stopped[k] for k in ("north_m", "east_m", "down_m")], [held[k] for k in ("north_m", "east_m", "down_m")]
    )
    assert drift < 0.3  # centred sticks hold the position
    assert samples["landed"]["down_m"] == pytest.approx(0.0, abs=0.3)
    assert "POSCTL" in [m["mode"] for m in summary["mode_history"]]
