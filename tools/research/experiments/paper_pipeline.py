"""The paper's experiments reproduced in-process (paper section 4, SPEC §6.4 and §12).

1. Tune, with the SAME extremum-seeking method and the same rollout budget, a fixed PID (k1 == k2, 3
   numbers per level) and the NLVG-PID (k1, k2: 6 numbers per level): attitude level first (roll+pitch
   steps), then the position level (x+y steps) flown on top of that structure's tuned attitude loop.
   Budget fairness: the PID gets at least as many rollouts as the NLVG (more iterations, since each of its
   iterations needs fewer probes); both start one restart at the paper's gains, the others at random.
2. Step responses of roll, pitch (attitude loop alone) and x, y (whole cascade): IAE, ITAE, ITSE over
   t_peak = 0.15 s (attitude, errors in degrees as in the paper's Table 1) and 0.37 s (position, m).
3. Storm spiral and 3D Lissajous tracking in gusty wind (the same seeded gusts for both controllers), and
   in calm air: RMS of the position-error norm (m) and of the attitude-error norm (deg) over the route.
4. Portability: the two gain sets tuned on the x500, unchanged, on quad250, x500 and delivery650
   (Lissajous). Payload: delivery650 hovering, total mass −30 % / +30 % mid-flight (controller not told).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from autopilot.control.gains import CascadeGains
from autopilot.tuning import CentralEsConfig
from autopilot.tuning.metrics import T_PEAK_ATTITUDE_S, T_PEAK_POSITION_S, iae, itae, itse, rms
from tools.research.experiments.references import make_reference
from tools.research.experiments.rollout import (
    MassChangeTrace,
    StepTrace,
    TrackTrace,
    gusty_world,
    run_mass_change,
    run_step,
    run_tracking,
)
from tools.research.experiments.tune_config import TuneConfig, load_tune_config
from tools.research.experiments.tuner import RolloutMap, TuneOutcome, in_process, tune

CONFIG_DIR = Path(__file__).resolve().parent
LEVELS = ("attitude", "position")
STRUCTURES = ("pid", "nlvg")
STEP_CHANNELS = {"phi": "roll", "theta": "pitch", "x": "x", "y": "y"}
PORTABILITY_VEHICLES = ("quad250", "x500", "delivery650")
RECOVERY_BAND_M = 0.1
#: route disturbance: 2.8 m/s mean wind (towards the south-east... NED (2, 2, 0): blowing towards north-east)
#: plus 1.5 m/s (1 sigma) Gauss-Markov gusts
WIND_MEAN_NED_M_S = (2.0, 2.0, 0.0)
WIND_GUST_M_S = 1.5


@dataclass(frozen=True, slots=True)
class PaperSettings:
    """Budgets and durations; ``quick()`` gives a smoke-test version of the same pipeline."""

    nlvg_iterations: int = 15
    restarts: int = 5
    seed: int = 0
    step_duration_attitude_s: float = 1.0
    step_duration_position_s: float = 4.0
    storm_duration_s: float = 140.0
    lissajous_duration_s: float = 40.0
    payload_vehicle: str = "delivery650"
    payload_hover_s: float = 3.0
    payload_after_s: float = 30.0
    tune_step_scale: float = 1.0  # multiplies the tuning configs' step durations (quick mode shortens them)
    # the noisy, effort-aware setting (tools/research/experiments/noisy_pipeline.py, noisy_eval.py)
    effort_scales: tuple[float, ...] = (0.0, 1.0, 4.0)  # λ multipliers of the sweep; 1.0 is the headline
    noisy_iterations: int | None = 4  # NLVG ES iterations per noisy tune (the PID: equal rollouts); None: configs'
    hover_s: float = 10.0
    noisy_storm_duration_s: float = 140.0
    noisy_lissajous_duration_s: float = 40.0

    @classmethod
    def quick(cls) -> PaperSettings:
        return cls(
            nlvg_iterations=1,
            restarts=1,
            step_duration_attitude_s=0.3,
            step_duration_position_s=0.6,
            storm_duration_s=2.0,
            lissajous_duration_s=2.0,
            payload_hover_s=0.3,
            payload_after_s=0.7,
            tune_step_scale=0.2,
            effort_scales=(0.0, 1.0),
            noisy_iterations=1,
            hover_s=0.5,
            noisy_storm_duration_s=2.0,
            noisy_lissajous_duration_s=2.0,
        )


@dataclass(frozen=True, slots=True)
class TunedPair:
    """The tuned cascade gains of each structure and the four tune outcomes."""

    gains: dict[str, CascadeGains]  # "pid" / "nlvg"
    outcomes: dict[tuple[str, str], TuneOutcome]  # (level, structure)


def _config(level: str, structure: str) -> TuneConfig:
    return load_tune_config(CONFIG_DIR / f"{level}_{structure}.yaml")


def equal_budget_iterations(nlvg_dim: int, pid_dim: int, restarts: int, nlvg_iterations: int) -> int:
    """PID iterations so that its rollouts ``R (2 d_pid + 1)(I + 1)`` are >= the NLVG's."""
    nlvg_rollouts = restarts * (2 * nlvg_dim + 1) * (nlvg_iterations + 1)
    return math.ceil(nlvg_rollouts / (restarts * (2 * pid_dim + 1))) - 1


def tune_both(
    settings: PaperSettings, log: Callable[[str], None] = print, rollouts: RolloutMap = in_process
) -> TunedPair:
    """Tune attitude then position, for PID and NLVG alike (same method, budget >= for the PID); ``rollouts``
    flies the ES cost evaluations (in this process, or on the campaign engine: the same numbers)."""
    gains: dict[str, CascadeGains] = {}
    outcomes: dict[tuple[str, str], TuneOutcome] = {}
    base = {s: CascadeGains.fixed_pid() for s in STRUCTURES}
    for level in LEVELS:
        cfgs = {s: _config(level, s) for s in STRUCTURES}
        dims = {s: cfgs[s].parametrisation().space().dim for s in STRUCTURES}
        iters = {
            "nlvg": settings.nlvg_iterations,
            "pid": equal_budget_iterations(dims["nlvg"], dims["pid"], settings.restarts, settings.nlvg_iterations),
        }
        for s in STRUCTURES:
            cfg = cfgs[s]
            if not isinstance(cfg.es, CentralEsConfig):
                raise ValueError(f"{level}_{s}.yaml: the paper pipeline uses the central method")
            exps = tuple(replace(e, duration_s=e.duration_s * settings.tune_step_scale) for e in cfg.experiments)
            cfg = replace(
                cfg,
                base_gains=base[s],
                experiments=exps,
                es=replace(cfg.es, iterations=iters[s], restarts=settings.restarts, seed=settings.seed),
            )
            out = tune(cfg, rollouts=rollouts)
            outcomes[(level, s)] = out
            base[s] = out.gains
            log(
                f"tuned {level:<8} {s:<4}: J {out.result.j_initial:.5g} -> {out.result.j_best:.5g} "
                f"({out.result.n_evaluations} rollouts, {out.wall_s:.1f} s)"
            )
    for s in STRUCTURES:
        gains[s] = base[s]
    return TunedPair(gains, outcomes)


def _stacked(pair: TunedPair) -> CascadeGains:
    """PID as vehicle 0, NLVG as vehicle 1 of one batch."""
    return CascadeGains.stacked([pair.gains["pid"], pair.gains["nlvg"]])


def step_table(
    pair: TunedPair, vehicle: str, settings: PaperSettings, large: bool = True
) -> tuple[dict[str, dict[str, dict[str, float]]], dict[str, StepTrace]]:
    """``{"phi"|"theta"|"x"|"y": {"pid"|"nlvg": {"IAE","ITAE","ITSE"}}}`` and the traces.

    Step amplitudes: the largest (``large``, the paper's "maximum desired angle or position") or the
    smallest of the tuning configs' steps per channel."""
    amplitude: dict[str, float] = {}
    for lvl in LEVELS:
        for e in _config(lvl, "nlvg").experiments:
            pick = max if large else min
            amplitude[e.channel] = pick(amplitude.get(e.channel, e.amplitude), e.amplitude)
    g = _stacked(pair)
    table: dict[str, dict[str, dict[str, float]]] = {}
    traces: dict[str, StepTrace] = {}
    for key, channel in STEP_CHANNELS.items():
        attitude = channel in ("roll", "pitch")
        duration = settings.step_duration_attitude_s if attitude else settings.step_duration_position_s
        tr = run_step(vehicle, g, channel, amplitude[channel], duration, m=2)
        traces[key] = tr
        e = np.degrees(tr.error) if attitude else tr.error
        t_peak = T_PEAK_ATTITUDE_S if attitude else T_PEAK_POSITION_S
        vals = {"IAE": iae(e, tr.t_s, t_peak), "ITAE": itae(e, tr.t_s, t_peak), "ITSE": itse(e, tr.t_s, t_peak)}
        table[key] = {
            s: {name: (float(v[i]) if not tr.diverged[i] else math.inf) for name, v in vals.items()}
            for i, s in enumerate(STRUCTURES)
        }
    return table, traces


def tracking_errors(tr: TrackTrace, i: int) -> dict[str, float]:
    """RMS of the position-error norm (m) and of the attitude-error norm (deg) of vehicle ``i``."""
    if tr.diverged[i]:
        return {"pos_rms_m": math.inf, "att_rms_deg": math.inf}
    pos = float(rms(np.linalg.norm(tr.pos_err_ned[i], axis=1)))
    att = float(rms(np.degrees(np.linalg.norm(tr.att_err_rad[i], axis=1))))
    return {"pos_rms_m": pos, "att_rms_deg": att}


def tracking_table(
    pair: TunedPair, vehicle: str, route: str, duration_s: float, gusty: bool = True, seed: int = 0
) -> tuple[dict[str, dict[str, float]], TrackTrace]:
    """``{"pid"|"nlvg": {"pos_rms_m", "att_rms_deg"}}`` on ``route`` and the trace.

    ``gusty``: mean wind :data:`WIND_MEAN_NED_M_S` plus gusts of :data:`WIND_GUST_M_S` (seeded, the same
    for both controllers): the paper's routes are flown "under disturbance"; otherwise calm air."""
    world = gusty_world(WIND_MEAN_NED_M_S, WIND_GUST_M_S, seed) if gusty else None
    tr = run_tracking(vehicle, _stacked(pair), make_reference(route, duration_s), duration_s, m=2, world=world)
    return {s: tracking_errors(tr, i) for i, s in enumerate(STRUCTURES)}, tr


def portability_table(pair: TunedPair, duration_s: float, gusty: bool = True) -> dict[str, dict[str, dict[str, float]]]:
    """The same two gain sets on every vehicle on the Lissajous route: ``{vehicle: {structure: errors}}``."""
    out: dict[str, dict[str, dict[str, float]]] = {}
    for vehicle in PORTABILITY_VEHICLES:
        out[vehicle], _ = tracking_table(pair, vehicle, "lissajous", duration_s, gusty)
    return out


def recovery_time_s(trace: MassChangeTrace, i: int, band_m: float = RECOVERY_BAND_M) -> float:
    """Time after the mass change until |altitude error| stays within ``band_m`` (inf if never)."""
    after = trace.t_s >= trace.t_change_s
    err = np.abs(trace.alt_err_m[i, after])
    t = trace.t_s[after]
    outside = np.nonzero(err > band_m)[0]
    if outside.size == 0:
        return 0.0
    last = outside[-1]
    return math.inf if last == err.size - 1 else float(t[last + 1] - trace.t_change_s)


def payload_table(
    pair: TunedPair, settings: PaperSettings
) -> tuple[dict[str, dict[str, dict[str, float]]], dict[str, MassChangeTrace]]:
    """``{"-30%"|"+30%": {structure: {"max_alt_dev_m", "recovery_s", "mass_before_kg", "mass_after_kg"}}}``.

    −30 %: the vehicle starts with payload P such that dropping all of it is −30 % of the total,
    P = 0.3 / 0.7 · m_airframe (slightly above the rated payload for delivery650). +30 %: it starts with its
    rated payload and picks up 30 % of its total mass. The controller is told the starting mass only.
    """
    from tools.research.experiments.rollout import _vehicle

    v = _vehicle(settings.payload_vehicle)
    starts = {"-30%": (-0.3, 0.3 / 0.7 * v.mass_kg), "+30%": (0.3, v.payload_max_kg)}
    table: dict[str, dict[str, dict[str, float]]] = {}
    traces: dict[str, MassChangeTrace] = {}
    for key, (frac, payload0) in starts.items():
        tr = run_mass_change(
            settings.payload_vehicle,
            _stacked(pair),
            frac,
            settings.payload_hover_s,
            settings.payload_hover_s + settings.payload_after_s,
            payload0,
            m=2,
        )
        traces[key] = tr
        after = tr.t_s >= tr.t_change_s
        table[key] = {
            s: {
                "max_alt_dev_m": math.inf if tr.diverged[i] else float(np.max(np.abs(tr.alt_err_m[i, after]))),
                "recovery_s": math.inf if tr.diverged[i] else recovery_time_s(tr, i),
                "mass_before_kg": tr.mass_before_kg,
                "mass_after_kg": tr.mass_after_kg,
            }
            for i, s in enumerate(STRUCTURES)
        }
    return table, traces
