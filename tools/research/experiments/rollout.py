"""Batched closed-loop experiments: BatchSim (sim/) + CascadeController (autopilot/) in one process.

Each function runs ``m`` vehicles side by side, vehicle ``i`` flying gain set ``i`` of a batched
:class:`~autopilot.control.gains.CascadeGains`, and returns the error traces the paper's metrics and the
ES cost (SPEC §6.3, ``J = 1/(tf - t0) ∫ e² dt``) are computed from. Vehicles whose simulation ended
(non-finite state, ground impact) get ``diverged = True``; their cost is +inf.

:func:`run_step` and :func:`run_tracking` take an optional ``noise``
(:class:`~tools.research.experiments.feedback_noise.FeedbackNoise`) and ``seeds``: the batch is then
``len(seeds)`` blocks of the ``m`` gain sets, the controller is fed the noisy state of its seed (the same
draws for every gain set of a block), while errors are measured on the true state. Every trace also
carries the motor-command chatter (RMS rate of the motor commands, 1/s, yaw mode excluded).

* :func:`run_step`: the paper's step responses, started from hover at ``hover_alt_m``. Attitude channels
  (roll, pitch, yaw) drive the attitude loop alone with hover collective thrust; position channels
  (x, y, z) drive the whole cascade with a position setpoint step.
* :func:`run_tracking`: follow a parametric reference (storm spiral, Lissajous, ...) with the whole cascade,
  feed-forward of the reference velocity and acceleration; returns position and attitude errors.
* :func:`run_mass_change`: hover, then the mass jumps by a fraction (payload added or dropped) without the
  controller being told; returns the altitude error.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from functools import lru_cache

import numpy as np

from autopilot.control.airframe import Airframe, load_airframe
from autopilot.control.cascade import CascadeController
from autopilot.control.gains import CascadeGains, CascadeLimits
from autopilot.tuning.metrics import es_cost
from sim.batch import BatchSim
from sim.vehicle_config import VehicleConfig, load_vehicle
from sim.world import WindConfig, World, empty_world
from tools.research.experiments.feedback_noise import FeedbackNoise, NoiseStream

ATTITUDE_CHANNELS = ("roll", "pitch", "yaw")
POSITION_AXES = {"x": 0, "y": 1, "z": 2}
ATTITUDE_AXES = {"roll": 0, "pitch": 1, "yaw": 2}


@dataclass(frozen=True, slots=True)
class StepTrace:
    """Step response of ``m`` vehicles: ``error[i, k]`` = setpoint − measured at ``t_s[k]`` (rad or m).

    ``t_s[0] = 0`` is the step instant (error = amplitude), then one sample per control step."""

    channel: str
    amplitude: float
    t_s: np.ndarray  # (T,)
    error: np.ndarray  # (n, T) true error, n = n_seeds · m (seed-major blocks)
    response: np.ndarray  # (n, T) the true stepped quantity
    diverged: np.ndarray  # (n,) bool
    chatter: np.ndarray  # (n,) motor-command rate RMS, 1/s (yaw mode excluded)
    n_seeds: int = 1

    @property
    def overshoot(self) -> np.ndarray:
        """Peak beyond the setpoint as a fraction of the amplitude (n,), 0 when it never crosses."""
        return np.maximum(np.max(self.response / self.amplitude, axis=1) - 1.0, 0.0)

    def settling_time_s(self, band: float = 0.05) -> np.ndarray:
        """Time after which |error| stays within ``band``·amplitude (n,); the duration if it never settles."""
        outside = np.abs(self.error) > band * abs(self.amplitude)
        last = np.where(outside.any(axis=1), outside.shape[1] - 1 - np.argmax(outside[:, ::-1], axis=1), -1)
        idx = np.minimum(last + 1, self.t_s.size - 1)
        return np.where(last < 0, 0.0, self.t_s[idx])


@dataclass(frozen=True, slots=True)
class TrackTrace:
    """Reference tracking of ``m`` vehicles: errors are reference − measured."""

    t_s: np.ndarray  # (T,)
    pos_err_ned: np.ndarray  # (m, T, 3) m
    att_err_rad: np.ndarray  # (m, T, 3) roll, pitch, yaw (controller's attitude error)
    pos_ned: np.ndarray  # (m, T, 3)
    ref_pos_ned: np.ndarray  # (T, 3)
    diverged: np.ndarray  # (m,) bool
    chatter: np.ndarray  # (m,) motor-command rate RMS, 1/s (yaw mode excluded)
    n_seeds: int = 1


@dataclass(frozen=True, slots=True)
class MassChangeTrace:
    """Altitude error (m, positive = below the setpoint) around a mass change at ``t_change_s``."""

    t_s: np.ndarray  # (T,)
    alt_err_m: np.ndarray  # (m, T)
    t_change_s: float
    mass_before_kg: float
    mass_after_kg: float
    diverged: np.ndarray  # (m,) bool


@dataclass(frozen=True, slots=True)
class ReferenceSample:
    """Reference at one time: position, velocity, acceleration (NED) and yaw."""

    pos_ned: np.ndarray  # (3,)
    vel_ned: np.ndarray  # (3,)
    acc_ned: np.ndarray  # (3,)
    yaw_rad: float


Reference = Callable[[float], ReferenceSample]


@lru_cache(maxsize=8)
def _vehicle(name: str) -> VehicleConfig:
    """Vehicle config by name, parsed once per process (frozen dataclass)."""
    return load_vehicle(name)


@lru_cache(maxsize=8)
def _airframe(name: str) -> Airframe:
    return load_airframe(name)


def gusty_world(mean_ned_m_s: tuple[float, float, float], gust_m_s: float, seed: int) -> World:
    """No obstacles, a mean wind plus seeded Gauss-Markov gusts (every vehicle of a batch feels the same gusts
    when the batch shares one seed)."""
    return replace(empty_world(), wind=WindConfig(mean_ned_m_s=mean_ned_m_s, gust_m_s=gust_m_s, seed=seed))


def _hovering_batch(
    vehicle: str, m: int, alt_m: float, seed: int, payload_kg: float = 0.0, world: World | None = None
) -> BatchSim:
    """m vehicles hovering (rotors at hover speed) at ``alt_m``; the payload is written after the reset so
    an experiment may exceed the vehicle's rated payload (the mass-change experiment needs +-30 %)."""
    sim = BatchSim(_vehicle(vehicle), m, seed=seed, payload_kg=0.0, world=world)
    sim.reset(pos_ned=np.array([0.0, 0.0, -alt_m]))
    sim.payload_kg[:] = payload_kg
    sim.omega_rad_s[:] = sim.hover_omega_rad_s()[:, None]
    sim.on_ground[:] = False
    return sim


def _controller(vehicle: str, gains: CascadeGains, m: int, dt_s: float, limits: CascadeLimits | None):
    if gains.n not in (1, m):
        raise ValueError(f"gain batch of {gains.n} does not fit {m} vehicles")
    return CascadeController(_airframe(vehicle), gains, n=m, dt_s=dt_s, limits=limits)


class MotorChatter:
    """Running RMS of the motor-command rate (1/s) per vehicle, the yaw mode (rotor_yaw_dir) projected out."""

    def __init__(self, vehicle: str, n: int, dt_s: float) -> None:
        yaw = np.asarray(_airframe(vehicle).rotor_yaw_dir, dtype=np.float64)
        self._proj = np.eye(4) - np.outer(yaw, yaw) / float(yaw @ yaw)
        self._prev: np.ndarray | None = None
        self._sum = np.zeros(n)
        self._count = 0
        self._dt_s = dt_s

    def add(self, u: np.ndarray) -> None:
        u = np.nan_to_num(u, nan=0.0)
        if self._prev is not None:
            d = (u - self._prev) @ self._proj / self._dt_s
            self._sum += np.mean(d * d, axis=1)
            self._count += 1
        self._prev = u

    def rms(self) -> np.ndarray:
        return np.sqrt(self._sum / max(self._count, 1))


def _seeded(gains: CascadeGains, m: int | None, seeds: Sequence[int]) -> tuple[CascadeGains, int, int]:
    """(gains for the whole batch, m gain sets, n vehicles = len(seeds)·m)."""
    m = gains.n if m is None else m
    if gains.n not in (1, m):
        raise ValueError(f"gain batch of {gains.n} does not fit {m} vehicles")
    if len(seeds) < 1:
        raise ValueError("need at least one seed")
    return (gains.tiled(len(seeds)) if gains.n > 1 else gains), m, len(seeds) * m


def run_step(
    vehicle: str,
    gains: CascadeGains,
    channel: str,
    amplitude: float,
    duration_s: float,
    m: int | None = None,
    hover_alt_m: float = 20.0,
    seed: int = 0,
    limits: CascadeLimits | None = None,
    noise: FeedbackNoise | None = None,
    seeds: Sequence[int] = (0,),
    world: World | None = None,
) -> StepTrace:
    """Step of ``amplitude`` (rad for roll/pitch/yaw, m for x/y/z NED) at t = 0 from hover; ``m`` gain sets,
    each flown once per noise seed in ``seeds`` (with ``noise``; otherwise ``seeds`` just repeats the batch),
    in ``world``'s wind if given (the same gusts for every vehicle).
    """
    if channel not in ATTITUDE_AXES and channel not in POSITION_AXES:
        raise ValueError(f"step channel {channel!r} is not one of {(*ATTITUDE_AXES, *POSITION_AXES)}")
    gains, m, n = _seeded(gains, m, seeds)
    sim = _hovering_batch(vehicle, n, hover_alt_m, seed, world=world)
    ctrl = _controller(vehicle, gains, n, sim.control_dt_s, limits)
    n_steps = round(duration_s * sim.control_hz)
    stream = None if noise is None else NoiseStream(noise, seeds, m, n_steps, sim.control_dt_s)
    chatter = MotorChatter(vehicle, n, sim.control_dt_s)
    t_s = np.arange(n_steps + 1) / sim.control_hz  # sample 0 is the step instant (response 0)
    response = np.zeros((n, n_steps + 1))
    diverged = np.zeros(n, dtype=bool)
    home = np.array([0.0, 0.0, -hover_alt_m])
    if channel in ATTITUDE_AXES:
        axis = ATTITUDE_AXES[channel]
        att_sp = np.zeros((n, 3))
        att_sp[:, axis] = amplitude
        thrust_n = ctrl.hover_thrust_n()
        for k in range(1, n_steps + 1):
            q, rate = sim.q_ned_frd, sim.rate_frd
            if stream is not None:
                _, _, q, rate = stream.feedback(k - 1, sim.pos_ned, sim.vel_ned, q, rate)
            u = ctrl.update_attitude(q, rate, att_sp, thrust_n)
            chatter.add(u)
            sim.step(u)
            _euler_axis(sim, axis, out=response[:, k])
            diverged |= ~sim.running
    else:
        axis = POSITION_AXES[channel]
        pos_sp = np.broadcast_to(home, (n, 3)).copy()
        pos_sp[:, axis] += amplitude
        zeros = np.zeros((n, 3))
        for k in range(1, n_steps + 1):
            state = (sim.pos_ned, sim.vel_ned, sim.q_ned_frd, sim.rate_frd)
            if stream is not None:
                state = stream.feedback(k - 1, *state)
            u = ctrl.update_position(*state, pos_sp, zeros, zeros, 0.0)
            chatter.add(u)
            sim.step(u)
            response[:, k] = sim.pos_ned[:, axis] - home[axis]
            diverged |= ~sim.running
    error = amplitude - response
    diverged |= ~np.all(np.isfinite(error), axis=1)
    return StepTrace(channel, float(amplitude), t_s, error, response, diverged, chatter.rms(), len(seeds))


def _euler_axis(sim: BatchSim, axis: int, out: np.ndarray) -> None:
    """Roll, pitch or yaw (ZYX Euler, rad) of every vehicle, written into ``out`` (m,)."""
    q = sim.q_ned_frd
    w, x, y, z = q[:, 0], q[:, 1], q[:, 2], q[:, 3]
    if axis == 0:
        out[:] = np.arctan2(2.0 * (w * x + y * z), 1.0 - 2.0 * (x * x + y * y))
    elif axis == 1:
        out[:] = np.arcsin(np.clip(2.0 * (w * y - z * x), -1.0, 1.0))
    else:
        out[:] = np.arctan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))


def run_tracking(
    vehicle: str,
    gains: CascadeGains,
    reference: Reference,
    duration_s: float,
    m: int | None = None,
    seed: int = 0,
    limits: CascadeLimits | None = None,
    record_every: int = 1,
    world: World | None = None,
    noise: FeedbackNoise | None = None,
    seeds: Sequence[int] = (0,),
) -> TrackTrace:
    """Track ``reference`` for ``duration_s`` starting in hover at the reference's start point.

    ``world``: e.g. :func:`gusty_world`; all vehicles share ``seed``, so they meet the same gusts.
    ``noise``/``seeds``: feedback noise as in :func:`run_step` (errors are true-state errors)."""
    gains, m, n = _seeded(gains, m, seeds)
    ref0 = reference(0.0)
    sim = _hovering_batch(vehicle, n, 0.0, seed, world=world)
    sim.reset(pos_ned=ref0.pos_ned, yaw_rad=ref0.yaw_rad)
    sim.omega_rad_s[:] = sim.hover_omega_rad_s()[:, None]
    sim.on_ground[:] = False
    ctrl = _controller(vehicle, gains, n, sim.control_dt_s, limits)
    n_steps = round(duration_s * sim.control_hz)
    stream = None if noise is None else NoiseStream(noise, seeds, m, n_steps, sim.control_dt_s)
    chatter = MotorChatter(vehicle, n, sim.control_dt_s)
    n_rec = n_steps // record_every
    t_s = np.empty(n_rec)
    pos_err = np.empty((n, n_rec, 3))
    att_err = np.empty((n, n_rec, 3))
    pos_rec = np.empty((n, n_rec, 3))
    ref_rec = np.empty((n_rec, 3))
    diverged = np.zeros(n, dtype=bool)
    pos_sp = np.empty((n, 3))
    vel_sp = np.empty((n, 3))
    acc_ff = np.empty((n, 3))
    true_att = np.empty((n, 3))
    for k in range(n_steps):
        ref = reference(k * sim.control_dt_s)
        pos_sp[:] = ref.pos_ned
        vel_sp[:] = ref.vel_ned
        acc_ff[:] = ref.acc_ned
        state = (sim.pos_ned, sim.vel_ned, sim.q_ned_frd, sim.rate_frd)
        if stream is not None:
            state = stream.feedback(k, *state)
        u = ctrl.update_position(*state, pos_sp, vel_sp, acc_ff, ref.yaw_rad)
        chatter.add(u)
        if k % record_every == 0 and k // record_every < n_rec:
            r = k // record_every
            t_s[r] = k * sim.control_dt_s
            if stream is None:
                pos_err[:, r] = ctrl.diagnostics.pos_err_ned
                att_err[:, r] = ctrl.diagnostics.att_err_rad
            else:  # the controller's errors hold the noise: measure against the true state
                pos_err[:, r] = pos_sp - sim.pos_ned
                for axis in range(3):
                    _euler_axis(sim, axis, out=true_att[:, axis])
                att_err[:, r] = _wrap(ctrl.diagnostics.att_sp_rad - true_att)
            pos_rec[:, r] = sim.pos_ned
            ref_rec[r] = ref.pos_ned
        sim.step(u)
        diverged |= ~sim.running
    diverged |= ~(np.all(np.isfinite(pos_err), axis=(1, 2)) & np.all(np.isfinite(att_err), axis=(1, 2)))
    return TrackTrace(t_s, pos_err, att_err, pos_rec, ref_rec, diverged, chatter.rms(), len(seeds))


def _wrap(angle_rad: np.ndarray) -> np.ndarray:
    return (angle_rad + np.pi) % (2.0 * np.pi) - np.pi


def run_mass_change(
    vehicle: str,
    gains: CascadeGains,
    mass_fraction_change: float,
    t_change_s: float,
    duration_s: float,
    payload_before_kg: float,
    m: int | None = None,
    hover_alt_m: float = 20.0,
    seed: int = 0,
    limits: CascadeLimits | None = None,
) -> MassChangeTrace:
    """Hover with ``payload_before_kg`` (the controller knows this mass), then the total mass changes by
    ``mass_fraction_change`` (e.g. -0.3) at ``t_change_s`` through the payload; the controller is not told.
    """
    m = gains.n if m is None else m
    sim = _hovering_batch(vehicle, m, hover_alt_m, seed, payload_kg=payload_before_kg)
    mass_before = float(sim.mass_kg[0])
    mass_after = mass_before * (1.0 + mass_fraction_change)
    payload_after = mass_after - sim.vehicle.mass_kg
    if payload_after < 0.0:
        raise ValueError(
            f"a {mass_fraction_change:+.0%} change from {mass_before:.3f} kg leaves less than the airframe "
            f"({sim.vehicle.mass_kg} kg): carry more payload before the change"
        )
    ctrl = _controller(vehicle, gains, m, sim.control_dt_s, limits)
    ctrl.set_mass_kg(mass_before)
    n_steps = round(duration_s * sim.control_hz)
    k_change = round(t_change_s * sim.control_hz)
    t_s = np.arange(1, n_steps + 1) / sim.control_hz
    alt_err = np.empty((m, n_steps))
    home = np.array([0.0, 0.0, -hover_alt_m])
    pos_sp = np.broadcast_to(home, (m, 3)).copy()
    zeros = np.zeros((m, 3))
    diverged = np.zeros(m, dtype=bool)
    for k in range(n_steps):
        if k == k_change:
            sim.payload_kg[:] = payload_after
        u = ctrl.update_position(sim.pos_ned, sim.vel_ned, sim.q_ned_frd, sim.rate_frd, pos_sp, zeros, zeros, 0.0)
        sim.step(u)
        alt_err[:, k] = sim.pos_ned[:, 2] - home[2]  # NED down: positive = below the setpoint
        diverged |= ~sim.running
    return MassChangeTrace(t_s, alt_err, t_change_s, mass_before, mass_after, diverged)


def mean_square_cost(error: np.ndarray, t_s: np.ndarray, diverged: np.ndarray, t0_s: float = 0.0) -> np.ndarray:
    """ES cost J = 1/(tf − t0) ∫_{t0}^{tf} e² dt per vehicle (SPEC §6.3, ``autopilot.tuning.metrics.es_cost``);
    +inf where the rollout diverged. ``error`` is (m, T) sampled at ``t_s`` (T,)."""
    with np.errstate(invalid="ignore", over="ignore"):
        j = es_cost(np.nan_to_num(error, nan=0.0, posinf=0.0, neginf=0.0), t_s, t0_s=max(t0_s, float(t_s[0])))
    return np.where(diverged | ~np.isfinite(j), np.inf, j)
