"""Rerun telemetry cost (issue 7, SPEC §9, §11): listener µs per step and recording size per sim minute.

A synthetic flight (a climbing helix flown at 250 Hz, with live controller diagnostics,
events, a planner detour and tracked obstacles) is fed in-process to ``RerunTelemetry``
saving to a temporary ``.rrd``. The listener cost per step is compared with the lockstep
step budget: ``telemetry_cost_fraction_of_floor_step`` = listener µs per step / floor µs per step
when the messaging-floor benchmark has run in the same process (else against ``budget_step_us``).
``synthetic_records`` is also what ``tests/test_telemetry_*.py`` fly.
"""

from __future__ import annotations

import math
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path
from types import SimpleNamespace

import numpy as np

from autopilot.control.cascade import CascadeDiagnostics
from autopilot.estimator import VehicleState
from autopilot.runner import StepRecord
from autopilot.setpoints import NavTarget, TargetKind
from autopilot.telemetry import RerunTelemetry
from autopilot.telemetry.sinks import RerunSink, SinkKind, open_recording
from mavlink_bridge.frames import quat_from_euler
from mavlink_bridge.gcs_types import FlightMode, LandedState, Severity, StatusText
from tools.benchmarks import BenchResult

CONTROL_HZ = 250


@dataclass(frozen=True, slots=True)
class _Obstacle:
    obstacle_id: int
    center_ned: tuple[float, float, float]
    radius_m: float


@dataclass(frozen=True, slots=True)
class _PlannerOut:
    """The fields of ``autopilot.planner.planner.PlannerOutput`` the telemetry reads."""

    detour: object | None
    hold_path: object | None
    obstacles: tuple[_Obstacle, ...]
    clearance_m: float
    planned_path_ned: np.ndarray | None


def _diagnostics() -> CascadeDiagnostics:
    return CascadeDiagnostics(
        pos_err_ned=np.zeros((1, 3)),
        att_err_rad=np.zeros((1, 3)),
        kp=np.zeros((1, 6)),
        ki=np.zeros((1, 6)),
        kd=np.zeros((1, 6)),
        acc_sp_ned=np.zeros((1, 3)),
        att_sp_rad=np.zeros((1, 3)),
        torque_frd_nm=np.zeros((1, 3)),
        thrust_n=np.zeros(1),
        motor_cmd=np.zeros((1, 4)),
        valid=np.ones(1),
    )


def synthetic_records(n_steps: int, *, with_planner: bool = True, t0_us: int = 1_000_000):
    """Yield ``n_steps`` StepRecords of a climbing helix at 250 Hz (controller diagnostics updated in place).

    Deterministic: position at step k is (20 cos(w t), 20 sin(w t), -(2 + 0.05 t)) with w = 0.2 rad/s;
    the first 50 steps are IDLE on the ground, then AUTO_MISSION. Planner output between 30 % and 60 %.
    """
    diag = _diagnostics()
    controller = SimpleNamespace(diagnostics=diag)
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
        diag.att_err_rad[0] = (0.01 * math.sin(3 * t), -0.01 * math.cos(3 * t), 0.002)
        diag.att_sp_rad[0] = (roll + 0.01, pitch - 0.01, yaw)
        diag.kp[0] = (5.0, 5.0, 5.0, 8.0, 8.0, 8.0 + math.sin(t))
        diag.ki[0] = (0.2, 0.2, 0.2, 0.1, 0.1, 0.1)
        diag.kd[0] = (5.0, 5.0, 5.0, 5.0, 5.0, 5.0)
        diag.torque_frd_nm[0] = (0.01, -0.01, 0.001)
        diag.thrust_n[0] = 19.6 + math.sin(t)
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
            pos_sp_ned_m=sp,
            vel_sp_ned_m_s=(0.0, 0.0, 0.0),
            acc_sp_ned_m_s2=(0.0, 0.0, 0.0),
            yaw_sp_rad=yaw,
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
            controller=controller,
        )


def measure_logger(n_steps: int, path: Path) -> tuple[float, float, int]:
    """(listener wall µs per step, its thread CPU µs per step, recording bytes) for a synthetic flight.

    Only the listener is timed (``on_step`` calls, their flushes and ``close``), not the record generator.
    """
    rec = open_recording(RerunSink(SinkKind.SAVE, str(path)))
    assert rec is not None
    telemetry = RerunTelemetry(rec)
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


def run(quick: bool) -> list[BenchResult]:
    n_steps = CONTROL_HZ * (30 if quick else 120)
    with tempfile.TemporaryDirectory() as tmp:
        us_per_step, cpu_us_per_step, size_b = measure_logger(n_steps, Path(tmp) / "bench.rrd")
    sim_min = n_steps / CONTROL_HZ / 60.0
    # The lockstep step of the whole SITL cannot be faster than the messaging floor; 20 % of it is the budget.
    from tools.benchmarks.lockstep_floor import measure_floor

    _, floor_us, _ = measure_floor(1000 if quick else 3000)
    fraction = us_per_step / floor_us
    return [
        BenchResult("telemetry_logger_us_per_step", us_per_step, note=f"{n_steps} steps at {CONTROL_HZ} Hz, save:.rrd"),
        BenchResult("telemetry_logger_cpu_us_per_step", cpu_us_per_step, note="main-thread CPU (load-independent)"),
        BenchResult("rerun_recording_bytes_per_sim_min", size_b / sim_min),
        BenchResult("lockstep_floor_step_us", floor_us, note="null sim + null autopilot over UDP"),
        BenchResult(
            "telemetry_cost_fraction_of_floor_step",
            fraction,
            "<= 0.2",
            fraction <= 0.2,
            "listener µs / floor µs per step: an upper bound of its share of the lockstep step",
        ),
    ]
