"""Estimator-like noise on the controller's feedback for tuning rollouts (SPEC §6.3, issue 14).

A flying controller sees the estimator's state, not the truth. Each fed-back quantity gets white noise
plus a slow drift (first-order Gauss-Markov, time constant ``drift_tau_s``), per axis::

    x_fed = x_true + n_white + d,     d[k+1] = a·d[k] + σ_d·√(1 − a²)·w[k],  a = exp(−dt/τ)

The drift starts from its stationary distribution, so every sample of it has standard deviation σ_d.
Attitude noise is a small rotation vector applied in the body frame (``q_fed = q ⊗ exp(δθ/2)``).

**The one place the numbers live** is :data:`DEFAULT_FEEDBACK_NOISE`. They are *estimated* from the
simulator's sensor noise (``sim/sensors.py`` ``SensorNoise``), not yet measured from the EKF:

* position: GPS error is Gauss-Markov σ 0.4 m horizontal / 0.7 m vertical with τ = 5 s; the filter cannot
  remove a correlated GPS error, so the drift keeps σ 0.4 m horizontally; vertically the baro (0.08 m white)
  is blended in, drift σ 0.3 m. The white part is what 10 Hz GPS updates leave between fixes: 0.03 m.
* velocity: GPS velocity 0.05 m/s white at 10 Hz, smoothed by the accelerometer: 0.02 m/s white, 0.02 m/s drift
  (accelerometer bias 0.03 m/s² through the filter), τ 5 s.
* attitude: gyro noise 0.004 rad/s integrated over a 4 ms step plus accelerometer tilt corrections:
  0.002 rad white; tilt drift from the accelerometer bias 0.03 m/s² / g ≈ 0.003 rad, τ 20 s (yaw the same).
* rate: the gyro itself: 0.004 rad/s white, bias 0.002 rad/s (turn-on constant: τ 1000 s).

When the EKF's measured error statistics are available, replace these values (and say which run measured
them); everything else reads them from here.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

Vec3 = tuple[float, float, float]


@dataclass(frozen=True, slots=True)
class ErrorStats:
    """White σ and Gauss-Markov drift σ (per axis, same unit as the quantity) and the drift's time constant."""

    white: Vec3
    drift: Vec3
    drift_tau_s: float

    def __post_init__(self) -> None:
        vals = (*self.white, *self.drift)
        if len(self.white) != 3 or len(self.drift) != 3 or not all(math.isfinite(v) and v >= 0.0 for v in vals):
            raise ValueError(f"white and drift must be 3 finite sigmas >= 0, got {self.white}, {self.drift}")
        if not (math.isfinite(self.drift_tau_s) and self.drift_tau_s > 0.0):
            raise ValueError(f"drift_tau_s must be > 0, got {self.drift_tau_s}")

    def scaled(self, factor: float) -> ErrorStats:
        return ErrorStats(
            tuple(factor * v for v in self.white), tuple(factor * v for v in self.drift), self.drift_tau_s
        )


@dataclass(frozen=True, slots=True)
class FeedbackNoise:
    """Estimate error of position (m, NED), velocity (m/s, NED), attitude (rad, body) and body rates (rad/s)."""

    pos_ned_m: ErrorStats
    vel_ned_m_s: ErrorStats
    att_rad: ErrorStats
    rate_frd_rad_s: ErrorStats

    def scaled(self, factor: float) -> FeedbackNoise:
        """Every σ multiplied by ``factor`` (0 gives noise-free feedback)."""
        return FeedbackNoise(*(getattr(self, f).scaled(factor) for f in _FIELDS))

    def to_dict(self) -> dict[str, dict[str, object]]:
        return {
            f: {"white": list(s.white), "drift": list(s.drift), "drift_tau_s": s.drift_tau_s}
            for f in _FIELDS
            for s in (getattr(self, f),)
        }


_FIELDS = ("pos_ned_m", "vel_ned_m_s", "att_rad", "rate_frd_rad_s")

#: Estimated from sim/sensors.py SensorNoise (see the module docstring); replace with the EKF's measured numbers.
DEFAULT_FEEDBACK_NOISE = FeedbackNoise(
    pos_ned_m=ErrorStats(white=(0.03, 0.03, 0.03), drift=(0.4, 0.4, 0.3), drift_tau_s=5.0),
    vel_ned_m_s=ErrorStats(white=(0.02, 0.02, 0.02), drift=(0.02, 0.02, 0.02), drift_tau_s=5.0),
    att_rad=ErrorStats(white=(0.002, 0.002, 0.002), drift=(0.003, 0.003, 0.003), drift_tau_s=20.0),
    rate_frd_rad_s=ErrorStats(white=(0.004, 0.004, 0.004), drift=(0.002, 0.002, 0.002), drift_tau_s=1000.0),
)


class NoiseStream:
    """Pre-drawn feedback noise for ``len(seeds)`` seed blocks of ``m`` vehicles each, ``n_steps`` steps.

    Vehicle ``b·m + i`` (seed block ``b``, gain set ``i``) sees seed ``seeds[b]``'s draws: every gain set of
    a batch meets exactly the same noise (common random numbers), and a seed always gives the same sequence.
    """

    def __init__(self, noise: FeedbackNoise, seeds: Sequence[int], m: int, n_steps: int, dt_s: float) -> None:
        self.m = int(m)
        self.n_steps = int(n_steps)
        per_seed = []
        for seed in seeds:
            rng = np.random.default_rng([int(seed), 14])
            per_seed.append(np.stack([_sequence(getattr(noise, f), rng, n_steps, dt_s) for f in _FIELDS], axis=1))
        # (n_steps, 4 quantities, n_seeds, 3) -> repeat each seed block m times along the vehicle axis
        self._draws = np.repeat(np.stack(per_seed, axis=2), self.m, axis=2)

    def at(self, k: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Noise of step ``k``: position, velocity, attitude rotation vector, rate; each (n_seeds·m, 3)."""
        d = self._draws[min(k, self.n_steps - 1)]
        return d[0], d[1], d[2], d[3]

    def feedback(
        self, k: int, pos_ned: np.ndarray, vel_ned: np.ndarray, q_ned_frd: np.ndarray, rate_frd: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """The true state of step ``k`` as the controller sees it (new arrays; the truth is not touched)."""
        dp, dv, da, dr = self.at(k)
        return pos_ned + dp, vel_ned + dv, rotate_body(q_ned_frd, da), rate_frd + dr


def _sequence(stats: ErrorStats, rng: np.random.Generator, n_steps: int, dt_s: float) -> np.ndarray:
    """White + Gauss-Markov drift, (n_steps, 3), drift started in its stationary distribution."""
    white = rng.standard_normal((n_steps, 3)) * np.asarray(stats.white)
    w = rng.standard_normal((n_steps, 3))
    a = math.exp(-dt_s / stats.drift_tau_s)
    drift = np.empty((n_steps, 3))
    drift[0] = w[0]
    b = math.sqrt(1.0 - a * a)
    for k in range(1, n_steps):
        drift[k] = a * drift[k - 1] + b * w[k]
    return white + drift * np.asarray(stats.drift)


def rotate_body(q_ned_frd: np.ndarray, rotvec_frd: np.ndarray) -> np.ndarray:
    """``q ⊗ exp(δθ/2)`` for every row: quaternions (n, 4) w-first, rotation vectors (n, 3) rad, body frame."""
    angle = np.linalg.norm(rotvec_frd, axis=1)
    half = 0.5 * angle
    scale = np.where(angle > 1e-12, np.sin(half) / np.where(angle > 1e-12, angle, 1.0), 0.5)
    dw = np.cos(half)
    dx, dy, dz = (rotvec_frd * scale[:, None]).T
    w, x, y, z = q_ned_frd.T
    return np.stack(
        (
            w * dw - x * dx - y * dy - z * dz,
            w * dx + x * dw + y * dz - z * dy,
            w * dy - x * dz + y * dw + z * dx,
            w * dz + x * dy - y * dx + z * dw,
        ),
        axis=1,
    )
