"""Route references for the tracking experiments, from ``autopilot.flight_tasks.trajectories`` (SPEC §6.5).

The trajectory is sampled once on the control grid; the returned callable maps a control time to the
precomputed sample (no per-step numpy work in the rollout loop).
"""

from __future__ import annotations

import numpy as np

from autopilot.flight_tasks.trajectories import make_trajectory
from tools.research.experiments.rollout import Reference, ReferenceSample

#: the paper's storm route: takeoff at 20 s of 140 s
PAPER_STORM_DURATION_S = 140.0
PAPER_STORM_TAKEOFF_S = 20.0


def route_params(route: str, duration_s: float) -> dict[str, float]:
    """Trajectory parameters for ``route`` lasting ``duration_s``.

    storm: the paper's timing (takeoff at 20 s of 140 s), scaled down proportionally for shorter runs;
    lissajous: one full period over ``duration_s`` (the trajectory's default shape).
    """
    if route == "storm":
        scale = min(1.0, duration_s / PAPER_STORM_DURATION_S)
        return {
            "duration_s": duration_s,
            "takeoff_s": PAPER_STORM_TAKEOFF_S * scale,
            "ramp_s": min(3.0, 0.2 * duration_s),
        }
    if route == "lissajous":
        return {"duration_s": duration_s, "period_s": duration_s, "ramp_s": min(2.0, 0.2 * duration_s)}
    return {"duration_s": duration_s}


def make_reference(route: str, duration_s: float, control_hz: int = 250) -> Reference:
    """A :data:`Reference` for ``route`` ("storm", "lissajous", "figure8", ...) sampled at ``control_hz``."""
    traj = make_trajectory(route, **route_params(route, duration_s))
    t = np.arange(round(duration_s * control_hz) + 1) / control_hz
    ref = traj.sample(t)
    samples = [
        ReferenceSample(ref.pos_ned[k].copy(), ref.vel_ned[k].copy(), ref.acc_ned[k].copy(), float(ref.yaw_rad[k]))
        for k in range(t.size)
    ]
    last = len(samples) - 1

    def reference(t_s: float) -> ReferenceSample:
        return samples[min(max(round(t_s * control_hz), 0), last)]

    return reference
