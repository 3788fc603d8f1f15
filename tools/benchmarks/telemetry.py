"""Rerun telemetry cost (issue 7, SPEC §9, §11): listener µs per step and recording size per sim minute.

A synthetic flight (a climbing helix flown at 250 Hz, with live controller diagnostics,
events, a planner detour and tracked obstacles) is fed in-process to ``RerunTelemetry``
saving to a temporary ``.rrd``: listener µs per step and bytes per simulated minute. Then the
``lockstep_flight`` scripted flight (sim + autopilot processes) runs with ``--rerun off`` and
``--rerun save:`` alternately: ``lockstep_rtf_rerun_ratio`` (target >= 0.8, i.e. logging costs at
most 20 % of the real-time factor). ``synthetic_records`` is also what ``tests/test_telemetry_*.py`` fly.
"""

from __future__ import annotations

import math
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from autopilot.control.cascade import ControlSample
from autopilot.estimation import VehicleState
from autopilot.flight_tasks.setpoints import NavTarget, Reference, TargetKind
from autopilot.reporting.report import StepRecord
from autopilot.telemetry import RerunTelemetry
from autopilot.telemetry.rerun_logger import SAVE_BATCH_ROWS, SAVE_TRAIL_POINTS
from autopilot.telemetry.sinks import RerunSink, SinkKind, open_recording
from mavlink_bridge.contract.frames import quat_from_euler
from mavlink_bridge.contract.vehicle_api import FlightMode, LandedState, Severity, StatusText
from tools.benchmarks import BenchResult
from tools.benchmarks.lockstep_flight import fly

CONTROL_HZ = 250


@dataclass(frozen=True, slots=True)
class _Obstacle:
    obstacle_id: int
    center_ned: tuple[float, float, float]
    radius_m: float


@dataclass(frozen=True, slots=True)
class _PlannerOut:
    """The fields of ``autopilot.planner.planner_output.PlannerOutput`` the telemetry reads."""

    detour: object | None
    hold_path: object | None
    obstacles: tuple[_Obstacle, ...]
    clearance_m: float
    planned_path_ned: np.ndarray | None


def synthetic_records(n_steps: int, *, with_planner: bool = True, t0_us: int = 1_000_000):
    """Yield ``n_steps`` StepRecords of a climbing helix at 250 Hz (controller diagnostics updated in place).

    Deterministic: position at step k is (20 cos(w t), 20 sin(w t), -(2 + 0.05 t)) with w = 0.2 rad/s;
    the first 50 steps are IDLE on the ground, then AUTO_MISSION. Planner output between 30 % and 60 %.
    """
    home = (0.0, 0.0, 0.0)
    path = np.column_stack([np.linspace(15, 25, 20), np.linspace(-5, 5, 20), np.full(20, -5.0)])
    detour_obj = object()
    obstacles = (_Obstacle(1, (20.0, 0.0, -4.0), 1.5), _Obstacle(2, (0.0, 20.0, -6.0), 2.0))
    for k in range(n_steps):
        t_us = t0_us + k * 1_000_000 // CONTROL_HZ
        t = k / CONTROL_HZ
        w = 0.2
        pos = (20.0 * math.cos(w * t), 20.0 * math.sin(w * t), -(2.0 + 0.05 * t))
        sp = (20.0 * math.cos(w * t + 0.01), 20.0 * math.sin(w * t + 0.01), -(2.0 + 0.05 * t) - 0.1)
        roll, pitch, yaw = 0.05 * math.sin(t), 0.04 * math.cos(t), w * t + math.pi / 2
        q = tuple(float(c) for c in quat_from_euler(roll, pitch, yaw))
        idle = k < 50
        control = ControlSample(
            (
                *(0.01 * math.sin(3 * t), -0.01 * math.cos(3 * t), 0.002),  # attitude error
                *(roll + 0.01, pitch - 0.01, yaw),  # attitude setpoint
                *(5.0, 5.0, 5.0, 8.0, 8.0, 8.0 + math.sin(t)),  # k_p
                *(0.2, 0.2, 0.2, 0.1, 0.1, 0.1),  # k_i
                *(5.0, 5.0, 5.0, 5.0, 5.0, 5.0),  # k_d
                *(19.6 + math.sin(t), 0.01, -0.01, 0.001),  # thrust, torque
            )
        )
        state = VehicleState(
            t_us, pos, (0.0, 0.0, 0.0), q, (0.0, 0.0, 0.0), roll, pitch, yaw, 30.0, 120.0, 12.0, 3, 12, 0.5, 0.8, True
        )
        texts: tuple[StatusText, ...] = ()
        if k == 50:
            texts = (StatusText(Severity.INFO, "Takeoff"),)
        elif k > 0 and k % 2500 == 0:
            texts = (StatusText(Severity.NOTICE, f"Reached item {k // 2500}"),)
        planner = None
        if with_planner and 0.3 * n_steps <= k < 0.6 * n_steps:
            in_detour = k < 0.45 * n_steps
            planner = _PlannerOut(
                detour_obj if in_detour else None, None, obstacles, 3.0 + math.sin(t), path if in_detour else None
            )
        yield StepRecord(
            time_us=t_us,
            state=state,
            target=NavTarget(TargetKind.IDLE if idle else TargetKind.POSITION, (20.0 * (1 + k // 2500), 0.0, -5.0)),
            reference=Reference(sp, (0.0, 0.0, 0.0), (0.0, 0.0, 0.0), yaw),
            motor_cmd=(0.5, 0.51, 0.52, 0.53) if not idle else (0.05, 0.05, 0.05, 0.05),
            thrust_ratio=1.0,
            armed=k >= 25,
            mode=FlightMode.AUTO_LOITER if idle else FlightMode.AUTO_MISSION,
            landed_state=LandedState.ON_GROUND if idle else LandedState.IN_AIR,
            home_ned_m=home if k >= 25 else None,
            mission_seq=k // 2500,
            reached=(),
            texts=texts,
            detections=(),
            planner_output=planner,
            control=None if idle else control,
        )


def measure_logger(n_steps: int, path: Path) -> tuple[float, float, int]:
    """(listener wall µs per step, its thread CPU µs per step, recording bytes) for a synthetic flight.

    Only the listener is timed (``on_step`` calls, their flushes and ``close``), not the record generator.
    """
    rec = open_recording(RerunSink(SinkKind.SAVE, str(path)))
    assert rec is not None
    telemetry = RerunTelemetry(rec, batch_rows=SAVE_BATCH_ROWS, trail_segment_points=SAVE_TRAIL_POINTS)  # as saved
    wall_s = cpu_s = 0.0
    for record in synthetic_records(n_steps):
        w0, c0 = time.perf_counter(), time.thread_time()
        telemetry.on_step(record)
        cpu_s += time.thread_time() - c0
        wall_s += time.perf_counter() - w0
    w0, c0 = time.perf_counter(), time.thread_time()
    telemetry.close()
    cpu_s += time.thread_time() - c0
    wall_s += time.perf_counter() - w0
    return 1e6 * wall_s / n_steps, 1e6 * cpu_s / n_steps, path.stat().st_size


def fly_rtf(duration_s: float, work_dir: Path, rerun: str) -> tuple[float, int]:
    """Sim real-time factor of the scripted ``lockstep_flight`` flight (two processes) with ``--rerun``.

    Returns (real_time_factor, recording bytes or 0).
    """
    summary = fly(duration_s, work_dir, autopilot_args=("--rerun", rerun))
    rrd = Path(rerun.partition(":")[2]) if rerun.startswith("save:") else None
    return float(summary["real_time_factor"]), (rrd.stat().st_size if rrd is not None and rrd.is_file() else 0)


def run(quick: bool) -> list[BenchResult]:
    n_steps = CONTROL_HZ * (30 if quick else 120)
    duration_s = 12.0 if quick else 30.0
    pairs = 1 if quick else 2
    with tempfile.TemporaryDirectory(prefix="telemetry_bench_") as tmp:
        us_per_step, cpu_us_per_step, size_b = measure_logger(n_steps, Path(tmp) / "bench.rrd")
        off, on, flight_bytes = [], [], 0
        for k in range(pairs):  # alternate to spread the machine's load drift over both
            off.append(fly_rtf(duration_s, Path(tmp) / f"off{k}", "off")[0])
            rtf, flight_bytes = fly_rtf(duration_s, Path(tmp) / f"on{k}", f"save:{tmp}/on{k}/flight.rrd")
            on.append(rtf)
    sim_min = n_steps / CONTROL_HZ / 60.0
    rtf_off, rtf_on = float(np.median(off)), float(np.median(on))
    ratio = rtf_on / rtf_off
    step_us = 1e6 / (CONTROL_HZ * rtf_off)
    return [
        BenchResult("telemetry_logger_us_per_step", us_per_step, note=f"synthetic, {n_steps} steps, save:.rrd"),
        BenchResult("telemetry_logger_cpu_us_per_step", cpu_us_per_step, note="main-thread CPU (load-independent)"),
        BenchResult("rerun_recording_bytes_per_sim_min", size_b / sim_min, note="synthetic flight with planner"),
        BenchResult("rerun_flight_recording_bytes_per_sim_min", flight_bytes / (duration_s / 60.0)),
        BenchResult("lockstep_rtf_without_rerun", rtf_off, note=f"median of {pairs}, {duration_s:.0f} s flight"),
        BenchResult("lockstep_rtf_with_rerun", rtf_on, note=f"median of {pairs}, --rerun save:"),
        BenchResult("lockstep_rtf_rerun_ratio", ratio, ">= 0.8", ratio >= 0.8, "logging costs <= 20 % of the RTF"),
        BenchResult(
            "telemetry_cost_fraction_of_step",
            us_per_step / step_us,
            "<= 0.2",
            us_per_step / step_us <= 0.2,
            "listener µs per step / lockstep wall µs per step without Rerun",
        ),
    ]
