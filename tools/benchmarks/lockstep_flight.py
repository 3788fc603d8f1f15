"""Whole-flight lockstep real-time factor next to the messaging floor, same run (issue 4, SPEC §11).

Starts ``python -m sim --speed max`` (250 Hz control, 1 kHz physics) and ``python -m autopilot``
as two processes over UDP; the autopilot flies a fixed script (arm, take off to 10 m, fly 20 m,
land) so the flight does not depend on a GCS. ``lockstep_rtf`` is the sim's own
``real_time_factor`` (sim seconds per wall second from the first HEARTBEAT to the end);
the floor (``lockstep_floor.measure_floor``: null sim + null autopilot) is measured right after.
Targets: ``lockstep_rtf >= 30`` and ``lockstep_rtf_fraction_of_floor >= 0.5``. The autopilot's own
per-step cost is reported too (``autopilot_step_us``: ``Autopilot.step`` on recorded frames, in-process).
"""

from __future__ import annotations

import json
import os
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from tools.benchmarks import BenchResult
from tools.benchmarks.lockstep_floor import measure_floor

REPO_ROOT = Path(__file__).resolve().parents[2]
RTF_TARGET = 30.0
FLOOR_FRACTION_TARGET = 0.5
FLIGHT_SCRIPT = """\
- {at_s: 0.5, cmd: arm}
- {at_s: 1.0, cmd: takeoff, alt_m: 10}
- {at_s: 10.0, cmd: goto, north_m: 20, east_m: 5, alt_m: 10}
- {at_s: 20.0, cmd: land}
"""


def _free_udp_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def fly(duration_s: float, work_dir: Path, seed: int = 0) -> dict[str, object]:
    """One scripted flight as two processes; the sim summary (raises if either process failed)."""
    script = work_dir / "flight.yaml"
    script.write_text(FLIGHT_SCRIPT)
    port = _free_udp_port()
    env = dict(os.environ, PYTHONUNBUFFERED="1")
    sim_cmd = [sys.executable, "-m", "sim", "--listen", f"udp:127.0.0.1:{port}", "--speed", "max"]
    sim_cmd += ["--duration-s", str(duration_s), "--seed", str(seed), "--log-dir", str(work_dir)]
    ap_cmd = [sys.executable, "-m", "autopilot", "--sim", f"udpout:127.0.0.1:{port}", "--gcs", "off", "--api", "off"]
    ap_cmd += ["--script", str(script), "--log-dir", str(work_dir)]
    with open(work_dir / "sim.log", "wb") as sim_log, open(work_dir / "autopilot.log", "wb") as ap_log:
        sim = subprocess.Popen(sim_cmd, cwd=REPO_ROOT, env=env, stdout=sim_log, stderr=sim_log)
        autopilot = subprocess.Popen(ap_cmd, cwd=REPO_ROOT, env=env, stdout=ap_log, stderr=ap_log)
        try:
            sim.wait(timeout=600)
        finally:
            for proc in (autopilot, sim):
                proc.terminate()
                try:
                    proc.wait(timeout=30)
                except subprocess.TimeoutExpired:
                    proc.kill()
                    proc.wait()
    summary = json.loads((work_dir / "sim_summary.json").read_text())
    if sim.returncode != 0 or summary["end_reason"] != "COMPLETED":
        logs = (work_dir / "sim.log").read_text(errors="replace")[-2000:]
        logs += (work_dir / "autopilot.log").read_text(errors="replace")[-2000:]
        raise RuntimeError(f"whole-flight run failed: {summary['end_reason']} (exit {sim.returncode})\n{logs}")
    return summary


def run(quick: bool) -> list[BenchResult]:
    duration_s = 12.0 if quick else 30.0
    with tempfile.TemporaryDirectory(prefix="lockstep_flight_") as tmp:
        summary = fly(duration_s, Path(tmp))
    rtf = float(summary["real_time_factor"])  # type: ignore[arg-type]
    floor_rtf, _, _ = measure_floor(1500 if quick else 7500)
    fraction = rtf / floor_rtf
    return [
        BenchResult(
            "lockstep_rtf",
            rtf,
            f">= {RTF_TARGET:g}",
            rtf >= RTF_TARGET,
            f"scripted flight {duration_s:g} s, sim + autopilot processes over UDP, 250 Hz / 1 kHz",
        ),
        BenchResult("lockstep_floor_rtf_same_run", floor_rtf, note="null sim + null autopilot, measured right after"),
        BenchResult(
            "lockstep_rtf_fraction_of_floor",
            fraction,
            f">= {FLOOR_FRACTION_TARGET:g}",
            fraction >= FLOOR_FRACTION_TARGET,
            "whole flight / messaging floor",
        ),
        BenchResult("lockstep_flight_resends", float(summary["resends"]), note="lockstep re-sends in the flight"),  # type: ignore[arg-type]
        BenchResult("autopilot_step_us", autopilot_step_us(), note="Autopilot.step per frame in hover, in-process"),
    ]


def autopilot_step_us(frames: int = 2000) -> float:
    """Mean wall time of ``Autopilot.step`` (estimator → commander → setpoints → cascade) in hover.

    The frames come from the simulator's vehicle model in-process (the autopilot flies it to a
    10 m hover first); only the autopilot step is timed.
    """
    from autopilot.runner import Autopilot, AutopilotConfig
    from autopilot.scripted_commands import CommandScript, parse_script
    from mavlink_bridge.lockstep import LockstepFrame
    from sim.sensors import SensorModel
    from sim.vehicle import VehicleSim
    from sim.vehicle_config import load_vehicle
    from sim.world import empty_world

    vehicle, world = load_vehicle("x500"), empty_world()
    sim, sensors = VehicleSim(vehicle, world=world, seed=0), SensorModel(vehicle, world.home, 0)
    script = CommandScript(parse_script([{"at_s": 0.1, "cmd": "arm"}, {"at_s": 0.2, "cmd": "takeoff", "alt_m": 10}]))
    ap = Autopilot(AutopilotConfig(), script=script)
    recorded = []
    for k in range(250 * 12 + frames):
        frame = LockstepFrame(sensors.imu_baro_mag(sim), sensors.gps(sim), sim.ground_truth())
        sim.step(ap.step(frame).motor_cmd)
        if k >= 250 * 12:
            recorded.append(frame)
    t0 = time.perf_counter()
    for frame in recorded:
        ap.step(frame)
    return (time.perf_counter() - t0) / len(recorded) * 1e6
