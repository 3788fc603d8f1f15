"""The avoidance planner on a point-mass follower: the planner's own closed loop, for planner tests.

The sim's :class:`ObstacleSensor` (stereo + ultrasonic, 10 Hz) feeds the autopilot's :class:`AvoidancePlanner`;
a point-mass follower with speed and acceleration limits (PD on the reference plus its acceleration
feed-forward) flies the route or the planner's detour. ``tests/autopilot/planner/test_planner_closed_loop.py`` uses
:func:`fly_route` and the seeded fields (:func:`random_field`, :func:`benchmark_fields`) to test the planner
alone. The shipped route glue (route ahead, rejoin skipping, nose heading) is the navigator's: the
``routing`` benchmark suite flies the autopilot's :class:`~autopilot.navigation.Navigator` over seeded worlds
with obstacles and fences and reports the avoidance keys (``avoid_collisions``, ``avoid_min_clearance_m``,
``plan_p99_ms``).
"""

from __future__ import annotations

import itertools
import math
import time
from collections.abc import Iterator, Sequence
from dataclasses import dataclass

import numpy as np

from autopilot.planner.geometry import FenceZone
from autopilot.planner.param_decls import PlannerParams
from autopilot.planner.planner import AvoidancePlanner, PlannerState
from mavlink_bridge.contract.frames import quat_from_euler
from sim.obstacle_sensor import ObstacleSensor, ObstacleSensorConfig
from sim.world import Box, Cylinder, Sphere, WindConfig, World, empty_world
from tools.benchmarks.routing import ACCEPT_RADIUS_M, KD_VEL, KP_POS, VEHICLE_ACC_MAX_M_S2  # the bench's follower

#: Closer than this to a waypoint, the nose turns to the next one (the camera looks around the corner).
LOOK_NEXT_WITHIN_M = 10.0
#: The route handed to the planner reaches at least this many look-ahead lengths past the current target
#: (a detour around an obstacle near the look-ahead horizon must find its rejoin point on it; dense expanded
#: patterns need many waypoints for that).
ROUTE_AHEAD_LOOKAHEADS = 2.0


@dataclass(frozen=True, slots=True)
class FlightResult:
    """One in-process flight: safety, efficiency and planner timing."""

    collisions: int  # entries into any obstacle
    min_clearance_m: float  # smallest true distance to any obstacle surface
    path_length_m: float
    route_length_m: float  # the obstacle-free route from the start
    completed: bool  # reached the last waypoint
    blocked: bool  # not completed and the planner was holding at the end (no safe detour found)
    sim_time_s: float
    plan_times_s: tuple[float, ...]  # CPU time of each planner update that ran a detour search
    update_times_s: tuple[float, ...]  # CPU time of every planner update
    decisions: tuple[str, ...]
    max_track_err_m: float  # follower vs detour reference


def fly_route(
    world: World,
    waypoints_ned: np.ndarray,
    params: PlannerParams | None = None,
    *,
    fences: Sequence[FenceZone] = (),
    sensor_config: ObstacleSensorConfig | None = None,
    seed: int = 0,
    speed_m_s: float = 5.0,
    dt_s: float = 0.04,
    max_time_s: float | None = None,
) -> FlightResult:
    """Fly ``waypoints_ned`` (first row = start) through ``world`` with the planner in the loop."""
    params = params or PlannerParams()
    sensor = ObstacleSensor(world, seed=seed, config=sensor_config)
    planner = AvoidancePlanner(params, fences=fences)
    wps = np.asarray(waypoints_ned, float)
    s_wps = np.concatenate(([0.0], np.cumsum(np.linalg.norm(np.diff(wps, axis=0), axis=1))))
    route_len = float(s_wps[-1])
    ahead_m = ROUTE_AHEAD_LOOKAHEADS * params.lookahead_m
    max_time_s = max_time_s or 3.0 * route_len / speed_m_s + 30.0
    pos, vel = wps[0].copy(), np.zeros(3)
    yaw = math.atan2(wps[1, 1] - wps[0, 1], wps[1, 0] - wps[0, 0])
    sensor_every = max(1, round(1.0 / (sensor.config.rate_hz * dt_s)))
    target_i = 1
    collisions, inside = 0, False
    min_clear = math.inf
    path_len = 0.0
    plan_t: list[float] = []
    upd_t: list[float] = []
    texts: list[str] = []
    track_err = 0.0
    steps = int(max_time_s / dt_s)
    k = 0
    for k in range(steps):
        time_us = round(k * dt_s * 1e6)
        q = quat_from_euler(0.0, 0.0, yaw)
        dets = sensor.detect(pos, q, time_us) if k % sensor_every == 0 else ()
        last_i = int(np.searchsorted(s_wps, s_wps[target_i] + ahead_m)) + 1
        nxt = wps[target_i + 1 : last_i] if target_i + 1 < len(wps) else None
        t0 = time.thread_time()
        out = planner.update(time_us, pos, vel, q, dets, wps[target_i], nxt)
        dt_cpu = time.thread_time() - t0
        upd_t.append(dt_cpu)
        if out.replanned:
            plan_t.append(dt_cpu)
        texts.extend(d.text for d in out.decisions)
        if out.rejoin_route_index:  # the detour rejoins a later leg: skip the waypoints it bypassed
            target_i = min(target_i + out.rejoin_route_index, len(wps) - 1)
        if out.setpoint is not None:
            sp_p, sp_v, sp_a = (
                np.array(x) for x in (out.setpoint.pos_ned_m, out.setpoint.vel_ned_m_s, out.setpoint.acc_ned_m_s2)
            )
            track_err = max(track_err, float(np.linalg.norm(sp_p - pos)))
            acc = sp_a + KP_POS * (sp_p - pos) + KD_VEL * (sp_v - vel)
        else:
            to_target = wps[target_i] - pos
            dist = float(np.linalg.norm(to_target))
            last = target_i == len(wps) - 1
            v_des_mag = min(speed_m_s, math.sqrt(2.0 * 0.5 * params.a_max_m_s2 * dist)) if last else speed_m_s
            v_des = to_target / max(dist, 1e-9) * v_des_mag
            acc = KD_VEL * (v_des - vel)
        norm = float(np.linalg.norm(acc))
        if norm > VEHICLE_ACC_MAX_M_S2:
            acc *= VEHICLE_ACC_MAX_M_S2 / norm
        vel = vel + acc * dt_s
        step = vel * dt_s
        pos = pos + step
        path_len += float(np.linalg.norm(step))
        look = _look_point(out.look_ahead_ned, pos, wps, target_i)
        if float(np.hypot(look[0] - pos[0], look[1] - pos[1])) > 0.5:
            yaw = math.atan2(look[1] - pos[1], look[0] - pos[0])
        clear = float(world.clearance_m(pos)[0]) if world.obstacles else math.inf
        min_clear = min(min_clear, clear)
        if clear < 0.0 and not inside:
            collisions += 1
        inside = clear < 0.0
        if float(np.linalg.norm(wps[target_i] - pos)) < ACCEPT_RADIUS_M:
            if target_i == len(wps) - 1:
                break
            target_i += 1
    completed = target_i == len(wps) - 1 and float(np.linalg.norm(wps[-1] - pos)) < ACCEPT_RADIUS_M
    return FlightResult(
        collisions,
        min_clear,
        path_len,
        route_len,
        completed,
        not completed and planner.state is PlannerState.HOLD,
        (k + 1) * dt_s,
        tuple(plan_t),
        tuple(upd_t),
        tuple(texts),
        track_err,
    )


def _look_point(detour_look: tuple[float, float, float] | None, pos: np.ndarray, wps: np.ndarray, i: int) -> np.ndarray:
    """Where the nose (camera) points: the detour's look-ahead, else the target, or the next one when close."""
    if detour_look is not None:
        return np.array(detour_look)
    if i + 1 < len(wps) and float(np.linalg.norm(wps[i] - pos)) < LOOK_NEXT_WITHIN_M:
        return wps[i + 1]
    return wps[i]


#: Lateral offset (m) of the free corridor kept beside every route leg, and its clear half-width beyond R_safe.
CORRIDOR_OFFSET_M = 12.0
CORRIDOR_CLEAR_M = 2.0


def corridor_polyline(wps: np.ndarray, sides: np.ndarray) -> np.ndarray:
    """The free corridor of a route: each leg offset ``CORRIDOR_OFFSET_M`` to its side (+1 right, -1 left),
    joined to the waypoints at both ends, sampled every metre."""
    pts = [wps[0]]
    for i, side in enumerate(sides):
        a, b = wps[i], wps[i + 1]
        d = b - a
        lateral = np.array((-d[1], d[0], 0.0)) / max(float(np.hypot(d[0], d[1])), 1e-9) * float(side)
        pts += [a + 0.1 * d + lateral * CORRIDOR_OFFSET_M, a + 0.9 * d + lateral * CORRIDOR_OFFSET_M, b]
    poly = np.array(pts)
    out = [poly[:1]]
    for a, b in itertools.pairwise(poly):
        n = max(1, math.ceil(float(np.linalg.norm(b - a))))
        out.append(a + (b - a) * (np.arange(1, n + 1) / n)[:, None])
    return np.concatenate(out)


def random_field(rng: np.random.Generator, r_keep_m: float) -> tuple[World, np.ndarray]:
    """A delivery route (start + 2-3 waypoints, ~120 m, 8-15 m altitude) with 6-12 obstacles near it.

    Obstacles never cover a waypoint or the start (kept ``r_keep_m`` away). Every field is flyable
    by construction: each leg keeps a free corridor on a random side (:func:`corridor_polyline`, the
    leg offset ``CORRIDOR_OFFSET_M`` sideways) that every obstacle clears by ``r_keep_m −
    6 + CORRIDOR_CLEAR_M`` (R_safe + 2 m with the benchmark's ``r_keep_m``); obstacles may still
    close every other gap, and the planner has to find that corridor (or one of its own).
    """
    alt = float(rng.uniform(8.0, 15.0))
    n_wp = int(rng.integers(2, 4))
    heading = float(rng.uniform(0, 2 * math.pi))
    pts = [np.array((0.0, 0.0, -alt))]
    for _ in range(n_wp):
        heading += float(rng.uniform(-0.8, 0.8))
        leg = float(rng.uniform(35.0, 55.0))
        step = np.array((math.cos(heading) * leg, math.sin(heading) * leg, -float(rng.uniform(-2.0, 2.0))))
        nxt = pts[-1] + step
        nxt[2] = min(nxt[2], -6.0)
        pts.append(nxt)
    wps = np.array(pts)
    corridor = corridor_polyline(wps, rng.choice((-1.0, 1.0), size=n_wp))
    corridor_clear_m = r_keep_m - 6.0 + CORRIDOR_CLEAR_M
    obstacles: list[Sphere | Cylinder | Box] = []
    tries = 0
    while len(obstacles) < int(rng.integers(6, 13)) and tries < 200:
        tries += 1
        leg = int(rng.integers(0, len(wps) - 1))
        a, b = wps[leg], wps[leg + 1]
        t = float(rng.uniform(0.15, 0.85))
        d = b - a
        lateral = np.array((-d[1], d[0], 0.0)) / max(float(np.hypot(d[0], d[1])), 1e-9)
        c = a + t * d + lateral * float(rng.uniform(-5.0, 5.0))
        kind = rng.choice(3, p=(0.4, 0.3, 0.3))
        if kind == 0:
            obs = Cylinder(float(c[0]), float(c[1]), float(rng.uniform(1.0, 3.5)), float(rng.uniform(15.0, 40.0)))
        elif kind == 1:
            size = (float(rng.uniform(3.0, 9.0)), float(rng.uniform(3.0, 9.0)), float(rng.uniform(15.0, 40.0)))
            obs = Box(float(c[0]), float(c[1]), size, float(rng.uniform(-90.0, 90.0)))
        else:
            obs = Sphere(float(c[0]), float(c[1]), float(-c[2] + rng.uniform(-3.0, 3.0)), float(rng.uniform(1.0, 3.0)))
        if float(obs.distance_m(wps).min()) < r_keep_m or float(obs.distance_m(corridor).min()) < corridor_clear_m:
            continue
        obstacles.append(obs)
    world = World(home=empty_world().home, obstacles=tuple(obstacles), wind=WindConfig(), payload_kg=0.0)
    return world, wps


#: Seed of the benchmark's field sequence (field i of a run is the i-th of it, flown with sensor seed i).
FIELD_SEED = 20240611


def benchmark_fields(n_fields: int, params: PlannerParams) -> Iterator[tuple[World, np.ndarray]]:
    """The benchmark's first ``n_fields`` random fields, in order (a quick run flies the first 30)."""
    rng = np.random.default_rng(FIELD_SEED)
    for _ in range(n_fields):
        yield random_field(rng, r_keep_m=params.r_safe_m + 6.0)
