"""Controller parameter declarations: names, ranges, and the params ↔ gains/limits round trip."""

from __future__ import annotations

import dataclasses
import math

import pytest

from autopilot.control.gains import CascadeGains, CascadeLimits
from autopilot.control.param_decls import (
    DEFAULT_GAINS_PATH,
    controller_param_specs,
    gains_from_params,
    limits_from_params,
    params_from_gains,
)
from autopilot.parameters.store import ParamStore


def test_every_gain_bound_delta_and_limit_is_declared() -> None:
    specs = controller_param_specs()
    names = [s.name for s in specs]
    assert len(names) == len(set(names)) and all(len(n) <= 16 for n in names)
    for ch in ("X", "Y", "Z", "ROLL", "PITCH", "YAW"):
        for term in "PID":
            assert f"NV_{ch}_{term}_K1" in names and f"NV_{ch}_{term}_K2" in names
        assert f"NV_{ch}_DLT1" in names and f"NV_{ch}_DLT2" in names
    assert {"MPC_TILTMAX_DEG", "MPC_ACC_HOR_MAX", "NV_VARIANT", "NV_SCHED"} <= set(names)
    ParamStore(specs)  # accepted by the store (valid names, defaults in range)


def test_defaults_are_the_shipped_gains_and_default_limits() -> None:
    store = ParamStore(controller_param_specs())
    g = gains_from_params(store.values())
    shipped = CascadeGains.from_yaml(DEFAULT_GAINS_PATH)
    assert g == shipped
    assert g.x.k1 != g.x.k2  # the shipped defaults are a variable gain (tools.research.tune_es --ship)
    lim = limits_from_params(store.values())
    assert lim.tilt_max_rad == pytest.approx(CascadeLimits().tilt_max_rad)


def test_round_trip_gains_params_gains() -> None:
    g = CascadeGains.paper_default(k1_scale=0.4, k2_scale=1.9, variant="paper_literal", schedule="per_term")
    lim = CascadeLimits(tilt_max_rad=math.radians(25.0), acc_xy_max_m_s2=4.0)
    values = params_from_gains(g, lim)
    store = ParamStore(controller_param_specs())
    for name, v in values.items():
        store.set(name, v)  # every value is inside its declared range
    back = gains_from_params(store.values())
    for a, b in zip(g.channels(), back.channels(), strict=True):
        assert a.to_dict() == b.to_dict()
    lim_back = limits_from_params(store.values())
    for field in dataclasses.fields(CascadeLimits):
        assert getattr(lim_back, field.name) == pytest.approx(getattr(lim, field.name), rel=1e-12)


def test_changed_param_changes_gains_and_inconsistent_deltas_are_refused() -> None:
    store = ParamStore(controller_param_specs())
    store.set("NV_ROLL_P_K2", 12.0)
    assert gains_from_params(store.values()).roll.k2[0] == 12.0
    store.set("NV_ROLL_DLT1", 2.0)  # above δ2 = 0.838
    with pytest.raises(ValueError, match="delta"):
        gains_from_params(store.values())
