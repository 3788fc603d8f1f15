"""Simulator physics throughput (issue 2, SPEC §12): single-vehicle control step and batch vehicle-steps/s.

A vehicle-step is one 1 kHz RK4 physics step of one vehicle; a control step is 4 of them (250 Hz).
JIT compilation is excluded (warm-up first). Vehicles hover with small random command perturbations
in gusty wind, so every effect of the kernel (rotors, lag, drag, wind, gusts) is exercised.
"""

from __future__ import annotations

import time

import numpy as np

from sim.batch import BatchSim
from sim.vehicle import VehicleSim
from sim.vehicle_config import load_vehicle
from sim.world import WindConfig, World, empty_world
from tools.benchmarks import BenchResult

SINGLE_STEP_TARGET_US = 60.0
BATCH_TARGET_STEPS_PER_S = 1_000_000.0


def _world() -> World:
    return World(empty_world().home, (), WindConfig(mean_ned_m_s=(2.0, -1.0, 0.0), gust_m_s=1.0, seed=7), 0.0)


def _hover_cmds(sim: BatchSim, count: int) -> np.ndarray:
    rng = np.random.default_rng(0)
    hover = sim.hover_omega_rad_s()[:, None] / sim.vehicle.omega_max_rad_s
    return np.clip(hover[None, :, :] + 0.01 * rng.standard_normal((count, sim.n, 4)), 0.0, 1.0)


def _single_control_step_us(steps: int) -> float:
    vehicle = load_vehicle("x500")
    sim = VehicleSim(vehicle, world=_world())
    sim.reset(pos_ned=[0.0, 0.0, -50.0])
    sim.omega_rad_s[:] = sim.hover_omega_rad_s()
    cmds = _hover_cmds(sim.batch, steps)[:, 0, :]
    for k in range(min(steps, 200)):  # warm-up (JIT compile, caches)
        sim.step(cmds[k])
    best = np.inf
    for _ in range(3):
        t0 = time.perf_counter()
        for k in range(steps):
            sim.step(cmds[k])
        best = min(best, (time.perf_counter() - t0) / steps)
    return best * 1e6


def _batch_vehicle_steps_per_s(n: int, control_steps: int) -> float:
    vehicle = load_vehicle("x500")
    sim = BatchSim(vehicle, n, world=_world(), seed=np.arange(n))
    sim.reset(pos_ned=[0.0, 0.0, -50.0])
    sim.omega_rad_s[:] = sim.hover_omega_rad_s()[:, None]
    cmds = _hover_cmds(sim, control_steps)
    sim.step(cmds[0])  # warm-up
    best = 0.0
    for _ in range(3):
        t0 = time.perf_counter()
        for k in range(control_steps):
            sim.step(cmds[k])
        elapsed = time.perf_counter() - t0
        best = max(best, n * control_steps * sim.substeps / elapsed)
    return best


def run(quick: bool) -> list[BenchResult]:
    """Measure and return the sim_physics keys (see module docstring)."""
    single_steps = 500 if quick else 5000
    step_us = _single_control_step_us(single_steps)
    substeps = 4
    results = [
        BenchResult(
            "sim_single_control_step_us",
            step_us,
            f"<= {SINGLE_STEP_TARGET_US:g}",
            step_us <= SINGLE_STEP_TARGET_US,
            "x500, 4 RK4 substeps at 1 kHz per 250 Hz step, incl. Python call",
        ),
        BenchResult("sim_physics_steps_per_s", substeps / (step_us * 1e-6), note="single vehicle, 1 kHz RK4 steps"),
    ]
    per_n: dict[int, float] = {}
    for n, steps in ((1, 2000), (100, 200), (1000, 50)):
        per_n[n] = _batch_vehicle_steps_per_s(n, max(steps // (10 if quick else 1), 5))
        results.append(BenchResult(f"batch_vehicle_steps_per_s_n{n}", per_n[n], note=f"BatchSim N={n}"))
    results.append(
        BenchResult(
            "batch_vehicle_steps_per_s",
            per_n[1000],
            f">= {BATCH_TARGET_STEPS_PER_S:.0e}",
            per_n[1000] >= BATCH_TARGET_STEPS_PER_S,
            "N=1000, 1 kHz RK4 vehicle-steps per wall second",
        )
    )
    return results
