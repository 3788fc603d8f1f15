"""Loopback SITL with injected failures (issue 12 "Must show"): sim and autopilot as two processes, failures
scheduled at fixed sim times from the ``--script`` file or the world file's ``failures:`` (MAV_CMD_INJECT_FAILURE,
SYS_FAILURE_EN = 1).

- GPS off mid-mission: dead reckoning for COM_POS_FS_DELAY, then a landing without horizontal position
  control; disarmed within the delay plus the descent, no collision.
- GPS stuck mid-mission (from the world file): the stale check drops the frozen fix, then as GPS off.
- GPS off and back before the delay: the mission continues and completes.
- Baro stuck mid-mission: reported, the mission completes and the vehicle lands.
- Mag off mid-mission: "heading from the gyro" warned, the mission completes.
- One motor off in the air: reported; the quad crash-lands (the sim ends the run on the ground impact) and
  both processes exit with their documented status and write their summaries. Before it, bad
  MAV_CMD_INJECT_FAILURE requests over MAVLink get an honest COMMAND_ACK and their reason.

The sensor failures need a filter that fuses the sensors (``--estimator ekf``); the truth estimator reads the
sim's ground truth, which no failure reaches. The ground station only uploads the mission before the scripted
arm time; the sim runs paced (``--speed``) so the upload has several wall seconds to finish.
"""

from __future__ import annotations

import math
from pathlib import Path

import pytest
from sitl_procs import STARTUP_TIMEOUT_S, Ports, connect_gcs, logs, read_json, start_autopilot, start_sim, stop

from autopilot.estimation import ESTIMATORS
from autopilot.mission.files import load_mission_file
from autopilot.telemetry.recording_reader import read_recording
from mavlink_bridge.contract.mav_enums import FailureUnit, MavCmd
from mavlink_bridge.contract.vehicle_api import CommandResult, MissionType
from tools.sitl import SitlRun, sitl_run

pytestmark = [pytest.mark.sitl, pytest.mark.slow]

needs_ekf = pytest.mark.skipif("ekf" not in ESTIMATORS, reason="sensor failures need the EKF (--estimator ekf)")

ROUTE = """\
name: failure_route
home: {lat_deg: 30.2635, lon_deg: 120.1233, alt_m: 12.0}
vehicle: x500
speed_m_s: 5.0
mission:
  - takeoff: {alt_m: 10}
  - waypoint: {north_m: 60, east_m: 0, alt_m: 10, accept_radius_m: 1.0}
  - waypoint: {north_m: 60, east_m: 30, alt_m: 10, accept_radius_m: 1.0}
  - land: {}
world:
  wind: {north_m_s: 1.0, east_m_s: 0.5, down_m_s: 0.0, gust_m_s: 0.3, seed: 3}
"""
ALT_M = 10.0
POS_FS_DELAY_S = 3.0  # shorter than the EKF's own no-aid validity (5 s), so this delay decides
ARM_S = 30.0  # the mission is uploaded before this sim time
INJECT_S = 42.0  # on the first leg (takeoff done at ~38 s, the leg takes ~14 s)
SPEED = "10"  # sim seconds per wall second: ARM_S leaves the ground station ~3 wall seconds to upload
FLIGHT_TIMEOUT_S = 240.0  # wall


def _files(tmp_path: Path, *failures: str, world_failures: str = "") -> tuple[Path, Path, Path]:
    world = tmp_path / "route.yaml"
    world.write_text(ROUTE + (f"  failures: {world_failures}\n" if world_failures else ""))
    params = tmp_path / "params.yaml"
    params.write_text(f"SYS_FAILURE_EN: 1\nCOM_POS_FS_DELAY: {POS_FS_DELAY_S}\n")
    script = tmp_path / "script.yaml"
    steps = [f"- {{at_s: {ARM_S}, cmd: arm}}", f"- {{at_s: {ARM_S + 0.5}, cmd: mission_start}}", *failures]
    script.write_text("\n".join(steps) + "\n")
    return world, params, script


def _fly(tmp_path: Path, *failures: str, world_failures: str = "") -> tuple[SitlRun, list[tuple[float, str]]]:
    """Fly the route with the scripted failures (and the world file's ``failures:``) until the vehicle has landed
    and disarmed; the run and the recording's text log as (sim s, text)."""
    world, params, script = _files(tmp_path, *failures, world_failures=world_failures)
    rrd = tmp_path / "flight.rrd"
    ap_args = ("--estimator", "ekf", "--params", str(params), "--script", str(script), "--rerun", f"save:{rrd}")
    pair = sitl_run(tmp_path, world, seed=5, sim_args=("--speed", SPEED), autopilot_args=ap_args)
    with pair as run, run.gcs_client() as gcs:
        gcs.wait_until(lambda s: s.gps_fix_type >= 3 and s.home is not None, STARTUP_TIMEOUT_S)
        gcs.upload_mission(load_mission_file(world).items, MissionType.MISSION)
        gcs.wait_until(lambda s: s.armed, FLIGHT_TIMEOUT_S)
        gcs.wait_until(lambda s: not s.armed, FLIGHT_TIMEOUT_S)
    texts = [(t_us * 1e-6, text) for t_us, _level, text in read_recording(rrd).text_log()]
    started = [t for t, text in texts if text == "Script mission_start: ACCEPTED"]
    assert started, f"the mission did not start at {ARM_S + 0.5} s (uploaded too late?): {texts[:40]}"
    return run, texts


def _first(texts: list[tuple[float, str]], prefix: str) -> float:
    times = [t for t, text in texts if text.startswith(prefix)]
    assert times, f"no {prefix!r} in the recording's log: {[text for _, text in texts]}"
    return times[0]


def _no_collision(run: SitlRun) -> None:
    assert run.sim_summary["collisions"] == 0 and run.sim_summary["end_reason"] == "STOPPED"
    assert run.autopilot_summary["landed"] and run.autopilot_summary["disarmed"]


@needs_ekf
def test_gps_off_mid_mission_dead_reckons_then_lands_without_position(tmp_path: Path) -> None:
    run, texts = _fly(tmp_path, f"- {{at_s: {INJECT_S}, cmd: inject_failure, unit: gps, type: off}}")
    t_inject = _first(texts, "Failure injected: GPS off")
    assert t_inject == pytest.approx(INJECT_S, abs=0.01)
    t_lost = _first(texts, "GPS lost: dead reckoning")
    assert 0.0 <= t_lost - t_inject <= 2.0  # the filter notices within its fusion timeout
    t_action = _first(texts, "Failsafe: position lost")
    assert t_action - t_lost == pytest.approx(POS_FS_DELAY_S, abs=0.15)  # failsafes run at 10 Hz
    t_disarm = _first(texts, "Disarmed")
    descent_s = ALT_M / 0.7 + 2.0  # all of it at MPC_LAND_SPEED (slowest), land detection, COM_DISARM_LAND
    assert t_action < t_disarm <= t_lost + POS_FS_DELAY_S + descent_s + 1.0
    assert not any(text.startswith("GPS regained") for _, text in texts)
    _no_collision(run)
    summary = run.autopilot_summary
    modes = [m["mode"] for m in summary["mode_history"]]
    assert modes[modes.index("AUTO_MISSION") :][:2] == ["AUTO_MISSION", "AUTO_LAND"]
    assert summary["items_reached"] < summary["items_total"]  # it never reached the end of the route


@needs_ekf
def test_gps_stuck_from_the_world_file_is_caught_and_the_vehicle_lands(tmp_path: Path) -> None:
    """The receiver freezes on the first leg at 5 m/s (scheduled by the world file, not the script): the stale
    check drops the repeated fix, the filter dead-reckons, the position-loss action lands it."""
    run, texts = _fly(tmp_path, world_failures=f"[{{at_s: {INJECT_S}, inject: gps_stuck}}]")
    t_inject = _first(texts, "Failure injected: GPS stuck")
    assert t_inject == pytest.approx(INJECT_S, abs=0.01)
    t_stale = _first(texts, "GPS stale")
    assert 0.4 <= t_stale - t_inject <= 0.7  # five identical fixes
    t_lost = _first(texts, "GPS lost: dead reckoning")
    t_action = _first(texts, "Failsafe: position lost")
    assert t_stale <= t_lost and t_action - t_lost == pytest.approx(POS_FS_DELAY_S, abs=0.15)
    t_disarm = _first(texts, "Disarmed")
    assert t_action < t_disarm <= t_action + ALT_M / 0.7 + 3.0
    _no_collision(run)
    assert run.autopilot_summary["items_reached"] < run.autopilot_summary["items_total"]


@needs_ekf
def test_gps_back_before_the_delay_and_the_mission_completes(tmp_path: Path) -> None:
    run, texts = _fly(
        tmp_path,
        f"- {{at_s: {INJECT_S}, cmd: inject_failure, unit: gps, type: off}}",
        f"- {{at_s: {INJECT_S + 0.5 * POS_FS_DELAY_S}, cmd: inject_failure, unit: gps, type: ok}}",
    )
    t_lost = _first(texts, "GPS lost: dead reckoning")
    t_back = _first(texts, "GPS regained")
    assert t_lost < t_back < t_lost + POS_FS_DELAY_S
    assert "flight continues" in next(text for _, text in texts if text.startswith("GPS regained"))
    assert not any(text.startswith("Failsafe: position lost") for _, text in texts)
    _no_collision(run)
    summary = run.autopilot_summary
    assert summary["items_reached"] == summary["items_total"] and summary["mission_state"] == "COMPLETE"
    assert "AUTO_LAND" not in [m["mode"] for m in summary["mode_history"]]  # the mission's own LAND item


@needs_ekf
def test_baro_stuck_mid_mission_is_reported_and_the_vehicle_lands(tmp_path: Path) -> None:
    run, texts = _fly(tmp_path, f"- {{at_s: {INJECT_S}, cmd: inject_failure, unit: baro, type: stuck}}")
    t_inject = _first(texts, "Failure injected: baro stuck")
    assert t_inject == pytest.approx(INJECT_S, abs=0.01)
    t_lost = _first(texts, "Baro lost: height from GPS")  # the filter rejects the frozen height, at the latest
    assert t_inject < t_lost < _first(texts, "Landing detected")  # while the vehicle descends onto it
    _no_collision(run)
    assert run.autopilot_summary["items_reached"] == run.autopilot_summary["items_total"]


@needs_ekf
def test_mag_off_mid_mission_warns_heading_from_the_gyro_and_the_mission_completes(tmp_path: Path) -> None:
    run, texts = _fly(tmp_path, f"- {{at_s: {INJECT_S}, cmd: inject_failure, unit: mag, type: off}}")
    t_inject = _first(texts, "Failure injected: mag off")
    assert t_inject < _first(texts, "Mag lost: heading from the gyro") < t_inject + 2.0
    _no_collision(run)
    summary = run.autopilot_summary
    assert summary["items_reached"] == summary["items_total"] and summary["mission_state"] == "COMPLETE"


def test_a_motor_off_is_reported_and_no_process_dies(tmp_path: Path) -> None:
    """One motor off at 10 m: the quad falls; the sim ends the run (GROUND_IMPACT, exit 4 as documented), the
    autopilot answers every frame until then and exits on the sim's loss (exit 3); both write summaries."""
    params = tmp_path / "params.yaml"
    params.write_text("SYS_FAILURE_EN: 1\n")
    script = tmp_path / "script.yaml"
    script.write_text(  # armed once the estimator is healthy (ARM_S), the motor fails in the hover
        f"- {{at_s: {ARM_S}, cmd: arm}}\n- {{at_s: {ARM_S + 0.1}, cmd: takeoff, alt_m: 10}}\n"
        f"- {{at_s: {INJECT_S}, cmd: inject_failure, unit: motor, type: off, instance: 1}}\n"
    )
    ports = Ports.free()
    sim = start_sim(tmp_path, ports.sim, "--seed", "4", "--autopilot-timeout-s", "30", "--duration-s", "90")
    ap = start_autopilot(tmp_path, ports.sim, ports, "--params", str(params), "--script", str(script))
    try:
        with connect_gcs(f"udpin:127.0.0.1:{ports.gcs_target}") as gcs:
            # bad requests over MAVLink: an honest COMMAND_ACK and the reason in a STATUSTEXT, nothing breaks
            for params, result, reason in (
                ((42, 1, 0), CommandResult.DENIED, "unknown failure unit 42"),
                ((math.nan, 1, 0), CommandResult.DENIED, "unit must be a whole number"),
                ((FailureUnit.SENSOR_VIO, 1, 0), CommandResult.UNSUPPORTED, "SENSOR_VIO cannot fail here"),
            ):
                serial = gcs.statustext_serial
                assert gcs.command(MavCmd.INJECT_FAILURE, *params) is result
                gcs.wait_until(lambda s, r=reason, n=serial: any(r in t.text for t in gcs.statustexts_since(n)), 20.0)
            status = gcs.wait_until(lambda s: any("motor 1 off" in t.text for t in s.statustexts), 120.0)
            assert any(t.text.startswith("Failure injected: motor 1 off") for t in status.statustexts)
        sim_rc = sim.wait(timeout=120)
        ap_rc = ap.wait(timeout=60)
    finally:
        ap_rc, sim_rc = stop(ap), stop(sim)
    sim_summary = read_json(tmp_path / "sim_summary.json")
    ap_summary = read_json(tmp_path / "autopilot_summary.json")
    assert (sim_rc, sim_summary["end_reason"]) == (4, "GROUND_IMPACT"), logs(tmp_path)
    assert (ap_rc, ap_summary["end_reason"]) == (3, "sim_lost"), logs(tmp_path)
    assert ap_summary["frames"] == sim_summary["frames"]  # it answered every frame to the end
    assert float(sim_summary["sim_time_s"]) > INJECT_S and math.isfinite(float(ap_summary["sim_time_s"]))
    assert [m["mode"] for m in ap_summary["mode_history"]][:2] == ["AUTO_TAKEOFF", "AUTO_LOITER"]  # it was flying
    assert "Traceback" not in logs(tmp_path)
