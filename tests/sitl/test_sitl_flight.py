"""Loopback SITL: sim and autopilot as two processes over UDP, flown from a ground-station client.

Arm, take off to 10 m, hold, fly to a setpoint (DO_REPOSITION), land, auto-disarm; and a killed
autopilot makes the simulator report AUTOPILOT_LOST and exit on its own.
"""

from __future__ import annotations

import math
import signal
from pathlib import Path

import pytest
from sitl_procs import Ports, logs, read_json, start_autopilot, start_sim, stop

from mavlink_bridge.contract.frames import LocalNedFrame
from mavlink_bridge.contract.vehicle_api import FlightMode, LandedState
from mavlink_bridge.gcs_client.client import GcsClient

pytestmark = [pytest.mark.sitl, pytest.mark.slow]

MAV_CMD_DO_REPOSITION = 192


def test_gcs_arm_takeoff_hold_reposition_land_disarm(tmp_path: Path) -> None:
    ports = Ports.free()
    sim = start_sim(tmp_path, ports.sim, "--seed", "4", "--autopilot-timeout-s", "30")
    ap = start_autopilot(tmp_path, ports.sim, ports)
    try:
        with GcsClient(f"udpin:127.0.0.1:{ports.gcs_target}", timeout_s=20.0) as gcs:
            gcs.wait_heartbeat(60.0)
            status = gcs.wait_until(lambda s: s.home is not None and s.pos_ned_m is not None, 60.0)
            assert status.landed_state is LandedState.ON_GROUND and not status.armed
            home = status.home
            assert home is not None
            gcs.arm()
            gcs.takeoff(10.0)
            status = gcs.wait_until(
                lambda s: s.mode is FlightMode.AUTO_LOITER and s.landed_state is LandedState.IN_AIR, 120.0
            )
            assert status.armed
            # Streams are capped at their rate in wall time, so at --speed max the altitude that came with
            # the mode change can be ~0.4 s of sim time old (0.5 m of climb): judge it on later samples.
            t_loiter = status.sim_time_s or 0.0
            status = gcs.wait_until(lambda s: (s.sim_time_s or 0.0) > t_loiter + 0.5, 60.0)
            assert status.alt_rel_m == pytest.approx(10.0, abs=1.0)
            t_hold = status.sim_time_s or 0.0
            status = gcs.wait_until(lambda s: (s.sim_time_s or 0.0) > t_hold + 3.0, 60.0)
            assert status.alt_rel_m == pytest.approx(10.0, abs=0.3)
            assert status.landed_state is LandedState.IN_AIR
            frame = LocalNedFrame(home)
            goal = frame.geodetic_from_ned(12.0, -6.0, 0.0)
            alt_amsl = home.alt_amsl_m + 8.0
            gcs.command(MAV_CMD_DO_REPOSITION, -1.0, 1.0, 0.0, math.nan, goal.lat_deg, goal.lon_deg, alt_amsl)

            def at_goal(s) -> bool:  # type: ignore[no-untyped-def]
                return s.pos_ned_m is not None and math.dist(s.pos_ned_m, (12.0, -6.0, -8.0)) < 0.7

            gcs.wait_until(at_goal, 120.0)
            gcs.land()
            status = gcs.wait_until(lambda s: not s.armed, 120.0)
            assert status.landed_state is LandedState.ON_GROUND
            assert status.pos_ned_m is not None and math.dist(status.pos_ned_m[:2], (12.0, -6.0)) < 1.0
    finally:
        ap_rc, sim_rc = stop(ap), stop(sim)
    assert (ap_rc, sim_rc) == (0, 0), logs(tmp_path)
    ap_summary, sim_summary = read_json(tmp_path / "autopilot_summary.json"), read_json(tmp_path / "sim_summary.json")
    assert ap_summary["landed"] and ap_summary["disarmed"]
    modes = [m["mode"] for m in ap_summary["mode_history"]]  # type: ignore[union-attr]
    assert modes[:3] == ["AUTO_TAKEOFF", "AUTO_LOITER", "AUTO_LAND"]
    assert sim_summary["collisions"] == 0 and sim_summary["end_reason"] == "STOPPED"
    assert sim_summary["truth_sha256"] and ap_summary["frames"] == sim_summary["frames"]


def test_killed_autopilot_is_reported_and_the_sim_exits(tmp_path: Path) -> None:
    script = tmp_path / "climb.yaml"
    script.write_text("- {at_s: 2.0, cmd: arm}\n- {at_s: 2.1, cmd: takeoff, alt_m: 20}\n")  # EKF healthy at 1.5 s
    ports = Ports.free()
    sim = start_sim(tmp_path, ports.sim, "--autopilot-timeout-s", "1.0")
    ap = start_autopilot(tmp_path, ports.sim, ports, "--script", str(script))
    try:
        with GcsClient(f"udpin:127.0.0.1:{ports.gcs_target}", timeout_s=20.0) as gcs:
            gcs.wait_until(lambda s: (s.alt_rel_m or 0.0) > 2.0, 120.0)  # airborne under the script
        ap.send_signal(signal.SIGKILL)
        ap.wait(timeout=10)
        sim_rc = sim.wait(timeout=30)  # must notice on its own, not hang
    finally:
        stop(ap)
        stop(sim)
    summary = read_json(tmp_path / "sim_summary.json")
    assert sim_rc == 3, logs(tmp_path)
    assert summary["end_reason"] == "AUTOPILOT_LOST"
    assert summary["sim_time_s"] > 1.0  # it was flying
