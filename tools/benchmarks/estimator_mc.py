"""200 seeded delivery flights in wind with sensor noise on the EKF (issue 12): divergences, collisions.

Each flight is ``estimator.fly_delivery`` with its own seed (sensor noise and biases, gusts); a divergence is a
position error above 5 m at any step, a collision an end in a collision or ground impact (targets: 0 of each).
Also writes ``bench/estimator_error_model.json`` (``estimator.error_model`` of the seed-1 delivery flight and the
first Monte Carlo flights), the feedback-noise model for controller tuning. The flights run one task per seed on
the campaign engine (:func:`tools.campaign.engine.run_tasks`, ``--workers`` / ``--scheduler`` of ``tools.benchmarks``).
"""

from __future__ import annotations

import json
import math
import sys
from dataclasses import dataclass

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
from tools.campaign.engine import run_tasks

#: Monte Carlo flights compare with the truth at 50 Hz (every 5th step; an error cannot grow metres in 20 ms),
#: those kept for the error model at every step
SAMPLE_EVERY = 5


#: flights compared with the truth at every step for the error model: the seed-1 delivery and the first MC ones
KEEP_FLIGHTS = 5
#: running counts, rewritten every 10 flights (what a run stopped early has shown)
PROGRESS_PATH = ERROR_MODEL_PATH.parent / "estimator_mc_progress.json"


def run(quick: bool, *, workers: int | None = None, scheduler: str | None = None) -> list[BenchResult]:
    keep = [fly_delivery("ekf", 1)]
    return monte_carlo(20 if quick else 200, keep=keep, workers=workers, scheduler=scheduler)


@dataclass(frozen=True, slots=True)
class McFlight:
    """What the Monte Carlo keeps of one flight (small, sent back by the engine); ``stats`` only when kept for the
    error model."""

    seed: int
    max_pos_err_m: float
    end_reason: str
    completed: bool
    pos_horiz_rms_m: float
    gps_horiz_rms_m: float
    vel_rms_m_s: float
    att_rms_deg: float
    stats: FlightStats | None


@dataclass(frozen=True, slots=True)
class McCase:
    """One Monte Carlo flight's inputs: its seed, whether it is kept for the error model, its sim-time limit."""

    seed: int
    keep: bool = False
    timeout_s: float = 300.0


def fly_seed(case: McCase) -> McFlight:
    """One Monte Carlo flight on the campaign engine; a kept one compares with the truth at every step and returns
    the whole :class:`FlightStats` (for the error model)."""
    seed, keep = case.seed, case.keep
    s = fly_delivery("ekf", seed, sample_every=1 if keep else SAMPLE_EVERY, timeout_s=case.timeout_s)
    air = s.airborne
    return McFlight(
        seed=seed,
        max_pos_err_m=s.max_pos_err_m,
        end_reason=s.end_reason,
        completed=s.completed,
        pos_horiz_rms_m=rms(s.pos_err_ned_m[air, :2]),
        gps_horiz_rms_m=rms(s.gps_err_ned_m[:, :2]),
        vel_rms_m_s=rms(s.vel_err_ned_m_s[air]),
        att_rms_deg=math.degrees(rms(s.att_err_ned_rad[air])),
        stats=s if keep else None,
    )


def write_error_model(flights: list[FlightStats]) -> None:
    """``bench/estimator_error_model.json``: :func:`error_model` of ``flights`` with their seeds and the method."""
    doc = {"mission": "missions/delivery.yaml", "seeds": [k.seed for k in flights], "method": error_model.__doc__}
    ERROR_MODEL_PATH.parent.mkdir(parents=True, exist_ok=True)
    ERROR_MODEL_PATH.write_text(json.dumps({**doc, **error_model(flights)}, indent=2) + "\n")


def monte_carlo(
    n: int,
    first_seed: int = 100,
    keep: list[FlightStats] | None = None,
    *,
    workers: int | None = None,
    scheduler: str | None = None,
    timeout_s: float = 300.0,
) -> list[BenchResult]:
    """``n`` seeded delivery flights in wind with sensor noise, one task per seed on the campaign engine (results
    in seed order: the same numbers whatever the number of workers): divergences, collisions, completion. The first
    flights' stats are appended to ``keep`` until it holds ``KEEP_FLIGHTS``; then the error model is written.
    ``timeout_s`` limits each flight's sim time (a shorter one only for tests)."""
    n_keep = 0 if keep is None else max(0, KEEP_FLIGHTS - len(keep))
    cases = [McCase(first_seed + i, i < n_keep, timeout_s) for i in range(n)]
    counts = {"flights": 0, "divergences": 0, "collisions": 0, "incomplete": 0, "worse_than_gps": 0}
    worst_so_far = [0.0]

    def progress(_: int, f: McFlight) -> None:  # running counts in completion order (what a stopped run showed)
        counts["flights"] += 1
        counts["divergences"] += f.max_pos_err_m > DIVERGED_M
        counts["collisions"] += _collided(f)
        counts["incomplete"] += not f.completed
        counts["worse_than_gps"] += f.pos_horiz_rms_m > f.gps_horiz_rms_m
        worst_so_far[0] = max(worst_so_far[0], f.max_pos_err_m)
        if counts["flights"] % 10 == 0:
            doc = {**counts, "max_pos_err_m": worst_so_far[0]}
            PROGRESS_PATH.parent.mkdir(parents=True, exist_ok=True)
            PROGRESS_PATH.write_text(json.dumps(doc, indent=2) + "\n")
            print(f"[estimator_mc] {doc}", file=sys.stderr, flush=True)

    flights: list[McFlight] = run_tasks(
        fly_seed, cases, workers=workers, scheduler=scheduler, key="estimator-mc", on_result=progress
    )
    if keep is not None and n_keep:
        keep += [f.stats for f in flights[:n_keep] if f.stats is not None]
        if len(keep) == KEEP_FLIGHTS:
            write_error_model(keep)
    worst = max((f.max_pos_err_m for f in flights), default=0.0)
    diverged = sum(f.max_pos_err_m > DIVERGED_M for f in flights)
    collisions = sum(_collided(f) for f in flights)
    incomplete = sum(not f.completed for f in flights)
    worse_than_gps = sum(f.pos_horiz_rms_m > f.gps_horiz_rms_m for f in flights)
    pos_h = [f.pos_horiz_rms_m for f in flights]
    vel = [f.vel_rms_m_s for f in flights]
    att = [f.att_rms_deg for f in flights]
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


def _collided(f: McFlight) -> bool:
    return f.end_reason in (EndReason.COLLISION.name, EndReason.GROUND_IMPACT.name)
