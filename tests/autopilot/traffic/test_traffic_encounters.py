"""Encounters flown in a small kinematic closed loop: every vehicle runs its own TrafficAvoidance on the others'
1 Hz reports and flies its decision (tests/traffic_kinematic.py). Seeded random geometries, property style: no loss
of separation, no mirroring, missions completed; manned traffic never inside the NMAC volume; warn-only warns."""

from __future__ import annotations

import numpy as np
import pytest
from traffic_kinematic import (
    converging,
    crossing,
    depot_departures,
    fly,
    head_on,
    manned_crossing,
    overtaking,
    overtaking_lander,
    vertical,
)

from autopilot.traffic.param_decls import TrafficAction

PAIRS = {"head_on": head_on, "crossing": crossing, "overtaking": overtaking, "vertical": vertical,
         "overtaking_lander": overtaking_lander}  # fmt: skip
SEEDS = range(8)


def _mirrored_steps(a, b) -> int:  # type: ignore[no-untyped-def]
    """Steps where both fly a detour and their offsets point the same way (horizontally or vertically)."""
    bad = 0
    for k in set(a.offsets) & set(b.offsets):
        oa, ob = a.offsets[k], b.offsets[k]
        same_h = float(oa[:2] @ ob[:2]) > 0.0
        same_v = oa[2] * ob[2] > 0.0
        bad += same_h or same_v
    return bad


@pytest.mark.parametrize("kind", sorted(PAIRS))
def test_two_vehicles_keep_separation_and_never_mirror(kind: str) -> None:
    for seed in SEEDS:
        ships = PAIRS[kind](np.random.default_rng(seed))
        out = fly(ships, duration_s=130.0)
        assert out.min_uav_ratio >= 1.0, f"{kind} seed {seed}: separation ratio {out.min_uav_ratio:.2f}"
        assert out.completed == 2, f"{kind} seed {seed}: {[s.texts[-3:] for s in ships]}"
        assert _mirrored_steps(*ships) == 0, f"{kind} seed {seed}: both moved the same way"


def test_without_avoidance_the_same_encounters_lose_separation() -> None:
    """The geometries are real conflicts: with NAV_TRAFF_AVOID = 1 (warn) most lose separation, and warn."""
    lost = 0
    for kind in sorted(PAIRS):
        for seed in range(4):
            ships = PAIRS[kind](np.random.default_rng(seed))
            out = fly(ships, action=TrafficAction.WARN, duration_s=110.0)
            lost += out.min_uav_ratio < 1.0
            assert all(s.detour_steps == 0 for s in ships)
            assert any("Traffic conflict" in t for s in ships for t in s.texts)
    assert lost >= 12


@pytest.mark.parametrize(("n", "seeds"), [(4, range(3)), (6, range(2))])
def test_converging_vehicles_keep_separation(n: int, seeds: range) -> None:
    for seed in seeds:
        out = fly(converging(np.random.default_rng(seed), n), duration_s=120.0)
        assert out.min_uav_ratio >= 1.0, f"n={n} seed {seed}: {out.min_uav_ratio:.2f}"
        assert out.completed == n


def test_staggered_depot_departures_keep_separation() -> None:
    for seed in range(2):
        out = fly(depot_departures(np.random.default_rng(seed), 5), duration_s=150.0)
        assert out.min_uav_ratio >= 1.0, f"seed {seed}: {out.min_uav_ratio:.2f}"
        assert out.completed == 5


def test_manned_traffic_never_inside_the_nmac_volume() -> None:
    worst_warn = np.inf
    for seed in range(8):
        ships, heli = manned_crossing(np.random.default_rng(seed))
        out = fly(ships, heli, duration_s=100.0)
        assert out.min_manned_ratio >= 1.0, f"seed {seed}: NMAC ratio {out.min_manned_ratio:.2f}"
        strategic = any("giving way to ICAO A1B2C3" in t for t in ships[0].texts)
        assert strategic or ships[0].reactive_steps > 0  # a detour, or the reactive layer moved first
        ships, heli = manned_crossing(np.random.default_rng(seed))
        worst_warn = min(worst_warn, fly(ships, heli, action=TrafficAction.WARN, duration_s=100.0).min_manned_ratio)
    assert worst_warn < 1.0  # the crossings are real NMACs without avoidance


def test_an_overtaker_stopped_behind_a_vehicle_hovering_on_its_route_goes_round_it() -> None:
    """The slow vehicle stops at its drop point, on the overtaker's route: the overtaker, held in its stop (the
    route is blocked), plans a way round as if flying its route instead of waiting for ever (seeds that stayed)."""
    for seed in (11, 12, 13):
        out = fly(overtaking(np.random.default_rng(seed)), duration_s=130.0)
        assert out.min_uav_ratio >= 1.0, f"seed {seed}: separation ratio {out.min_uav_ratio:.2f}"
        assert out.completed == 2, f"seed {seed}: {[s.texts[-3:] for s in out.ships]}"
