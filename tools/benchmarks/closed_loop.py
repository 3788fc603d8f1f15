"""Control benchmarks: single-vehicle cascade step cost and closed-loop batch throughput (issue 3).

- ``control_update_us_n1``: one ``CascadeController.update_position`` call at n = 1 (µs, median of
  repeats), the cost inside the 250 Hz lockstep loop; target <= 40 µs.
- ``closed_loop_vehicle_steps_per_s``: cascade + ``sim.batch.BatchSim`` at N = 1000 x500 vehicles flying
  a 1 m step; a vehicle-step is one 250 Hz control step incl. its 4 physics substeps; target >= 300,000.
- ``control_update_us_per_vehicle_n1000``: the cascade alone at N = 1000, per vehicle.

Every number is the best of a few repeats: the machine is shared, and the best run is the one least
disturbed by other processes.
"""

from __future__ import annotations

import time

import numpy as np

from autopilot.control import CascadeController, CascadeGains, load_airframe
from sim.batch import BatchSim
from sim.vehicle_config import load_vehicle
from tools.benchmarks import BenchResult


def _time_per_call_s(fn, calls: int, repeats: int) -> float:
    fn()
    samples = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        for _ in range(calls):
            fn()
        samples.append((time.perf_counter() - t0) / calls)
    return min(samples)


def _single_update_us(quick: bool) -> float:
    ctrl = CascadeController(load_airframe("x500"), CascadeGains.paper_default(), n=1)
    pos, vel, rate = np.array([0.1, -0.2, -5.0]), np.array([0.3, 0.0, -0.1]), np.array([0.01, -0.02, 0.0])
    q = np.array([0.999, 0.01, -0.02, 0.03])
    q /= np.linalg.norm(q)
    sp, zero = np.array([1.0, 0.0, -5.0]), np.zeros(3)

    def call() -> None:
        ctrl.update_position(pos, vel, q, rate, sp, zero, zero, 0.0)

    return 1e6 * _time_per_call_s(call, 2000 if quick else 20000, 3 if quick else 5)


def _closed_loop(n: int, steps: int, repeats: int) -> tuple[float, float]:
    sim = BatchSim(load_vehicle("x500"), n=n)
    start = np.array([0.0, 0.0, -5.0])
    sim.reset(pos_ned=start)
    sim.omega_rad_s[:] = sim.hover_omega_rad_s()[:, None]
    ctrl = CascadeController(load_airframe("x500"), CascadeGains.paper_default(), n=n)
    sp = np.tile(start + np.array([1.0, 0.0, 0.0]), (n, 1))
    zero, yaw = np.zeros((n, 3)), np.zeros(n)

    def one() -> None:
        u = ctrl.update_position(sim.pos_ned, sim.vel_ned, sim.q_ned_frd, sim.rate_frd, sp, zero, zero, yaw)
        sim.step(u)

    one()  # compile / warm caches
    pos, vel, q, rate = sim.pos_ned.copy(), sim.vel_ned.copy(), sim.q_ned_frd.copy(), sim.rate_frd.copy()
    best_loop_s, best_ctrl_s = float("inf"), float("inf")
    for _ in range(repeats):
        t0 = time.perf_counter()
        for _ in range(steps):
            one()
        best_loop_s = min(best_loop_s, time.perf_counter() - t0)
        t1 = time.perf_counter()
        for _ in range(steps):
            ctrl.update_position(pos, vel, q, rate, sp, zero, zero, yaw)
        best_ctrl_s = min(best_ctrl_s, time.perf_counter() - t1)
    return n * steps / best_loop_s, 1e6 * best_ctrl_s / (n * steps)


def run(quick: bool) -> list[BenchResult]:
    us_n1 = _single_update_us(quick)
    rate, ctrl_us = _closed_loop(1000, 50 if quick else 250, 2 if quick else 3)
    return [
        BenchResult("control_update_us_n1", us_n1, "<= 40", us_n1 <= 40.0, "update_position, x500, n=1"),
        BenchResult(
            "closed_loop_vehicle_steps_per_s",
            rate,
            ">= 300000",
            rate >= 300_000.0,
            "cascade + BatchSim x500, N=1000, 250 Hz control / 1 kHz RK4",
        ),
        BenchResult("control_update_us_per_vehicle_n1000", ctrl_us, "", None, "cascade alone, N=1000"),
    ]
