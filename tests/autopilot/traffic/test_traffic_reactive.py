"""The reactive layer (autopilot.traffic.reactive, orca_kernel): the solver against scipy, the ORCA planes' duties
(reciprocal, full), the fallback's rules, the vehicle's own limits, the column checks, and a kinematic ring swap
of 8 vehicles that never enters the volume."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.optimize import minimize

from autopilot.geofence.fence import CircleZone
from autopilot.navigation.home_frame import HomeFrame
from autopilot.navigation.traffic_guard import (
    DEPARTURE_CLEAR_US,
    HELD_AGL_M,
    HELD_DESCENT_M_S,
    PAD_ASIDE_VOLUMES,
    PAD_SETTLE_US,
    TrafficGuard,
    phase_of,
)
from autopilot.param_schema import all_param_specs
from autopilot.parameters.store import ParamStore
from autopilot.traffic.columns import column_conflict
from autopilot.traffic.orca_kernel import closest_admissible
from autopilot.traffic.param_decls import SeparationVolume, TrafficParams
from autopilot.traffic.reactive import OWN_ROWS, Phase, ReactiveLayer, ReactiveLimits, covering_sphere
from autopilot.traffic.tracks import TrafficTrack
from mavlink_bridge.contract.frames import GeoPoint
from mavlink_bridge.contract.traffic import TrafficSource
from mavlink_bridge.contract.vehicle_api import FlightMode

LIMITS = ReactiveLimits(12.0, 3.0, 1.5, 3.0, -2.0, -120.0)
PARAMS = TrafficParams()


Vec = tuple[float, float, float]


def uav(target_id: int, pos: Vec, vel: Vec, t_us: int = 0) -> TrafficTrack:
    return TrafficTrack(TrafficSource.UAV, target_id, "", pos, vel, t_us)


def test_solver_is_the_closest_admissible_velocity() -> None:
    rng = np.random.default_rng(7)
    infeasible = 0
    for _ in range(60):
        m = int(rng.integers(1, 16))
        normals = rng.normal(size=(m, 3))
        normals /= np.linalg.norm(normals, axis=1)[:, None]
        offsets = rng.normal(size=m) * 2.0 - 1.0
        pref, out = rng.normal(size=3) * 3.0, np.zeros(3)
        failed = closest_admissible(normals, offsets, m, pref, out)
        cons = [{"type": "ineq", "fun": lambda v, n=normals[i], b=offsets[i]: n @ v - b} for i in range(m)]
        ref = minimize(lambda v, p=pref: ((v - p) ** 2).sum(), np.zeros(3), constraints=cons, method="SLSQP",
                       options={"ftol": 1e-12, "maxiter": 500})  # fmt: skip
        scipy_ok = ref.success and min(normals @ ref.x - offsets) > -1e-6
        if failed >= 0:
            infeasible += 1
            assert not scipy_ok
        else:
            assert min(normals @ out - offsets) > -1e-6
            if scipy_ok:
                assert ((out - pref) ** 2).sum() <= ref.fun + 1e-5
    assert 0 < infeasible < 60  # both kinds of problem were tried


def test_covering_sphere_contains_the_cylinder() -> None:
    for hor, ver, reach in ((10.0, 5.0, math.sqrt(5.0)), (150.0, 30.0, 1.5)):
        radius, scale = covering_sphere(SeparationVolume(hor, ver), reach)
        assert math.hypot(hor, ver * scale) == pytest.approx(radius)  # the rim's corner is on the sphere
        assert radius / scale == pytest.approx(reach * ver)  # its vertical reach


def test_head_on_both_turn_opposite_ways_and_share_the_change() -> None:
    a, b = ReactiveLayer(1), ReactiveLayer(2)
    pa, pb, va, vb = (0.0, 0.0, -15.0), (60.0, 0.0, -15.0), (5.0, 0.0, 0.0), (-5.0, 0.0, 0.0)
    ca = a.solve(0, pa, va, va, [uav(2, pb, vb)], PARAMS, LIMITS, Phase.MISSION)
    cb = b.solve(0, pb, vb, vb, [uav(1, pa, va)], PARAMS, LIMITS, Phase.MISSION)
    assert ca is not None and cb is not None and not ca.fallback
    da, db = np.subtract(ca.vel_ned_m_s, va), np.subtract(cb.vel_ned_m_s, vb)
    assert np.allclose(da, -db, atol=1e-6)  # reciprocal: equal and opposite halves
    assert np.linalg.norm(da) > 0.1


def test_manned_traffic_gets_full_responsibility() -> None:
    layer = ReactiveLayer(1)
    own, vel = (0.0, 0.0, -15.0), (0.0, 5.0, 0.0)
    heli = TrafficTrack(TrafficSource.MANNED, 0xA1B2C3, "HELI1", (-1200.0, 0.0, -25.0), (40.0, 0.0, 0.0), 0)
    full = layer.solve(0, own, vel, vel, [heli], PARAMS, LIMITS, Phase.MISSION)
    as_uav = layer.solve(0, own, vel, vel, [uav(9, heli.pos_home_ned_m, heli.vel_ned_m_s)], PARAMS, LIMITS,
                         Phase.MISSION)  # fmt: skip
    assert full is not None
    assert as_uav is None or np.linalg.norm(np.subtract(full.vel_ned_m_s, vel)) > np.linalg.norm(
        np.subtract(as_uav.vel_ned_m_s, vel)
    )


def test_fallback_brakes_and_escapes_away_never_below_the_floor() -> None:
    layer = ReactiveLayer(3)
    # boxed in at one level by four vehicles closing from every side: no admissible velocity at all
    own = (0.0, 0.0, -15.0)
    around = [uav(k + 10, (12.0 * math.cos(a), 12.0 * math.sin(a), -15.0), (-6.0 * math.cos(a), -6.0 * math.sin(a),
              0.0)) for k, a in enumerate(np.arange(6) * math.pi / 3)]  # fmt: skip
    above = [uav(20, (0.0, 0.0, -21.0), (0.0, 0.0, 3.0)), uav(21, (0.0, 0.0, -9.0), (0.0, 0.0, -3.0))]
    c = layer.solve(0, own, (0.0, 0.0, 0.0), (5.0, 0.0, 0.0), around + above, PARAMS, LIMITS, Phase.MISSION)
    assert c is not None and c.fallback
    assert np.hypot(*c.vel_ned_m_s[:2]) < 12.0  # the least violation of every plane, wanting a hover
    # at the floor with the other above: hold, never descend below it
    low = (0.0, 0.0, -2.0)
    c = layer.solve(0, low, (0.0, 0.0, 0.0), (5.0, 0.0, 0.0), [uav(9, (0.0, 0.0, -3.0), (0.0, 0.0, 2.0)), *around],
                    PARAMS, LIMITS, Phase.MISSION)  # fmt: skip
    assert c is not None and c.fallback and c.vel_ned_m_s[2] <= 0.0


def test_fallback_sense_on_one_level_by_system_id() -> None:
    def sense(system_id: int, other_id: int) -> float:
        layer = ReactiveLayer(system_id)
        own = (0.0, 0.0, -15.0)
        boxed = [uav(other_id, (3.0, 0.0, -15.0), (-8.0, 0.0, 0.0))] + [
            uav(30 + k, (3.0 * math.cos(a), 3.0 * math.sin(a), -15.0), (0.0, 0.0, 0.0))
            for k, a in enumerate((1.5, 3.0, 4.5))
        ]
        c = layer.solve(0, own, (0.0, 0.0, 0.0), (3.0, 0.0, 0.0), boxed, PARAMS, LIMITS, Phase.MISSION)
        assert c is not None and c.fallback
        return c.escape

    assert (sense(1, 2), sense(2, 1)) == ("climbing", "descending")  # the lower id climbs, the higher descends


def test_no_sideways_motion_on_the_pad() -> None:
    layer = ReactiveLayer(1)
    crossing = uav(2, (-20.0, 0.0, -3.0), (6.0, 0.0, 0.0))
    c = layer.solve(0, (0.0, 0.0, -0.5), (0.0, 0.0, -1.0), (0.0, 0.0, -1.5), [crossing], PARAMS, LIMITS,
                    Phase.TAKEOFF)  # fmt: skip
    assert c is not None
    assert c.vel_ned_m_s[0] == pytest.approx(0.0, abs=1e-9) and c.vel_ned_m_s[1] == pytest.approx(0.0, abs=1e-9)
    assert c.vel_ned_m_s[2] > -1.5  # the climb is slowed (or stopped), not flown into the other


def test_parked_vehicles_are_not_avoided() -> None:
    layer = ReactiveLayer(1)
    parked = uav(2, (5.0, 0.0, 0.0), (0.0, 0.0, 0.0))
    assert layer.solve(0, (0.0, 0.0, -0.2), (0.0, 0.0, 0.0), (0.0, 0.0, -1.5), [parked], PARAMS, LIMITS,
                       Phase.TAKEOFF) is None  # fmt: skip


def test_column_conflict_departure_and_clear() -> None:
    pad = (0.0, 0.0, 0.0)
    through = uav(2, (-100.0, 0.0, -15.0), (8.0, 0.0, 0.0))
    wide = uav(3, (-100.0, 60.0, -15.0), (8.0, 0.0, 0.0))
    high = TrafficTrack(TrafficSource.MANNED, 1, "C172", (-2000.0, 0.0, -120.0), (50.0, 0.0, 0.0), 0)
    low = TrafficTrack(TrafficSource.MANNED, 2, "HELI", (-1000.0, 100.0, -25.0), (40.0, 0.0, 0.0), 0)
    assert column_conflict(through, 0, pad, -30.0, 25.0, PARAMS) == pytest.approx((100.0 - 13.0) / 8.0, abs=0.5)
    assert column_conflict(through, 0, pad, -30.0, 5.0, PARAMS) is None  # not before the vehicle is up
    assert column_conflict(wide, 0, pad, -30.0, 60.0, PARAMS) is None
    assert column_conflict(high, 0, pad, -30.0, 60.0, PARAMS) is None  # 120 m: above the column and its volume
    assert column_conflict(low, 0, pad, -30.0, 60.0, PARAMS) is not None  # 25 m, 100 m aside: inside the NMAC


def test_phase_of_modes() -> None:
    assert phase_of(FlightMode.POSCTL, False, (0.0, 0.0, -10.0), (0.0, 0.0, 0.0)) is Phase.MANUAL
    assert phase_of(FlightMode.AUTO_MISSION, True, (0.0, 0.0, -10.0), (0.0, 0.0, 1.0)) is Phase.LAND
    assert phase_of(FlightMode.AUTO_MISSION, False, (0.0, 0.0, -0.3), (0.0, 0.0, -1.0)) is Phase.TAKEOFF
    assert phase_of(FlightMode.AUTO_RTL, False, (0.0, 0.0, -20.0), (3.0, 0.0, 0.0)) is Phase.RETURN
    low_far = (260.0, 40.0, -1.8)  # pushed down to the floor far from its pad, climbing back: no take-off
    assert phase_of(FlightMode.AUTO_MISSION, False, low_far, (0.0, 0.0, -1.0), departing=False) is Phase.MISSION


def test_a_low_climb_away_from_where_the_take_off_began_is_no_take_off() -> None:
    """The departure hold is for a vehicle leaving its pad: in the failure search of the depot with a helicopter
    (case 3) one pushed down to the floor 260 m from its pad was held as a take-off there, sank to 0.7 m and, unable
    to move sideways so low, was come at by another within 4.4 m."""
    guard = TrafficGuard(ParamStore(all_param_specs()), 1)
    assert not guard.departing((0.0, 0.0, -0.5))  # never took off under this guard
    guard.taking_off = True
    assert guard.departing((0.0, 0.0, -0.5))
    frame = HomeFrame(GeoPoint(47.3977, 8.5456, 488.0))
    still = (0.0, 0.0, 0.0)
    guard.step(0, 0.02, frame, (0.5, 0.2, -0.4), still, (0.5, 0.2, -15.0), (0.0, 0.0, -1.0), FlightMode.AUTO_MISSION,
               False, _Table([]), PARAMS)  # type: ignore[arg-type]  # fmt: skip
    guard.taking_off = False  # off the pad
    assert guard.departing((1.5, 0.0, -1.5)) and not guard.departing((260.0, 40.0, -1.8))


def _ring_swap(n: int, radius_m: float, latency_s: float) -> tuple[float, int]:
    """``n`` point-mass vehicles at one altitude fly to the antipodal point (3 m/s^2, 8 m/s, reports at 1 Hz with
    ``latency_s``); the smallest separation ratio of any pair and how many arrived."""
    dt, params = 0.05, TrafficParams()
    angles = np.arange(n) * 2.0 * math.pi / n
    pos = np.stack([radius_m * np.cos(angles), radius_m * np.sin(angles), np.full(n, -15.0)], axis=1)
    goal = pos * np.array([-1.0, -1.0, 1.0])
    vel = np.zeros((n, 3))
    layers = [ReactiveLayer(i + 1) for i in range(n)]
    reports: list[list[TrafficTrack]] = [[] for _ in range(n)]
    held: list[dict[int, TrafficTrack]] = [{} for _ in range(n)]
    worst = math.inf
    steps = round(90.0 / dt)
    for k in range(steps):
        t = k * dt
        t_us = round(t * 1e6)
        for i in range(n):  # one report of every other vehicle each second, staggered, arriving latency_s later
            if k % round(1.0 / dt) == i % round(1.0 / dt):
                reports[i] += [uav(j + 1, tuple(pos[j]), tuple(vel[j]), t_us) for j in range(n) if j != i]
            for r in [r for r in reports[i] if t - r.t_us * 1e-6 >= latency_s]:
                held[i][r.target_id] = r
            reports[i] = [r for r in reports[i] if t - r.t_us * 1e-6 < latency_s]
        cmds = []
        for i in range(n):
            to_goal = goal[i] - pos[i]
            dist = float(np.linalg.norm(to_goal))
            speed = min(8.0, math.sqrt(2.0 * 3.0 * dist))
            pref = to_goal / dist * speed if dist > 1e-6 else np.zeros(3)
            c = layers[i].solve(t_us, tuple(pos[i]), tuple(vel[i]), tuple(pref), list(held[i].values()), params,
                                LIMITS, Phase.MISSION)  # fmt: skip
            cmds.append(np.array(c.vel_ned_m_s) if c is not None else pref)
        for i in range(n):
            dv = cmds[i] - vel[i]
            norm = float(np.linalg.norm(dv))
            vel[i] += dv if norm <= 3.0 * dt else dv / norm * 3.0 * dt
            pos[i] += vel[i] * dt
        for i in range(n):
            for j in range(i + 1, n):
                d = pos[j] - pos[i]
                worst = min(worst, max(math.hypot(d[0], d[1]) / params.uav.hor_m, abs(d[2]) / params.uav.ver_m))
    arrived = int(sum(np.linalg.norm(goal[i] - pos[i]) < 2.0 for i in range(n)))
    return worst, arrived


@pytest.mark.parametrize("n", [4, 8])
def test_ring_swap_keeps_the_volume(n: int) -> None:
    worst, arrived = _ring_swap(n, 60.0, latency_s=0.5)
    assert worst >= 1.0, f"a pair came inside the 10 m / 5 m volume (ratio {worst:.2f})"
    assert arrived == n


def test_the_escape_stays_inside_the_fence() -> None:
    """Near the edge of a 300 m inclusion circle, pushed toward it by traffic: no faster than the room allows."""
    from autopilot.geofence.fence import CircleZone

    fence = (CircleZone((0.0, 0.0), 300.0, True),)
    limits = ReactiveLimits(12.0, 3.0, 1.5, 3.0, -2.0, -120.0, fence, 3.0)
    layer = ReactiveLayer(1)
    heli = TrafficTrack(TrafficSource.MANNED, 0xA1B2C3, "HELI1", (-400.0, 0.0, -20.0), (40.0, 0.0, 0.0), 0)
    own = (290.0, 0.0, -15.0)
    c = layer.solve(0, own, (0.0, 0.0, 0.0), (0.0, 0.0, 0.0), [heli], PARAMS, limits, Phase.MISSION)
    assert c is not None
    assert c.vel_ned_m_s[0] <= (300.0 - 290.0 - 3.0) / 2.0 + 0.05  # the room beyond the margin, over 2 s
    free = layer.solve(0, own, (0.0, 0.0, 0.0), (0.0, 0.0, 0.0), [heli], PARAMS, LIMITS, Phase.MISSION)
    assert free is not None and free.vel_ned_m_s[0] > c.vel_ned_m_s[0] + 0.5  # without the fence it would go on


def test_the_fence_room_is_counted_from_where_the_vehicle_will_be() -> None:
    """Flying at the edge at 8 m/s, the room is what is left once the vehicle answers (FENCE_RESPONSE_S later): a
    bound from where it is let two vehicles fleeing a light aircraft cross a 300 m circle by 2 m (case 41)."""
    from autopilot.geofence.fence import CircleZone
    from autopilot.traffic.reactive import FENCE_RESPONSE_S

    fence = (CircleZone((0.0, 0.0), 300.0, True),)
    limits = ReactiveLimits(12.0, 3.0, 1.5, 3.0, -2.0, -120.0, fence, 3.0)
    heli = TrafficTrack(TrafficSource.MANNED, 0xA1B2C3, "HELI1", (-400.0, 0.0, -20.0), (40.0, 0.0, 0.0), 0)
    own, room = (280.0, 0.0, -15.0), 20.0 - 3.0
    still = ReactiveLayer(1).solve(0, own, (0.0, 0.0, 0.0), (8.0, 0.0, 0.0), [heli], PARAMS, limits, Phase.MISSION)
    moving = ReactiveLayer(1).solve(0, own, (8.0, 0.0, 0.0), (8.0, 0.0, 0.0), [heli], PARAMS, limits, Phase.MISSION)
    assert still is not None and moving is not None
    assert still.vel_ned_m_s[0] == pytest.approx(room / 2.0, abs=0.05)
    assert moving.vel_ned_m_s[0] == pytest.approx((room - 8.0 * FENCE_RESPONSE_S) / 2.0, abs=0.05)


def test_no_sideways_motion_near_the_ground_even_at_the_layers_own_velocity() -> None:
    """Low over the pads the layer moves the vehicle only vertically, whatever velocity it prefers: while it flies,
    the preferred velocity is its own, and a bound "toward the preferred one" let a landing vehicle skid off."""
    layer = ReactiveLayer(1)
    landing = uav(2, (0.0, 12.0, -4.0), (0.0, 0.0, 0.5))  # beside it, inside its volume, descending to its pad
    c = layer.solve(0, (0.0, 0.0, -1.0), (0.0, -2.0, 0.0), (0.0, -2.0, 0.0), [landing], PARAMS, LIMITS, Phase.HOLD)
    assert c is not None
    assert c.vel_ned_m_s[0] == pytest.approx(0.0, abs=1e-9) and c.vel_ned_m_s[1] == pytest.approx(0.0, abs=1e-9)


def test_away_from_the_pads_a_vehicle_at_the_floor_still_moves_aside() -> None:
    """The ground lock is for the pads: a vehicle pushed down to 1.8 m in the field (fleeing a helicopter, search
    case 3) with another closing on it moves aside; over a pad it only moves vertically."""
    closing = uav(2, (0.0, 12.0, -3.0), (0.0, -6.0, 0.0))
    field = ReactiveLayer(1).solve(0, (0.0, 0.0, -1.8), (0.0, 0.0, 0.0), (0.0, 0.0, 0.0), [closing], PARAMS, LIMITS,
                                   Phase.MISSION, over_pad=False)  # fmt: skip
    pad = ReactiveLayer(1).solve(0, (0.0, 0.0, -1.8), (0.0, 0.0, 0.0), (0.0, 0.0, 0.0), [closing], PARAMS, LIMITS,
                                 Phase.MISSION)  # fmt: skip
    assert field is not None and math.hypot(field.vel_ned_m_s[0], field.vel_ned_m_s[1]) > 1.0, field
    assert pad is not None and math.hypot(pad.vel_ned_m_s[0], pad.vel_ned_m_s[1]) < 1e-9, pad


class _Table:
    """The two things the guard reads of a track table."""

    def __init__(self, tracks: list[TrafficTrack]) -> None:
        self.tracks, self.has_tracks, self.version = tuple(tracks), bool(tracks), 1


@pytest.mark.parametrize(("agl_m", "engaged"), [(8.0, True), (1.0, False)])
def test_a_landing_below_the_ground_lock_is_committed(agl_m: float, engaged: bool) -> None:
    """A vehicle landing beside another landing one: avoided up high; below the ground lock it touches down."""
    guard = TrafficGuard(ParamStore(all_param_specs()), 1)
    other = uav(2, (0.0, 11.0, -agl_m), (0.0, 0.0, 0.8))
    frame = HomeFrame(GeoPoint(47.3977, 8.5456, 488.0))
    out = guard.step(0, 0.004, frame, (0.0, 0.0, -agl_m), (0.0, 0.0, 0.8), (0.0, 0.0, -agl_m), (0.0, 0.0, 0.8),
                     FlightMode.AUTO_MISSION, True, _Table([other]), PARAMS)  # type: ignore[arg-type]  # fmt: skip
    assert (out is not None) is engaged and guard.engaged is engaged


def _departed_here(params: ParamStore, frame: HomeFrame) -> TrafficGuard:
    """A guard whose commander's take-off left the ground at home (no track then), its take-off state over."""
    guard = TrafficGuard(params, 1)
    guard.taking_off = True
    pad = (0.0, 0.0, -0.05)
    guard.step(-100_000, 0.004, frame, pad, (0.0, 0.0, 0.0), pad, (0.0, 0.0, -1.0), FlightMode.AUTO_MISSION, False,
               _Table([]), PARAMS)  # type: ignore[arg-type]  # fmt: skip
    guard.taking_off = False
    return guard


def test_a_take_off_waits_on_the_pad_for_a_manned_aircraft_within_the_look_ahead() -> None:
    """A helicopter 40 s out, crossing over the depot at 22 m: the climb-out column (30 m at the 3 m/s climb + 5 s)
    is clear of it, but once up no escape leaves its NMAC volume in time; the vehicle stays on the pad, not moving
    at all (the layer's own escape would climb out of it). A UAV as far out is not waited for."""
    params = ParamStore(all_param_specs())
    frame = HomeFrame(GeoPoint(47.3977, 8.5456, 488.0))
    heli = TrafficTrack(TrafficSource.MANNED, 0xA1, "HELI1", (-1100.0, 40.0, -22.0), (27.0, 0.0, 0.0), 0)
    far_uav = uav(2, heli.pos_home_ned_m, heli.vel_ned_m_s)
    for track, held in ((heli, True), (far_uav, False)):
        guard = _departed_here(params, frame)
        pad, climb = (0.0, 0.0, -0.05), (0.0, 0.0, -3.0)
        out = guard.step(0, 0.004, frame, pad, (0.0, 0.0, 0.0), pad, climb, FlightMode.AUTO_MISSION, False,
                         _Table([track]), PARAMS)  # type: ignore[arg-type]  # fmt: skip
        assert (out is not None) is held
        if held:
            assert guard.command is not None and guard.command.vel_ned_m_s == (0.0, 0.0, 0.0)
            # held, its reference stops (no longer climbs, may even sag): the hold stays, said once (it used to
            # flip to "avoiding" at every solve whose reference did not climb, and let the vehicle creep up)
            for k, ref_vz in enumerate((0.0, 0.01, -0.01, 0.0) * 5):
                t_us = (k + 1) * 20_000
                out = guard.step(t_us, 0.004, frame, pad, (0.0, 0.0, 0.0), pad, (0.0, 0.0, ref_vz),
                                 FlightMode.AUTO_MISSION, False, _Table([track]), PARAMS)  # type: ignore[arg-type]  # fmt: skip
                assert out is not None and guard.holding_takeoff
                assert guard.command is not None and guard.command.vel_ned_m_s == (0.0, 0.0, 0.0)
            assert [t.text for t in guard.texts] == ["Traffic: take-off held for HELI1"]
    # its ADS-B climb rate is noise (3 m/s up would carry it over the column): a level flight is predicted too
    noisy = TrafficTrack(TrafficSource.MANNED, 0xA1, "HELI1", (-1100.0, 40.0, -22.0), (27.0, 0.0, -3.0), 0)
    guard = _departed_here(params, frame)
    # and a vehicle that had left the pad when the hold came goes back down to HELD_AGL_M, not onto the pad
    up = (0.0, 0.0, -1.6)
    out = guard.step(0, 0.004, frame, up, (0.0, 0.0, 0.0), up, (0.0, 0.0, -0.5), FlightMode.AUTO_MISSION, False,
                     _Table([noisy]), PARAMS)  # type: ignore[arg-type]  # fmt: skip
    assert out is not None and guard.holding_takeoff and guard.command is not None
    assert guard.command.vel_ned_m_s == (0.0, 0.0, HELD_DESCENT_M_S)
    low = (0.0, 0.0, -HELD_AGL_M)
    guard.step(20_000, 0.004, frame, low, (0.0, 0.0, 0.0), low, (0.0, 0.0, 0.0), FlightMode.AUTO_MISSION, False,
               _Table([noisy]), PARAMS)  # type: ignore[arg-type]  # fmt: skip
    assert guard.holding_takeoff and guard.command is not None and guard.command.vel_ned_m_s == (0.0, 0.0, 0.0)
    guard.taking_off = True  # the commander's take-off has not left the pad: it sits back on it (no land detection)
    guard.step(40_000, 0.004, frame, low, (0.0, 0.0, 0.0), low, (0.0, 0.0, 0.0), FlightMode.AUTO_MISSION, False,
               _Table([noisy]), PARAMS)  # type: ignore[arg-type]  # fmt: skip
    assert guard.command is not None and guard.command.vel_ned_m_s == (0.0, 0.0, HELD_DESCENT_M_S)
    pad, still, sinking = (0.0, 0.0, -0.05), (0.0, 0.0, 0.0), (0.0, 0.0, 0.5)
    assert not guard.on_pad(40_000, frame, low, still)  # half a metre up: flown down onto it
    assert not guard.on_pad(60_000, frame, pad, sinking)  # still coming down
    assert not guard.on_pad(80_000, frame, pad, still)  # on it, settling: the hold's descent still flown
    assert guard.on_pad(80_000 + PAD_SETTLE_US, frame, pad, still)  # settled: the caller flies nothing
    guard.taking_off = False
    assert not guard.on_pad(90_000 + PAD_SETTLE_US, frame, pad, still)  # the take-off is over (landing detected)
    passed = TrafficTrack(TrafficSource.MANNED, 0xA1, "HELI1", (300.0, 40.0, -22.0), (27.0, 0.0, 0.0), 0)
    guard = _departed_here(params, frame)
    out = guard.step(0, 0.004, frame, (0.0, 0.0, -0.05), (0.0, 0.0, 0.0), (0.0, 0.0, -0.05), (0.0, 0.0, -3.0),
                     FlightMode.AUTO_MISSION, False, _Table([passed]), PARAMS)  # type: ignore[arg-type]  # fmt: skip
    assert out is None  # gone past: the take-off goes on


def test_a_crowd_does_not_flood_the_link_with_texts() -> None:
    """Among several tracks the binding plane changes at every solve (50 Hz): a text names a new binding track at
    most every 5 s, a change of kind (reactive, fallback) at most every second; it used to be one text a solve."""
    guard = TrafficGuard(ParamStore(all_param_specs()), 1)
    frame = HomeFrame(GeoPoint(47.3977, 8.5456, 488.0))
    own, vel = (0.0, 0.0, -15.0), (0.0, 5.0, 0.0)
    a = uav(2, (0.0, 30.0, -15.0), (0.0, -5.0, 0.0))
    b = uav(3, (10.0, 30.0, -15.0), (-1.0, -5.0, 0.0))
    for k in range(250):  # 5 s of solves, the two tracks swapping their order in the table (which binds varies)
        table = _Table([a, b] if k % 2 else [b, a])
        guard.step(k * 20_000, 0.02, frame, own, vel, own, vel, FlightMode.AUTO_MISSION, False, table, PARAMS)  # type: ignore[arg-type]
    said = [t.text for t in guard.texts if t.text.startswith("Traffic:")]
    assert 1 <= len(said) <= 6, said


def test_a_level_change_waits_for_a_clear_corridor() -> None:
    """The vertical encounter: a vehicle climbing from 10 m toward 24 m meets one descending from 24 m head-on; the
    climb is held (level flight at 10 m keeps 14 m from the other) until the other has passed, then goes on. A track
    in a lane 25 m aside, one keeping station over the vehicle (the reactive layer's), and a change within the
    vehicle's own volume hold nothing."""
    params = ParamStore(all_param_specs())
    frame = HomeFrame(GeoPoint(47.3977, 8.5456, 488.0))
    own, vel, climb = (0.0, 0.0, -10.0), (5.0, 0.0, -2.0), (5.0, 0.0, -3.0)
    cases = (
        (uav(2, (20.0, 0.0, -24.0), (-5.0, 0.0, 2.0)), "Traffic: climb held for UAV 2 (predicted through the column)"),
        (uav(3, (20.0, 25.0, -24.0), (-5.0, 0.0, 2.0)), None),  # another lane
        (uav(4, (0.0, 0.0, -30.0), (5.0, 0.0, 0.0)), None),  # station over the vehicle: no passing
        (uav(5, (-20.0, 0.0, -24.0), (-5.0, 0.0, 0.0)), None),  # behind, going away: passed
    )
    for track, said in cases:
        guard = TrafficGuard(params, 1)
        guard.step(0, 0.004, frame, own, vel, own, climb, FlightMode.AUTO_MISSION, False, _Table([track]), PARAMS)  # type: ignore[arg-type]
        held = guard.command is not None and guard.command.escape == "climb held"
        assert held is (said is not None), track
        if said is not None:
            assert guard.command is not None and guard.command.vel_ned_m_s[2] >= 0.0  # no climb (the layer may descend)
            assert [t.text for t in guard.texts] == [said]
    guard = TrafficGuard(params, 1)
    small = (5.0, 0.0, -1.0)  # 5 m in CORRIDOR_S: inside its own grown volume (6.5 m)
    ahead = uav(2, (20.0, 0.0, -16.0), (-5.0, 0.0, 0.0))
    guard.step(0, 0.004, frame, own, vel, own, small, FlightMode.AUTO_MISSION, False, _Table([ahead]), PARAMS)  # type: ignore[arg-type]
    assert guard.command is None or guard.command.escape != "climb held"


def test_the_fallback_keeps_the_nearest_tracks_planes() -> None:
    """A crowd with no admissible velocity: the planes of the nearest tracks (as many as can be met together)
    stay hard and only the farther ones are violated; they used to be violated all alike, and in encounter case
    142 two vehicles, each in its fallback from others, converged to 8.2 m."""
    layer = ReactiveLayer(3)
    own = (0.0, 0.0, -15.0)
    near = uav(10, (0.0, 16.0, -15.0), (0.0, -4.0, 0.0))  # close, closing
    far = [uav(k + 20, (26.0 * math.cos(a), 26.0 * math.sin(a), -15.0), (-7.0 * math.cos(a), -7.0 * math.sin(a),
           0.0)) for k, a in enumerate(np.arange(7) * 2.0 * math.pi / 7 + 0.3)]  # fmt: skip
    stack = [uav(40, (0.0, 0.0, -23.0), (0.0, 0.0, 3.0)), uav(41, (0.0, 0.0, -7.0), (0.0, 0.0, -3.0))]
    c = layer.solve(0, own, (0.0, 0.0, 0.0), (0.0, 5.0, 0.0), [*far, near, *stack], PARAMS, LIMITS, Phase.MISSION)
    assert c is not None and c.fallback
    out = np.array(c.vel_ned_m_s)
    rows = [r for r in range(OWN_ROWS, OWN_ROWS + 10) if layer._rows[int(layer._index[r])] is near]
    assert rows, "the near track has a plane"
    slack = float(layer._normals[rows[0]] @ out - layer._offsets[rows[0]])
    assert slack >= -1e-6, slack


def test_the_fallback_keeps_a_uavs_plane_before_a_manned_aircrafts() -> None:
    """At the floor, a helicopter 200 m off at 26 m (nearer in its 150 m volume's measure than the UAV 16 m off in
    its 10 m one) and a UAV closing: no velocity meets both planes. The UAV's stays hard and the manned one's is
    given up: it used to be the other way, and in the failure search of the depot with a helicopter (case 3) two
    vehicles fleeing it at the floor, each giving up the other's plane, came within 3.5 m."""
    layer = ReactiveLayer(4)
    own, still = (0.0, 0.0, -2.2), (0.0, 0.0, 0.0)
    helicopter = TrafficTrack(TrafficSource.MANNED, 0xABC, "HELI1", (-190.0, -80.0, -26.0), (0.0, 40.0, 0.0), 0)
    closing = uav(2, (16.0, 0.0, -2.5), (-6.0, 0.0, 0.0))
    c = layer.solve(0, own, still, still, [helicopter, closing], PARAMS, LIMITS, Phase.MISSION)
    assert c is not None and c.fallback
    out = np.array(c.vel_ned_m_s)
    slack = {layer._rows[int(layer._index[r])].name: float(layer._normals[r] @ out - layer._offsets[r])
             for r in range(OWN_ROWS, OWN_ROWS + 2)}  # fmt: skip
    assert slack["UAV 2"] >= -1e-6 and slack["HELI1"] < 0.0, slack
    assert out[0] < 0.0  # not toward the UAV


@pytest.mark.parametrize("speed_m_s", [2.0, 10.0])
def test_inside_the_sphere_the_plane_moves_apart_and_never_through(speed_m_s: float) -> None:
    """Already inside the grown sphere (6 m from another vehicle, closing head-on): the plane asks both to move
    apart along the line of centres. It used to ask only to be outside the sphere after RECOVER_S, which a closing
    speed above radius / RECOVER_S met by flying on through the other: in search case 3 (the depot, a helicopter)
    a vehicle at 10.6 m/s flew into another at 2.4 m above the ground."""
    a, b = ReactiveLayer(1), ReactiveLayer(2)
    pa, pb, va, vb = (0.0, 0.0, -15.0), (0.0, -6.0, -15.0), (0.0, -speed_m_s, 0.0), (0.0, 5.0, 0.0)
    ca = a.solve(0, pa, va, va, [uav(2, pb, vb)], PARAMS, LIMITS, Phase.MISSION)
    cb = b.solve(0, pb, vb, vb, [uav(1, pa, va)], PARAMS, LIMITS, Phase.MISSION)
    assert ca is not None and cb is not None and not ca.fallback and not cb.fallback
    # a is east of b: a's east velocity minus b's is the rate they move apart, and both share it
    apart = ca.vel_ned_m_s[1] - cb.vel_ned_m_s[1]
    assert apart > 0.5, (ca, cb)
    assert ca.vel_ned_m_s[1] > -0.1 and cb.vel_ned_m_s[1] < 0.1  # neither goes on toward the other


def _landing_guard() -> tuple[TrafficGuard, HomeFrame]:
    guard = TrafficGuard(ParamStore(all_param_specs()), 1)
    guard.land_spot_ned_m = (0.0, 0.0, 0.0)
    return guard, HomeFrame(GeoPoint(47.3977, 8.5456, 488.0))


def test_a_departure_hold_ends_only_after_the_column_has_been_clear_a_while() -> None:
    """Encounter case 625: a track at the edge of the climb-out column, its prediction flipping in and out of it
    with its noise every few solves: the hold stays (the motors stay at idle on the pad) until the column has
    been clear DEPARTURE_CLEAR_US, then the take-off goes (it used to be released and held again every 0.25-0.5 s,
    the motors stepping between idle and hover a few centimetres up, and the vehicle tipped 19 degrees)."""
    params = ParamStore(all_param_specs())
    frame = HomeFrame(GeoPoint(47.3977, 8.5456, 488.0))
    crossing = uav(2, (-60.0, 0.0, -15.0), (4.0, 0.0, 0.0))  # through the column in 15 s
    aside = uav(2, (-60.0, 40.0, -15.0), (4.0, 0.0, 0.0))  # the same, 40 m east: clear
    guard = _departed_here(params, frame)
    pad, climb = (0.0, 0.0, -0.05), (0.0, 0.0, -1.5)
    released_us = None
    for k in range(200):  # 4 s of solves: 1 s with the track flipping, then clear
        t_us = k * 20_000
        track = crossing if t_us < 1_000_000 and k % 12 < 4 else aside
        guard.step(t_us, 0.004, frame, pad, (0.0, 0.0, 0.0), pad, climb, FlightMode.AUTO_MISSION, False,
                   _Table([track]), PARAMS)  # type: ignore[arg-type]  # fmt: skip
        if released_us is None and not guard.holding_takeoff:
            released_us = t_us
            assert k > 0  # held at once
    last_seen_us = max(k * 20_000 for k in range(50) if k % 12 < 4)
    assert released_us is not None and released_us >= last_seen_us + DEPARTURE_CLEAR_US
    assert released_us <= last_seen_us + DEPARTURE_CLEAR_US + 40_000
    assert [t.text for t in guard.texts] == ["Traffic: take-off held for UAV 2"]


def test_a_landing_waits_beside_a_pad_with_a_vehicle_on_it() -> None:
    """Ring swap: the pad a vehicle lands on is another's home, whose take-off is held. While that one stands on the
    spot, the landing waits level beside the pad (out of its climb-out column), said once; a vehicle there only
    passing by, or one already above, holds nothing. Encounter case 168: it used to land 2 m from the other (their
    rotors touched on the ground)."""
    over, descend = (0.0, 0.0, -15.0), (0.0, 0.0, 1.5)
    parked = uav(5, (0.5, -0.3, 0.0), (0.0, 0.0, 0.0))
    guard, frame = _landing_guard()
    for k in range(5):
        guard.step(k * 20_000, 0.02, frame, over, (0.0, 0.0, 0.0), over, descend, FlightMode.AUTO_MISSION, True,
                   _Table([parked]), PARAMS)  # type: ignore[arg-type]  # fmt: skip
    assert guard.command is not None and guard.command.escape == "landing held beside the pad"
    v = guard.command.vel_ned_m_s
    assert v[2] <= 0.0 and math.hypot(v[0], v[1]) > 1.0  # no descent; moving aside
    assert [t.text for t in guard.texts] == ["Traffic: landing held beside the pad, UAV 5 on it or over it"]
    # aside, 2 volumes out: it stays there (level, not drifting back over the pad)
    d = PAD_ASIDE_VOLUMES * PARAMS.uav.grown(PARAMS.margin).hor_m
    aside = (0.5 - 0.8 * d, -0.3 + 0.6 * d, -15.0)
    guard.step(200_000, 0.02, frame, aside, (0.0, 0.0, 0.0), aside, (0.0, 0.0, 0.0), FlightMode.AUTO_MISSION, True,
               _Table([parked]), PARAMS)  # type: ignore[arg-type]  # fmt: skip
    assert guard.command is not None and guard.command.escape == "landing held beside the pad"
    assert all(abs(c) < 0.5 for c in guard.command.vel_ned_m_s)
    # pushed low while waiting, it climbs back to PAD_HOLD_AGL_M and is not released as a committed landing
    low = (aside[0], aside[1], -1.5)
    guard.step(400_000, 0.02, frame, low, (0.0, 0.0, 0.0), low, (0.0, 0.0, 0.0), FlightMode.AUTO_MISSION, True,
               _Table([parked]), PARAMS)  # type: ignore[arg-type]  # fmt: skip
    assert guard.command is not None and guard.command.vel_ned_m_s[2] < 0.0
    for track in (uav(6, (0.0, 0.0, 0.0), (0.0, 5.0, 0.0)), uav(7, (0.0, 0.0, -25.0), (0.0, 0.0, 0.0))):
        guard, frame = _landing_guard()
        guard.step(0, 0.02, frame, over, (0.0, 0.0, 0.0), over, descend, FlightMode.AUTO_MISSION, True,
                   _Table([track]), PARAMS)  # type: ignore[arg-type]  # fmt: skip
        assert guard.command is None or guard.command.escape != "landing held beside the pad", track


def test_a_landing_pushed_off_its_spot_is_no_committed_landing() -> None:
    """A landing vehicle pushed 20 m aside (by a helicopter's plane) and low: not over its spot, so it is no committed
    landing and no pad: it keeps the altitude floor (no descent under it) and moves aside from a vehicle coming at
    it. Over the spot at the same height it touches down. Encounter case 84: released at 1.7 m, 45 m from its pad,
    it flew back at that height through another vehicle's escape (9.1 m)."""
    low = (20.0, 0.0, -1.5)
    other = uav(2, (20.0, 14.0, -1.8), (0.0, -6.0, 0.0))
    guard, frame = _landing_guard()
    guard.step(0, 0.02, frame, low, (0.0, 0.0, 0.5), low, (0.0, 0.0, 0.8), FlightMode.AUTO_MISSION, True,
               _Table([other]), PARAMS)  # type: ignore[arg-type]  # fmt: skip
    assert guard.command is not None and not guard.over_spot(frame, low)
    v = guard.command.vel_ned_m_s
    assert v[2] <= 1e-9 and math.hypot(v[0], v[1]) > 0.5, v  # no descent under the floor; aside (no ground lock)
    over = (0.0, 0.0, -1.5)
    guard, frame = _landing_guard()
    guard.step(0, 0.02, frame, over, (0.0, 0.0, 0.5), over, (0.0, 0.0, 0.8), FlightMode.AUTO_MISSION, True,
               _Table([uav(2, (0.0, 14.0, -1.8), (0.0, -6.0, 0.0))]), PARAMS)  # type: ignore[arg-type]  # fmt: skip
    assert guard.command is None and guard.over_spot(frame, over)


def test_an_engaged_guard_never_flies_toward_the_fence() -> None:
    """While the reactive layer is engaged its preference is the velocity it flew (the reference goes on from it):
    when no track binds it flew that preference as it was, fence or not, and in encounter case 178 a vehicle
    running from a helicopter's NMAC volume crossed a 300 m fence by 2 m. Now what it flies keeps the fence."""
    params = ParamStore(all_param_specs())
    guard = TrafficGuard(params, 1)
    guard.fences = (CircleZone((0.0, 0.0), 300.0, True),)
    frame = HomeFrame(GeoPoint(47.3977, 8.5456, 488.0))
    fast = (8.0, 0.0, 0.0)
    close = uav(2, (292.0, 20.0, -40.0), (0.0, -6.0, 0.0))  # closing from the side: the layer engages
    guard.step(0, 0.02, frame, (280.0, 0.0, -40.0), fast, (280.0, 0.0, -40.0), fast, FlightMode.AUTO_MISSION,
               False, _Table([close]), PARAMS)  # type: ignore[arg-type]  # fmt: skip
    assert guard.engaged
    gone = uav(2, (200.0, -200.0, -40.0), (0.0, -6.0, 0.0))  # no plane binds any more
    at = (295.0, 0.0, -40.0)  # 5 m from the edge, still engaged (MIN_ENGAGED_US)
    later = _Table([gone])
    later.version = 2
    guard.step(40_000, 0.02, frame, at, fast, at, fast, FlightMode.AUTO_MISSION, False, later, PARAMS)  # type: ignore[arg-type]
    assert guard.engaged and guard.command is not None
    assert guard.command.vel_ned_m_s[0] <= 1e-3, guard.command  # not toward the edge any more (8 m/s before)


def test_the_velocity_on_its_way_to_a_command_keeps_the_fence() -> None:
    """The velocity flown slews toward the command at the acceleration limit per axis; each command keeps the
    fence, but the way between two need not (a reversal along the fence passes through outward velocities): in the
    failure search of the depot with a helicopter (case 0) a vehicle went 9.6 m past a 300 m fence that way. What
    is flown now keeps the fence rows on the way too."""
    guard = TrafficGuard(ParamStore(all_param_specs()), 1)
    guard.fences = (CircleZone((0.0, 0.0), 300.0, True),)
    frame = HomeFrame(GeoPoint(47.3977, 8.5456, 488.0))
    at, along = (296.0, 0.0, -40.0), (0.0, 10.0, 0.0)  # 4 m from the edge: at most 0.5 m/s outward
    close = uav(2, (296.0, 25.0, -40.0), (0.0, -6.0, 0.0))  # ahead along the fence, closing: the layer engages
    table = _Table([close])
    guard.step(0, 0.02, frame, at, along, at, along, FlightMode.AUTO_MISSION, False, table, PARAMS)  # type: ignore[arg-type]
    assert guard.engaged
    guard._vel = [6.0, 10.0, 0.0]  # outward, left over from the slew toward another command
    out = guard.step(20_000, 0.02, frame, at, along, at, along, FlightMode.AUTO_MISSION, False, table, PARAMS)  # type: ignore[arg-type]
    assert out is not None and out.vel_ned_m_s[0] <= 0.5 + 1e-6, out
