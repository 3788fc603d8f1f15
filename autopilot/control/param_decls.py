"""Controller parameters (SPEC §8): every NLVG gain bound, δ1/δ2, variant, schedule and the cascade limits.

Names (PX4 style, <= 16 chars): ``NV_<CH>_<T>_K1`` / ``_K2`` for the k1/k2 of term T ∈ {P, I, D} of channel
CH ∈ {X, Y, Z, ROLL, PITCH, YAW}; ``NV_<CH>_DLT1`` / ``_DLT2`` for δ1/δ2; ``NV_VARIANT`` (0 raised cosine,
1 paper literal) and ``NV_SCHED`` (0 |e| for all gains, 1 per term); limits ``MPC_TILTMAX_DEG``,
``MPC_ACC_HOR_MAX``, ``MPC_ACC_UP_MAX``, ``MPC_ACC_DOWN_MAX``, ``NV_AACC_RP_MAX``, ``NV_AACC_Y_MAX``,
``NV_POS_I_MAX``, ``NV_ATT_I_MAX``, ``NV_POS_TSCALE``, ``NV_ATT_TSCALE``. Gains are dimensionless in each
loop's normalised time (pid.py), so one set flies every wheelbase.

Defaults of the gains and δ: the airframe's own ES-tuned gains, ``autopilot/control/airframe_gains/<name>.yaml``
(:func:`airframe_gains_path`, written by ``python -m tools.research.tune_es --ship --vehicle <name>``, tuned on that
airframe's own closed loop with the EKF), else the generic set :data:`DEFAULT_GAINS_PATH`
(``autopilot/control/default_gains.yaml``). Each file records the command and seeds that produced it. A
malformed file is an error, never a silent fallback.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from functools import cache
from pathlib import Path

from autopilot.control.gain_schedule import GainVariant
from autopilot.control.gains import (
    CHANNELS,
    CascadeGains,
    CascadeLimits,
    NlvgGains,
)
from autopilot.control.pid import Schedule
from autopilot.parameters.store import ParamSpec

TERMS = ("P", "I", "D")
#: The shipped default gains (a gains file, ``CascadeGains.from_yaml``), written by ``tools.research.tune_es --ship``.
DEFAULT_GAINS_PATH = Path(__file__).resolve().parent / "default_gains.yaml"
#: Per-airframe default gains (``<airframe>.yaml``), written by ``tools.research.tune_es --ship --vehicle <airframe>``.
AIRFRAME_GAINS_DIR = Path(__file__).resolve().parent / "airframe_gains"
_LIMIT_PARAMS: tuple[tuple[str, str, float, float, str, str, float], ...] = (
    # name, CascadeLimits field, min, max, unit, description, scale (param value × scale = field value)
    ("MPC_TILTMAX_DEG", "tilt_max_rad", 5.0, 80.0, "deg", "maximum tilt of the thrust vector", math.pi / 180),
    ("MPC_ACC_HOR_MAX", "acc_xy_max_m_s2", 0.5, 20.0, "m/s^2", "maximum horizontal acceleration", 1.0),
    ("MPC_ACC_UP_MAX", "acc_up_max_m_s2", 0.5, 20.0, "m/s^2", "maximum upward acceleration", 1.0),
    ("MPC_ACC_DOWN_MAX", "acc_down_max_m_s2", 0.5, 9.0, "m/s^2", "maximum downward acceleration (< g)", 1.0),
    ("NV_AACC_RP_MAX", "ang_acc_max_rp_rad_s2", 1.0, 1000.0, "rad/s^2", "roll/pitch angular accel limit", 1.0),
    ("NV_AACC_Y_MAX", "ang_acc_max_yaw_rad_s2", 1.0, 500.0, "rad/s^2", "yaw angular acceleration limit", 1.0),
    ("NV_POS_I_MAX", "pos_i_max_m_s2", 0.01, 10.0, "m/s^2", "position integrator limit (output units)", 1.0),
    ("NV_ATT_I_MAX", "att_i_max_rad_s2", 0.01, 200.0, "rad/s^2", "attitude integrator limit (output units)", 1.0),
    ("NV_POS_TSCALE", "pos_time_scale_s", 0.05, 10.0, "s", "position loop time scale T (gains per T)", 1.0),
    ("NV_ATT_TSCALE", "att_time_scale_s", 0.01, 2.0, "s", "attitude loop time scale T (gains per T)", 1.0),
)


def gain_param_name(channel: str, term: str, bound: int) -> str:
    """``NV_ROLL_P_K1`` for channel "roll", term "P", bound 1."""
    return f"NV_{channel.upper()}_{term}_K{bound}"


def delta_param_name(channel: str, which: int) -> str:
    """``NV_ROLL_DLT1`` for δ1 of channel "roll"."""
    return f"NV_{channel.upper()}_DLT{which}"


def airframe_gains_path(airframe: str) -> Path:
    """Where ``airframe``'s own default gains live (the file may not exist: then the generic set flies it)."""
    return AIRFRAME_GAINS_DIR / f"{airframe}.yaml"


def default_gains_path(airframe: str | None = None) -> Path:
    """The gains file that gives ``airframe``'s defaults: its own if shipped, else :data:`DEFAULT_GAINS_PATH`."""
    own = airframe_gains_path(airframe) if airframe else None
    return own if own is not None and own.is_file() else DEFAULT_GAINS_PATH


@cache
def shipped_gains(airframe: str | None = None) -> CascadeGains:
    """The default gains of ``airframe`` (:func:`default_gains_path`); ValueError naming the file if unusable."""
    return CascadeGains.from_yaml(default_gains_path(airframe))


def controller_param_specs(airframe: str | None = None) -> list[ParamSpec]:
    """Every controller parameter with default (gains and δ: :func:`shipped_gains` of ``airframe``), range,
    unit and description."""
    specs: list[ParamSpec] = []
    shipped = shipped_gains(airframe)
    for ch in CHANNELS:
        g = getattr(shipped, ch)
        for t, term in enumerate(TERMS):
            for bound, k in ((1, g.k1), (2, g.k2)):
                which = "small-error (k1)" if bound == 1 else "large-error (k2)"
                specs.append(
                    ParamSpec(
                        gain_param_name(ch, term, bound),
                        float(k[t]),
                        0.0,
                        100.0,
                        "",
                        f"{ch} {term} gain, {which} bound, normalised",
                    )
                )
        unit = "m" if ch in ("x", "y", "z") else "rad"
        d1, d2 = float(g.delta1), float(g.delta2)
        specs.append(ParamSpec(delta_param_name(ch, 1), d1, 0.0, 10.0, unit, f"{ch} delta1: k1 below"))
        specs.append(ParamSpec(delta_param_name(ch, 2), d2, 0.001, 20.0, unit, f"{ch} delta2: k2 above"))
    variant = float(GainVariant.parse(shipped.x.variant))
    sched = float(Schedule.parse(shipped.x.schedule))
    specs.append(ParamSpec("NV_VARIANT", variant, 0.0, 1.0, "", "k(s) shape: 0 raised cosine, 1 paper literal"))
    specs.append(ParamSpec("NV_SCHED", sched, 0.0, 1.0, "", "gain schedule signal: 0 |e| for all, 1 per term"))
    defaults = CascadeLimits()
    for name, fld, lo, hi, unit, desc, scale in _LIMIT_PARAMS:
        specs.append(ParamSpec(name, round(getattr(defaults, fld) / scale, 9), lo, hi, unit, desc))
    return specs


def _value(values: Mapping[str, float], name: str, defaults: Mapping[str, float]) -> float:
    return float(values[name]) if name in values else defaults[name]


def gains_from_params(values: Mapping[str, float]) -> CascadeGains:
    """CascadeGains from parameter values (missing names take their defaults); ValueError if inconsistent."""
    defaults = {s.name: s.default for s in controller_param_specs()}
    variant = GainVariant(round(_value(values, "NV_VARIANT", defaults))).name.lower()
    schedule = Schedule(round(_value(values, "NV_SCHED", defaults))).name.lower()
    channels = {}
    for ch in CHANNELS:
        k = {b: tuple(_value(values, gain_param_name(ch, t, b), defaults) for t in TERMS) for b in (1, 2)}
        channels[ch] = NlvgGains(
            k1=k[1],
            k2=k[2],
            delta1=_value(values, delta_param_name(ch, 1), defaults),
            delta2=_value(values, delta_param_name(ch, 2), defaults),
            variant=variant,
            schedule=schedule,
        )
    return CascadeGains(**channels)


def limits_from_params(values: Mapping[str, float], gyroscopic: bool = True) -> CascadeLimits:
    """CascadeLimits from parameter values (missing names take their defaults)."""
    defaults = {s.name: s.default for s in controller_param_specs()}
    kw = {fld: _value(values, name, defaults) * scale for name, fld, _lo, _hi, _u, _d, scale in _LIMIT_PARAMS}
    return CascadeLimits(**kw, gyroscopic=gyroscopic)


def params_from_gains(gains: CascadeGains, limits: CascadeLimits | None = None) -> dict[str, float]:
    """Parameter values of a single gain set (and limits): the inverse of gains_from_params."""
    out: dict[str, float] = {}
    for ch in CHANNELS:
        g = getattr(gains, ch).to_dict()
        for t, term in enumerate(TERMS):
            out[gain_param_name(ch, term, 1)] = g["k1"][t]
            out[gain_param_name(ch, term, 2)] = g["k2"][t]
        out[delta_param_name(ch, 1)] = g["delta1"]
        out[delta_param_name(ch, 2)] = g["delta2"]
    out["NV_VARIANT"] = float(GainVariant.parse(gains.x.variant))
    out["NV_SCHED"] = float(Schedule.parse(gains.x.schedule))
    if limits is not None:
        for name, fld, _lo, _hi, _u, _d, scale in _LIMIT_PARAMS:
            out[name] = getattr(limits, fld) / scale
    return out
