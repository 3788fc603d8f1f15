"""Closest point of approach and the separation volumes (autopilot.traffic.cpa, SPEC §13)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from autopilot.traffic.cpa import predict_approach, separation_ratio
from autopilot.traffic.param_decls import SeparationVolume

UAV = SeparationVolume(10.0, 5.0)
MANNED = SeparationVolume(150.0, 30.0)


def test_head_on_cpa_time_distance_and_loss_window() -> None:
    a = predict_approach((100.0, 0.0, 0.0), (-10.0, 0.0, 0.0), 60.0, UAV)
    assert a.t_cpa_s == pytest.approx(10.0)
    assert a.hor_cpa_m == pytest.approx(0.0)
    assert (a.loss_in_s, a.loss_out_s) == (pytest.approx(9.0), pytest.approx(11.0))
    assert a.conflict


def test_offset_pass_has_its_miss_distance() -> None:
    a = predict_approach((100.0, 30.0, 0.0), (-10.0, 0.0, 0.0), 60.0, UAV)
    assert a.hor_cpa_m == pytest.approx(30.0)
    assert not a.conflict


@pytest.mark.parametrize(
    ("lateral_m", "vertical_m", "conflict"),
    [(3.0, 2.0, True), (11.0, 0.0, False), (0.0, 6.0, False), (0.0, -6.0, False), (9.9, 4.9, True)],
)
def test_uav_separation_is_kept_when_either_distance_is_outside(lateral_m, vertical_m, conflict) -> None:  # type: ignore[no-untyped-def]
    a = predict_approach((50.0, lateral_m, vertical_m), (-5.0, 0.0, 0.0), 60.0, UAV)
    assert a.conflict is conflict


@pytest.mark.parametrize(
    ("lateral_m", "vertical_m", "uav", "manned"),
    [(100.0, 20.0, False, True), (100.0, 35.0, False, False), (160.0, 0.0, False, False), (5.0, 4.0, True, True)],
)
def test_each_class_has_its_volume(lateral_m, vertical_m, uav, manned) -> None:  # type: ignore[no-untyped-def]
    rel, vel = (2000.0, lateral_m, vertical_m), (-40.0, 0.0, 0.0)
    assert predict_approach(rel, vel, 60.0, UAV).conflict is uav
    assert predict_approach(rel, vel, 60.0, MANNED).conflict is manned


def test_beyond_the_horizon_is_no_conflict_and_inside_now_is() -> None:
    assert not predict_approach((1000.0, 0.0, 0.0), (-10.0, 0.0, 0.0), 60.0, UAV).conflict  # in 99 s
    now = predict_approach((3.0, 0.0, 1.0), (0.0, 0.0, 0.0), 60.0, UAV)
    assert (now.loss_in_s, now.loss_out_s) == (0.0, 60.0)
    assert not predict_approach((30.0, 0.0, 0.0), (5.0, 0.0, 0.0), 60.0, UAV).conflict  # diverging


def test_vertical_encounter_loss_window() -> None:
    """Straight above, descending through the level: inside while |dz| < 5 m, i.e. 15 m ... 25 m of descent."""
    a = predict_approach((0.0, 0.0, -20.0), (0.0, 0.0, 1.0), 60.0, UAV)
    assert (a.loss_in_s, a.loss_out_s) == (pytest.approx(15.0), pytest.approx(25.0))


def test_loss_window_matches_sampling_on_random_geometries() -> None:
    rng = np.random.default_rng(7)
    t = np.linspace(0.0, 60.0, 60001)
    for _ in range(200):
        rel = rng.uniform(-300, 300, 3) * (1, 1, 0.1)
        vel = rng.uniform(-12, 12, 3) * (1, 1, 0.2)
        a = predict_approach(tuple(rel), tuple(vel), 60.0, UAV)
        pos = rel + np.outer(t, vel)
        inside = (np.hypot(pos[:, 0], pos[:, 1]) < UAV.hor_m) & (np.abs(pos[:, 2]) < UAV.ver_m)
        assert a.conflict == bool(inside.any()) or abs(a.loss_out_s - a.loss_in_s) < 2e-3
        if inside.any():
            assert a.loss_in_s == pytest.approx(t[inside][0], abs=2e-3)
            assert a.loss_out_s == pytest.approx(t[inside][-1], abs=2e-3)
        hor = np.hypot(pos[:, 0], pos[:, 1])
        assert a.hor_cpa_m == pytest.approx(float(hor.min()), abs=1e-2)


def test_separation_ratio() -> None:
    assert separation_ratio((6.0, 8.0, 0.0), UAV) == pytest.approx(1.0)
    assert separation_ratio((0.0, 0.0, -7.5), UAV) == pytest.approx(1.5)
    assert separation_ratio((3.0, 0.0, 1.0), UAV) < 1.0
    assert math.isinf(separation_ratio((math.inf, 0.0, 0.0), UAV))


def test_column_loss_window_matches_sampling_below_the_track() -> None:
    """A hovering or landing UAV's volume reaches down to the ground: below it only the horizontal distance counts."""
    rng = np.random.default_rng(11)
    t = np.linspace(0.0, 60.0, 60001)
    for _ in range(200):
        rel = rng.uniform(-150, 150, 3) * (1, 1, 0.15)
        vel = rng.uniform(-8, 8, 3) * (1, 1, 0.2)
        a = predict_approach(tuple(rel), tuple(vel), 60.0, UAV, column=True)
        pos = rel + np.outer(t, vel)
        inside = (np.hypot(pos[:, 0], pos[:, 1]) < UAV.hor_m) & (pos[:, 2] < UAV.ver_m)
        assert a.conflict == bool(inside.any()) or abs(a.loss_out_s - a.loss_in_s) < 2e-3
        if inside.any():
            assert a.loss_in_s == pytest.approx(t[inside][0], abs=2e-3)
            assert a.loss_out_s == pytest.approx(t[inside][-1], abs=2e-3)
    assert separation_ratio((0.0, 0.0, -30.0), UAV, column=True) == 0.0  # 30 m under it: inside its column
    assert separation_ratio((0.0, 0.0, 7.5), UAV, column=True) == pytest.approx(1.5)  # 7.5 m above it
