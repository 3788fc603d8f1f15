"""Routing benchmark (SPEC §7, §11; issue 13): seeded worlds with fences and obstacles across delivery routes.

Each world is a delivery route (home + 2-3 waypoints, ~100-160 m) with exclusion circles and polygons placed
*across* its legs, an inclusion boundary (circle or polygon) around it and 4-10 obstacles (columns, boxes,
spheres) near the legs and the fence-routed path. Every world is checked at upload like the autopilot does
(:func:`autopilot.mission.feasibility.check_feasibility`): a mission with no route is *refused with a
reason* (counted, never flown). The others are flown in-process with the autopilot's own parts: the
:class:`MissionRouter` (route on the known world: fences, and tracked obstacles after a HOLD), the reactive
:class:`AvoidancePlanner` (Bézier detours for what is newly sensed) and the sim's :class:`ObstacleSensor`,
glued as :func:`fly_mission` does (the navigator's route logic), on a point-mass follower (PD on the reference
plus its acceleration feed-forward, the gains below; the planner tests fly the same). The worlds are drawn in
order from one seeded generator, then flown one task per world on the campaign engine
(:func:`tools.campaign.engine.run_tasks`, ``--workers`` / ``--scheduler`` of ``tools.benchmarks``): results in
world order, the same numbers whatever the number of workers.

Worlds are flyable by construction where it matters: an obstacle is only added when the route still exists
with every obstacle known (inflated by R_safe + 1 m), so a world that ends stuck is the planners' failure.

Keys (prefix ``route_``): ``worlds``, ``refused`` (at upload, with a reason), ``collisions``,
``fence_breaches`` (entries into an exclusion zone or out of the inclusion fence), ``stuck`` (neither
completed nor refused), ``completed_pct`` (of the flown), ``min_clearance_m``, ``path_overhead_pct`` (flown
length over the shortest route with every obstacle known), ``items_bypassed`` (split into
``items_bypassed_unreachable``: inside a real obstacle's safety volume or the fence margin, and
``items_bypassed_reachable``, which must be 0: a reachable waypoint is reached), ``local_plan_p99_ms``
(reactive detour searches), ``known_plan_p99_ms`` (route searches on the known world), thread CPU time.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np

from autopilot.estimation import VehicleState
from autopilot.geofence.fence import CircleZone, Geofence, PolygonZone, circle_fence_items, polygon_fence_items
from autopilot.navigation import HomeFrame, Navigator
from autopilot.param_schema import make_param_store
from autopilot.planner.param_decls import PlannerParams
from autopilot.planner.planner import AvoidancePlanner
from autopilot.planner.route_graph import KnownWorld, ObstacleDisc
from mavlink_bridge.contract.frames import GeoPoint, LocalNedFrame, quat_from_euler
from mavlink_bridge.contract.mav_enums import MavCmd, MavFrame, MissionState
from mavlink_bridge.contract.vehicle_api import FlightMode, MissionItem, MissionResult, MissionType
from sim.obstacle_sensor import ObstacleSensor
from sim.world import Box, Cylinder, Sphere, WindConfig, World, empty_world
from tools.benchmarks import BenchResult
from tools.campaign.engine import run_tasks

#: Seed of the benchmark's world sequence (world i is the i-th of it, flown with sensor seed i).
WORLD_SEED = 20261123
#: Follower gains (1/s², 1/s) and limits: stiffer and more agile than the planner's limits.
KP_POS = 4.0
KD_VEL = 4.0
VEHICLE_ACC_MAX_M_S2 = 6.0
ACCEPT_RADIUS_M = 1.5
#: Cruise speed of the follower (m/s; the navigator's targets ask for MIS_CRUISE_SPD, capped here).
CRUISE_M_S = 5.0
#: Worlds flown by ``make bench`` (and by ``--quick``).
FULL_WORLDS = 500
QUICK_WORLDS = 40


@dataclass(frozen=True, slots=True)
class RoutingWorld:
    """One benchmark world: the mission's points (row 0 = after takeoff over home), the fence, the obstacles."""

    world: World
    waypoints_ned: np.ndarray
    fence: Geofence


@dataclass(frozen=True, slots=True)
class MissionFlight:
    """One flown (or refused) mission."""

    refused: str  # the upload refusal ("" when flown)
    collisions: int
    fence_breaches: int
    completed: bool
    min_clearance_m: float
    path_length_m: float
    best_length_m: float  # the shortest route with every obstacle known
    items_bypassed: int
    local_plan_s: tuple[float, ...]
    known_plan_s: tuple[float, ...]
    texts: tuple[str, ...]
    end_state: str
    #: bypassed waypoints that were reachable in truth: outside every obstacle's safety volume (CA_RSAFE_M from the
    #: world's surfaces) and the fence margin (CA_FENCE_MARG_M); the rest of ``items_bypassed`` were unreachable
    items_bypassed_reachable: int = 0


def _obstacle_disc(obs: Sphere | Cylinder | Box, r_extra_m: float) -> ObstacleDisc:
    """A world obstacle as a column the route planner can check (circumscribed radius)."""
    if isinstance(obs, Sphere):
        return ObstacleDisc((obs.north_m, obs.east_m), obs.radius_m + r_extra_m, obs.alt_m - obs.radius_m,
                            obs.alt_m + obs.radius_m)  # fmt: skip
    if isinstance(obs, Cylinder):
        return ObstacleDisc((obs.north_m, obs.east_m), obs.radius_m + r_extra_m, -math.inf, obs.height_m)
    half = 0.5 * math.hypot(obs.size_m[0], obs.size_m[1])
    return ObstacleDisc((obs.north_m, obs.east_m), half + r_extra_m, -math.inf, obs.size_m[2])


def _legs_routable(world: KnownWorld, wps: np.ndarray) -> bool:
    return all(world.route(wps[i], wps[i + 1]).ok for i in range(len(wps) - 1))


def random_world(rng: np.random.Generator, params: PlannerParams) -> RoutingWorld:
    """A delivery route with fences across it and obstacles near it (module docstring)."""
    alt = float(rng.uniform(8.0, 15.0))
    heading = float(rng.uniform(0, 2 * math.pi))
    pts = [np.array((0.0, 0.0, -alt))]
    for _ in range(int(rng.integers(2, 4))):
        heading += float(rng.uniform(-0.9, 0.9))
        leg = float(rng.uniform(40.0, 60.0))
        nxt = pts[-1] + np.array((math.cos(heading) * leg, math.sin(heading) * leg, float(rng.uniform(-2.0, 2.0))))
        nxt[2] = min(nxt[2], -6.0)
        pts.append(nxt)
    wps = np.array(pts)
    keep_m = params.fence_margin_m + 4.0  # no zone within this of a waypoint or home
    zones: list[CircleZone | PolygonZone] = []
    for _ in range(int(rng.integers(1, 4))):
        leg = int(rng.integers(0, len(wps) - 1))
        a, b = wps[leg, :2], wps[leg + 1, :2]
        c = a + float(rng.uniform(0.35, 0.65)) * (b - a)
        d = (b - a) / max(float(np.linalg.norm(b - a)), 1e-9)
        lateral = np.array((-d[1], d[0]))
        c = c + lateral * float(rng.uniform(-4.0, 4.0))
        if rng.random() < 0.5:
            zone: CircleZone | PolygonZone = CircleZone(
                (float(c[0]), float(c[1])), float(rng.uniform(5.0, 12.0)), False
            )
        else:  # a no-fly corridor (rotated rectangle) across the leg
            half_len, half_w = float(rng.uniform(8.0, 25.0)), float(rng.uniform(2.0, 6.0))
            corners = [c + lateral * sl * half_len + d * sw * half_w for sl, sw in ((-1, -1), (1, -1), (1, 1), (-1, 1))]
            zone = PolygonZone(tuple((float(p[0]), float(p[1])) for p in corners), False)
        if all(zone.boundary_distance_m(p) >= keep_m and not zone.contains(p) for p in wps):
            zones.append(zone)
    reach = float(np.max(np.hypot(wps[:, 0], wps[:, 1]))) + float(rng.uniform(25.0, 60.0))
    if rng.random() < 0.5:
        zones.append(CircleZone((0.0, 0.0), reach, True))
    else:
        k = np.arange(8) * (2 * math.pi / 8) + float(rng.uniform(0, 1))
        r = reach / math.cos(math.pi / 8)
        zones.append(PolygonZone(tuple((float(r * math.cos(t)), float(r * math.sin(t))) for t in k), True))
    fence = Geofence(tuple(zones))
    r_extra = params.r_safe_m + 1.0
    obstacles: list[Sphere | Cylinder | Box] = []
    discs: list[ObstacleDisc] = []
    fence_world = KnownWorld(fence, params.fence_margin_m)
    paths = [fence_world.route(wps[i], wps[i + 1]).path_ned_m for i in range(len(wps) - 1)]
    polyline = np.concatenate([p for p in paths if p is not None]) if all(p is not None for p in paths) else wps
    tries = 0
    while len(obstacles) < int(rng.integers(4, 11)) and tries < 60:
        tries += 1
        seg = int(rng.integers(0, len(polyline) - 1))
        a, b = polyline[seg], polyline[seg + 1]
        d = b - a
        if float(np.hypot(d[0], d[1])) < 1.0:
            continue
        lateral = np.array((-d[1], d[0], 0.0)) / float(np.hypot(d[0], d[1]))
        c = a + float(rng.uniform(0.1, 0.9)) * d + lateral * float(rng.uniform(-5.0, 5.0))
        kind = rng.choice(3, p=(0.4, 0.3, 0.3))
        if kind == 0:
            obs: Sphere | Cylinder | Box = Cylinder(float(c[0]), float(c[1]), float(rng.uniform(1.0, 3.5)),
                                                    float(rng.uniform(15.0, 40.0)))  # fmt: skip
        elif kind == 1:
            size = (float(rng.uniform(3.0, 8.0)), float(rng.uniform(3.0, 8.0)), float(rng.uniform(15.0, 40.0)))
            obs = Box(float(c[0]), float(c[1]), size, float(rng.uniform(-90.0, 90.0)))
        else:
            obs = Sphere(float(c[0]), float(c[1]), float(-c[2] + rng.uniform(-3.0, 3.0)), float(rng.uniform(1.0, 3.0)))
        if float(obs.distance_m(wps).min()) < params.r_safe_m + 6.0:
            continue
        disc = _obstacle_disc(obs, r_extra)
        if not _legs_routable(KnownWorld(fence, params.fence_margin_m, (*discs, disc)), wps):
            continue  # would close every route: kept out so a stuck flight is the planners' failure
        obstacles.append(obs)
        discs.append(disc)
    world = World(home=empty_world().home, obstacles=tuple(obstacles), wind=WindConfig(), payload_kg=0.0)
    return RoutingWorld(world, wps, fence)


def mission_uploads(rw: RoutingWorld, home: GeoPoint) -> tuple[list[MissionItem], list[MissionItem]]:
    """The world's mission (a waypoint per point after the first, accepted within ACCEPT_RADIUS_M) and its
    fence, as the MISSION and FENCE items a ground station uploads."""
    frame = LocalNedFrame(home)
    rel = int(MavFrame.GLOBAL_RELATIVE_ALT)
    items = []
    for seq, (n, e, d) in enumerate(rw.waypoints_ned[1:].tolist()):
        g = frame.geodetic_from_ned(n, e, 0.0)
        items.append(MissionItem(seq, int(MavCmd.NAV_WAYPOINT), rel, 0.0, ACCEPT_RADIUS_M, 0.0, math.nan,
                                 g.lat_deg, g.lon_deg, -d))  # fmt: skip
    fence: list[MissionItem] = []
    for zone in rw.fence.zones:
        if isinstance(zone, CircleZone):
            g = frame.geodetic_from_ned(zone.center_ne_m[0], zone.center_ne_m[1], 0.0)
            fence += circle_fence_items(len(fence), g.lat_deg, g.lon_deg, zone.radius_m, inclusion=zone.inclusion)
        else:
            pts = [frame.geodetic_from_ned(n, e, 0.0) for n, e in zone.vertices_ne_m]
            fence += polygon_fence_items(len(fence), [(g.lat_deg, g.lon_deg) for g in pts], inclusion=zone.inclusion)
    return items, fence


def fly_mission(
    rw: RoutingWorld,
    params: PlannerParams | None = None,
    *,
    seed: int = 0,
    dt_s: float = 0.04,
) -> MissionFlight:
    """Fly one world's mission with the autopilot's :class:`Navigator` in the loop (module docstring).

    The mission and the fence are uploaded *before* home is known (as a ground station syncing on connect),
    then home is set: a mission the navigator finds infeasible is refused with its reason and not flown.
    """
    store = make_param_store()
    if params is not None:
        for name, value in _planner_param_values(params).items():
            store.set(name, value)
    planner_params = PlannerParams.from_store(store)
    wps = rw.waypoints_ned
    best = KnownWorld(rw.fence, planner_params.fence_margin_m,
                      [_obstacle_disc(o, planner_params.r_safe_m) for o in rw.world.obstacles])  # fmt: skip
    best_len = sum(best.route(wps[i], wps[i + 1]).length_m for i in range(len(wps) - 1))
    home = rw.world.home
    nav = Navigator(store, AvoidancePlanner(planner_params))
    items, fence = mission_uploads(rw, home)
    answers = (nav.replace_mission(MissionType.FENCE, fence), nav.replace_mission(MissionType.MISSION, items))
    refused = [r for r in answers if r[0] is not MissionResult.ACCEPTED]
    nav.set_home(HomeFrame(home))
    reason = refused[0][1] if refused else nav.uploads.mission_issue
    if reason:
        return MissionFlight(reason, 0, 0, False, math.inf, 0.0, best_len, 0, (), (), (), "refused")
    sensor = ObstacleSensor(rw.world, seed=seed)
    nav.start_mission(0)
    max_time_s = 4.0 * best_len / CRUISE_M_S + 60.0
    pos, vel = wps[0].copy(), np.zeros(3)
    yaw = math.atan2(wps[1, 1] - wps[0, 1], wps[1, 0] - wps[0, 0])
    sensor_every = max(1, round(1.0 / (sensor.config.rate_hz * dt_s)))
    collisions = breaches = 0
    inside = breached = False
    min_clear = math.inf
    path_len = 0.0
    local_t: list[float] = []
    known_t: list[float] = []
    texts: list[str] = []
    end = "timeout"
    zero3 = (0.0, 0.0, 0.0)
    for k in range(int(max_time_s / dt_s)):
        time_us = round(k * dt_s * 1e6)
        q = quat_from_euler(0.0, 0.0, yaw)
        dets = sensor.detect(pos, q, time_us) if k % sensor_every == 0 else ()
        p = pos.tolist()
        v = vel.tolist()
        state = VehicleState(time_us, (p[0], p[1], p[2]), (v[0], v[1], v[2]), q, zero3, 0.0, 0.0, yaw,
                             home.lat_deg, home.lon_deg, home.alt_amsl_m, 3, 12, 0.5, 0.5, True)  # fmt: skip
        t0 = time.thread_time()
        out = nav.update(state, FlightMode.AUTO_MISSION, False, dets)
        dt_cpu = time.thread_time() - t0
        step = nav.routing.step
        if step is not None and step.planned:
            known_t.append(dt_cpu)
        if out.failsafe is not None:
            texts.append(out.failsafe.message)
            end = "no_route_action"
            break
        if nav.mission_state is MissionState.COMPLETE:
            end = "completed"
            break
        target = out.mission_target
        if target is None:
            continue
        t0 = time.thread_time()
        override = nav.avoid(state, target)
        if getattr(nav.planner_output, "replanned", False):
            local_t.append(time.thread_time() - t0)
        if override is not None:
            sp_p, sp_v, sp_a = (np.array(x) for x in (override.pos_ned_m, override.vel_ned_m_s, override.acc_ned_m_s2))
            acc = sp_a + KP_POS * (sp_p - pos) + KD_VEL * (sp_v - vel)
        else:
            to_goal = np.array(target.pos_ned_m) - pos
            dist = float(np.linalg.norm(to_goal))
            v_mag = min(CRUISE_M_S, math.sqrt(2.0 * 0.5 * planner_params.a_max_m_s2 * dist))
            acc = KD_VEL * (to_goal / max(dist, 1e-9) * v_mag - vel)
        norm = float(np.linalg.norm(acc))
        if norm > VEHICLE_ACC_MAX_M_S2:
            acc *= VEHICLE_ACC_MAX_M_S2 / norm
        vel = vel + acc * dt_s
        move = vel * dt_s
        pos = pos + move
        path_len += float(np.linalg.norm(move))
        if not math.isnan(target.yaw_rad):
            yaw = target.yaw_rad
        clear = float(rw.world.clearance_m(pos)[0]) if rw.world.obstacles else math.inf
        min_clear = min(min_clear, clear)
        collisions += clear < 0.0 and not inside
        inside = clear < 0.0
        out_of_fence = rw.fence.violates(pos)
        if out_of_fence and not breached:  # for the report: where and in which state
            where = np.round(pos, 1).tolist()
            route = step.status.name if step is not None else "-"
            texts.append(f"breach at {where}: planner {getattr(nav.planner_output, 'state', None)}, route {route}")
        breaches += out_of_fence and not breached
        breached = out_of_fence
    texts += [t.text for t in nav.drain_texts()]
    ok = sum(_reachable_in_truth(rw, wps[seq + 1], planner_params) for seq in set(nav.bypassed_seqs))
    return MissionFlight("", collisions, breaches, end == "completed", min_clear, path_len, best_len,
                         len(nav.bypassed_seqs), tuple(local_t), tuple(known_t), tuple(texts), end, ok)  # fmt: skip


def _reachable_in_truth(rw: RoutingWorld, wp_ned: np.ndarray, params: PlannerParams) -> bool:
    """The waypoint lies outside every real obstacle's safety volume and the fence margin (SPEC §7: it must be
    reached, never bypassed)."""
    clear = float(rw.world.clearance_m(wp_ned)[0]) if rw.world.obstacles else math.inf
    return clear >= params.r_safe_m and not rw.fence.violates(wp_ned, params.fence_margin_m)


def _planner_param_values(params: PlannerParams) -> dict[str, float]:
    """The CA_* values of ``params`` that differ from the defaults."""
    names = {"r_safe_m": "CA_RSAFE_M", "fence_margin_m": "CA_FENCE_MARG_M", "noroute_t_s": "CA_NOROUTE_T"}
    default = PlannerParams()
    return {n: float(getattr(params, f)) for f, n in names.items() if getattr(params, f) != getattr(default, f)}


def benchmark_worlds(n: int, params: PlannerParams) -> list[RoutingWorld]:
    rng = np.random.default_rng(WORLD_SEED)
    return [random_world(rng, params) for _ in range(n)]


def fly_world(case: tuple[RoutingWorld, PlannerParams, int]) -> MissionFlight:
    """One Monte Carlo case on the campaign engine: ``(world, planner params, sensor seed)`` -> its flight."""
    rw, params, seed = case
    return fly_mission(rw, params, seed=seed)


def monte_carlo(
    n: int, params: PlannerParams, *, workers: int | None = None, scheduler: str | None = None
) -> list[MissionFlight]:
    """The first ``n`` benchmark worlds flown on the campaign engine (world i with sensor seed i), in world order:
    the same flights whatever the number of workers."""
    cases = [(rw, params, i) for i, rw in enumerate(benchmark_worlds(n, params))]
    return run_tasks(fly_world, cases, workers=workers, scheduler=scheduler, key="routing-world")


def run(quick: bool, *, workers: int | None = None, scheduler: str | None = None) -> list[BenchResult]:
    """Monte Carlo over seeded worlds (FULL_WORLDS, or QUICK_WORLDS with ``quick``) on the campaign engine."""
    params = PlannerParams()
    n = QUICK_WORLDS if quick else FULL_WORLDS
    flights = monte_carlo(n, params, workers=workers, scheduler=scheduler)
    flown = [f for f in flights if not f.refused]
    done = [f for f in flown if f.completed]
    local_ms = np.array([t for f in flown for t in f.local_plan_s]) * 1e3
    known_ms = np.array([t for f in flown for t in f.known_plan_s]) * 1e3
    collisions = sum(f.collisions for f in flown)
    breaches = sum(f.fence_breaches for f in flown)
    stuck = len(flown) - len(done)
    overhead = 100.0 * float(np.mean([f.path_length_m / f.best_length_m - 1.0 for f in done])) if done else math.nan
    local_p99 = float(np.percentile(local_ms, 99)) if len(local_ms) else 0.0
    known_p99 = float(np.percentile(known_ms, 99)) if len(known_ms) else 0.0
    min_clear = min((f.min_clearance_m for f in flown), default=math.inf)
    floor = params.r_safe_m - params.track_tol_m
    bypassed = sum(f.items_bypassed for f in flown)
    bypassed_reachable = sum(f.items_bypassed_reachable for f in flown)
    return [
        BenchResult("route_worlds", float(n), note="seeded worlds: fences across the route + obstacles"),
        BenchResult("route_refused", float(n - len(flown)), note="refused at upload with a reason"),
        BenchResult("avoid_collisions", float(collisions), "== 0", collisions == 0),
        BenchResult("route_fence_breaches", float(breaches), "== 0", breaches == 0),
        BenchResult("route_stuck", float(stuck), "== 0", stuck == 0, "flown, not completed"),
        BenchResult("route_completed_pct", 100.0 * len(done) / max(len(flown), 1), note="of the flown"),
        BenchResult("avoid_min_clearance_m", min_clear, f">= {floor:g}", min_clear >= floor, "R_safe - track tol"),
        BenchResult("route_path_overhead_pct", overhead, note="vs shortest route with every obstacle known"),
        BenchResult("route_items_bypassed", float(bypassed), note="waypoints flown around, not reached"),
        BenchResult(
            "route_items_bypassed_unreachable",
            float(bypassed - bypassed_reachable),
            note="inside a safety volume or the fence margin",
        ),
        BenchResult(
            "route_items_bypassed_reachable",
            float(bypassed_reachable),
            "== 0",
            bypassed_reachable == 0,
            "clear of every safety volume and the fence margin",
        ),
        BenchResult("plan_p99_ms", local_p99, "<= 5", local_p99 <= 5.0, "reactive detour searches"),
        BenchResult("route_known_plan_p99_ms", known_p99, "<= 50", known_p99 <= 50.0, "routes on the known world"),
        BenchResult("route_known_plans", float(len(known_ms)), note="route searches (legs, replans after HOLD)"),
    ]
