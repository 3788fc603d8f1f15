"""200 seeded delivery flights in wind with sensor noise on the EKF (issue 12): divergences, collisions.

Each flight is ``estimator.fly_delivery`` with its own seed (sensor noise and biases, gusts); a divergence is a
position error above 5 m at any step, a collision an end in a collision or ground impact (targets: 0 of each).
Also writes ``bench/estimator_error_model.json`` (``estimator.error_model`` of the seed-1 delivery flight and the
first ten Monte Carlo flights), the feedback-noise model for controller tuning.
"""

from __future__ import annotations

import json
import math
import sys

import numpy as np

from sim.end_reason import EndReason
from tools.benchmarks import BenchResult
from tools.benchmarks.estimator import (
    DIVERGED_M,
    ERROR_MODEL_PATH,
    FlightStats,
    bench_result,
    error_model,
    fly_delivery,
    rms,
)

#: Monte Carlo flights compare with the truth at 50 Hz (every 5th step; an error cannot grow metres in 20 ms),
#: those kept for the error model at every step
SAMPLE_EVERY = 5


#: flights compared with the truth at every step for the error model: the seed-1 delivery and the first MC ones
KEEP_FLIGHTS = 5
#: running counts, rewritten every 10 flights (what a run stopped early has shown)
PROGRESS_PATH = ERROR_MODEL_PATH.parent / "estimator_mc_progress.json"


def run(quick: bool) -> list[BenchResult]:
    return monte_carlo(20 if quick else 200, keep=[fly_delivery("ekf", 1)])


def write_error_model(flights: list[FlightStats]) -> None:
    """``bench/estimator_error_model.json``: :func:`error_model` of ``flights`` with their seeds and the method."""
    doc = {"mission": "missions/delivery.yaml", "seeds": [k.seed for k in flights], "method": error_model.__doc__}
    ERROR_MODEL_PATH.parent.mkdir(parents=True, exist_ok=True)
    ERROR_MODEL_PATH.write_text(json.dumps({**doc, **error_model(flights)}, indent=2) + "\n")


def monte_carlo(n: int, first_seed: int = 100, keep: list[FlightStats] | None = None) -> list[BenchResult]:
    """``n`` seeded delivery flights in wind with sensor noise: divergences, collisions, completion. The first
    flights' stats are appended to ``keep`` until it holds ``KEEP_FLIGHTS``; then the error model is written."""
    diverged = collisions = incomplete = worse_than_gps = 0
    worst = 0.0
    pos_h, vel, att = [], [], []
    for seed in range(first_seed, first_seed + n):
        keeping = keep is not None and len(keep) < KEEP_FLIGHTS
        s = fly_delivery("ekf", seed, sample_every=1 if keeping else SAMPLE_EVERY)
        if keep is not None and keeping:
            keep.append(s)
            if len(keep) == KEEP_FLIGHTS:
                write_error_model(keep)
        worst = max(worst, s.max_pos_err_m)
        diverged += s.max_pos_err_m > DIVERGED_M
        collisions += s.end_reason in (EndReason.COLLISION.name, EndReason.GROUND_IMPACT.name)
        incomplete += not s.completed
        air = s.airborne
        pos_h.append(rms(s.pos_err_ned_m[air, :2]))
        worse_than_gps += pos_h[-1] > rms(s.gps_err_ned_m[:, :2])
        vel.append(rms(s.vel_err_ned_m_s[air]))
        att.append(math.degrees(rms(s.att_err_ned_rad[air])))
        done = seed - first_seed + 1
        if done % 10 == 0:
            counts = {"flights": done, "divergences": diverged, "collisions": collisions, "incomplete": incomplete,
                      "worse_than_gps": worse_than_gps, "max_pos_err_m": worst}  # fmt: skip
            PROGRESS_PATH.write_text(json.dumps(counts, indent=2) + "\n")
            print(f"[estimator_mc] {counts}", file=sys.stderr, flush=True)
    return [
        bench_result("ekf_mc_flights", n, "seeded delivery flights in wind with sensor noise (EKF)"),
        bench_result("ekf_mc_divergences", diverged, f"flights with a position error > {DIVERGED_M:g} m", "0",
                    diverged == 0),
        bench_result("ekf_mc_collisions", collisions, "flights that ended in a collision or ground impact", "0",
                    collisions == 0),
        bench_result("ekf_mc_incomplete", incomplete, "flights that did not land and disarm after the mission"),
        bench_result("ekf_mc_worse_than_gps", worse_than_gps, "flights: EKF horizontal RMS > the receiver's own"),
        bench_result("ekf_mc_max_pos_err_m", worst, "largest position error over all flights"),
        bench_result("ekf_mc_pos_horiz_rms_m", float(np.mean(pos_h)), "mean over flights of the horizontal RMS"),
        bench_result("ekf_mc_vel_rms_m_s", float(np.mean(vel)), "mean over flights of the velocity RMS"),
        bench_result("ekf_mc_att_rms_deg", float(np.mean(att)), "mean over flights of the attitude RMS"),
    ]  # fmt: skip
