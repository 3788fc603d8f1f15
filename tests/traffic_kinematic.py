"""A small kinematic closed loop for traffic-avoidance tests: point-mass "own ships", each running its own
:class:`TrafficAvoidance` (the strategic detour) and :class:`ReactiveLayer` on the others' 1 Hz reports: it flies
the velocity its reactive layer bounds (the detour's, else straight to its goal, or down when landing) with an
acceleration limit, among scripted straight-flying manned aircraft. A ship with ``land`` descends vertically to the
ground at its goal; separation counts while both ships are airborne (a ship on the ground is parked traffic)."""

from __future__ import annotations

import argparse
import math
from dataclasses import dataclass, field

import numpy as np

from autopilot.traffic import AvoidLimits, OwnShip, TrafficAvoidance, TrafficParams
from autopilot.traffic.param_decls import SeparationVolume, TrafficAction
from autopilot.traffic.reactive import Phase, ReactiveLayer, ReactiveLimits
from mavlink_bridge.contract.frames import GeoPoint, LocalNedFrame
from mavlink_bridge.contract.traffic import AdsbEmitterType, TrafficReport, TrafficSource

HOME = GeoPoint(47.397742, 8.545594, 488.0)
FRAME = LocalNedFrame(HOME)
DT_S = 0.1
ACC_M_S2 = 3.0
LAND_M_S = 1.5  # descent speed of a landing ship (MPC_LAND_SPEED-like)
AIRBORNE_M = 0.5  # a ship lower than this is on the ground
#: What a ship may fly (MPC_* defaults: 12 m/s, 3 up, 1.5 down, 3 m/s^2; floor 2 m, ceiling 120 m).
REACTIVE_LIMITS = ReactiveLimits(12.0, 3.0, 1.5, ACC_M_S2, -2.0, -120.0)


@dataclass
class Ship:
    system_id: int
    pos: np.ndarray  # NED about home
    goal: np.ndarray
    cruise_m_s: float = 5.0
    vel: np.ndarray = field(default_factory=lambda: np.zeros(3))
    avoidance: TrafficAvoidance | None = None
    texts: list[str] = field(default_factory=list)
    detour_steps: int = 0
    start_s: float = 0.0  # it hovers where it is until then (staggered departures)
    offsets: dict[int, np.ndarray] = field(default_factory=dict)  # step -> the offset of the detour flown then
    land: bool = False  # at its goal it descends to the ground
    landing: bool = False
    reactive: ReactiveLayer | None = None
    reactive_steps: int = 0

    @property
    def done(self) -> bool:
        return self.landing or float(np.linalg.norm(self.goal - self.pos)) < 1.0

    @property
    def airborne(self) -> bool:
        return -float(self.pos[2]) > AIRBORNE_M


@dataclass
class Manned:
    icao: int
    pos: np.ndarray
    vel: np.ndarray


def report(source: TrafficSource, target_id: int, pos: np.ndarray, vel: np.ndarray, t_us: int) -> TrafficReport:
    g = FRAME.geodetic_from_ned(float(pos[0]), float(pos[1]), float(pos[2]))
    emitter = AdsbEmitterType.UAV if source is TrafficSource.UAV else AdsbEmitterType.ROTOCRAFT
    return TrafficReport(source, target_id, "", emitter, g.lat_deg, g.lon_deg, g.alt_amsl_m, *map(float, vel), t_us)


def ratio(a: np.ndarray, b: np.ndarray, vol: SeparationVolume) -> float:
    d = b - a
    return max(math.hypot(d[0], d[1]) / vol.hor_m, abs(d[2]) / vol.ver_m)


@dataclass
class Outcome:
    min_uav_ratio: float
    min_manned_ratio: float
    completed: int
    ships: list[Ship]


def fly(
    ships: list[Ship],
    manned: list[Manned] = (),
    *,
    action: TrafficAction = TrafficAction.AVOID,
    duration_s: float = 120.0,
    limits: AvoidLimits | None = None,
    params: TrafficParams | None = None,
) -> Outcome:
    """Fly everyone for ``duration_s``; the smallest separation ratios (>= 1: separation kept) and completions."""
    params = params or TrafficParams(action=action)
    limits = limits or AvoidLimits(down_max_m=-2.0, down_min_m=-120.0)
    for s in ships:
        s.avoidance = TrafficAvoidance(params, s.system_id)
        s.avoidance.set_home(HOME)
        s.reactive = ReactiveLayer(s.system_id)
    min_uav = min_man = math.inf
    steps = round(duration_s / DT_S)
    for k in range(steps):
        t_us = round(k * DT_S * 1e6)
        for i, s in enumerate(ships):
            reports = []
            if k % 10 == i % 10:  # each receiver at 1 Hz, staggered
                reports = [report(TrafficSource.UAV, o.system_id, o.pos, o.vel, t_us) for o in ships if o is not s]
                reports += [report(TrafficSource.MANNED, m.icao, m.pos, m.vel, t_us) for m in manned]
            waiting = k * DT_S < s.start_s
            s.landing = s.landing or (s.land and float(np.linalg.norm(s.goal - s.pos)) < 1.0)
            route = () if s.done or waiting else (tuple(float(x) for x in s.goal),)
            own = OwnShip(t_us, tuple(map(float, s.pos)), tuple(map(float, s.vel)), route, s.cruise_m_s, s.system_id)
            decision = s.avoidance.update(own, reports, limits, can_avoid=not s.landing, airborne=s.airborne)
            s.texts += [t.text for t in decision.texts]
            sp = decision.setpoint(t_us)
            if decision.resolution is not None:
                s.offsets[k] = np.array(decision.resolution.offset_ned_m)
            if sp is not None:
                s._next = (np.array(sp[0]), np.array(sp[1]))  # type: ignore[attr-defined]
                s.detour_steps += 1
            else:
                s._next = None  # type: ignore[attr-defined]
        for s in ships:  # what each would fly (the detour, the landing, the goal), bounded by its reactive layer
            nxt = s._next  # type: ignore[attr-defined]
            if s.landing:
                pref = np.array((0.0, 0.0, LAND_M_S if s.airborne else 0.0))
            elif nxt is not None:
                pref = nxt[1] + np.clip(nxt[0] - s.pos, -3.0, 3.0)
            else:
                to_goal = s.goal - s.pos if k * DT_S >= s.start_s else np.zeros(3)
                dist = float(np.linalg.norm(to_goal))
                speed = min(s.cruise_m_s, math.sqrt(2.0 * ACC_M_S2 * dist))
                pref = to_goal / dist * speed if dist > 1e-6 else np.zeros(3)
            cmd = pref
            if s.reactive is not None and s.airborne and action is TrafficAction.AVOID:
                phase = Phase.LAND if s.landing else Phase.MISSION
                table = s.avoidance.table  # type: ignore[union-attr]
                c = s.reactive.solve(t_us, tuple(map(float, s.pos)), tuple(map(float, s.vel)),
                                     tuple(map(float, pref)), table.tracks, params, REACTIVE_LIMITS, phase,
                                     table.version)  # fmt: skip
                if c is not None:
                    cmd = np.array(c.vel_ned_m_s)
                    s.reactive_steps += 1
            dv = cmd - s.vel
            n = float(np.linalg.norm(dv))
            s.vel = s.vel + (dv if n <= ACC_M_S2 * DT_S else dv / n * ACC_M_S2 * DT_S)
            s.pos = s.pos + s.vel * DT_S
            if s.pos[2] > 0.0:  # on the ground
                s.pos[2], s.vel[2] = 0.0, 0.0
        for m in manned:
            m.pos = m.pos + m.vel * DT_S
        for i, a in enumerate(ships):
            for b in ships[i + 1 :]:
                if a.airborne and b.airborne:
                    min_uav = min(min_uav, ratio(a.pos, b.pos, params.uav))
            for m in manned:
                min_man = min(min_man, ratio(a.pos, m.pos, params.manned))
    return Outcome(min_uav, min_man, sum(s.done for s in ships), ships)


# ---------------------------------------------------------------------- seeded encounter geometries
def _ship(sid: int, start: tuple[float, float, float], goal: tuple[float, float, float], speed: float) -> Ship:
    return Ship(sid, np.array(start, float), np.array(goal, float), speed)


def head_on(rng: np.random.Generator) -> list[Ship]:
    alt, lat, v1, v2 = -rng.uniform(15, 40), rng.uniform(-4, 4), rng.uniform(3, 7), rng.uniform(3, 7)
    dz = rng.uniform(-2, 2)
    return [_ship(1, (0, 0, alt), (240, 0, alt), v1), _ship(2, (240, lat, alt + dz), (0, lat, alt + dz), v2)]


def crossing(rng: np.random.Generator) -> list[Ship]:
    """Two legs through one point at a random angle, arriving there within a second or two of each other."""
    alt, angle = -rng.uniform(15, 40), math.radians(rng.uniform(15, 165)) * rng.choice((-1, 1))
    v1, v2 = rng.uniform(3, 7), rng.uniform(3, 7)
    d1 = 120.0
    d2 = v2 * (d1 / v1 + rng.uniform(-2, 2))
    u = np.array((math.cos(angle), math.sin(angle), 0.0))
    c = np.array((d1, 0.0, alt))
    a = _ship(1, (0, 0, alt), (2 * d1, 0, alt), v1)
    b = _ship(2, tuple(c - u * d2), tuple(c + u * d1), v2)
    ids = rng.permutation([1, 2])
    a.system_id, b.system_id = int(ids[0]), int(ids[1])
    return [a, b]


def overtaking(rng: np.random.Generator) -> list[Ship]:
    alt, lat = -rng.uniform(15, 40), rng.uniform(-3, 3)
    fast, slow = rng.uniform(6, 8), rng.uniform(2, 3)
    a = _ship(1, (0, 0, alt), (260, 0, alt), fast)  # passes and flies on
    b = _ship(2, (40, lat, alt), (200, lat, alt), slow)
    if rng.random() < 0.5:
        a.system_id, b.system_id = 2, 1
    return [a, b]


def overtaking_lander(rng: np.random.Generator) -> list[Ship]:
    """A fast vehicle overtakes a slow one on its line; the slow one stops at its drop point and lands there, right
    under the fast one's way (tools.encounters' overtaking: the slower vehicle lands first, short of the others)."""
    alt, lat = -15.0, rng.uniform(-2, 2)
    fast, slow = rng.uniform(6, 8), rng.uniform(2.5, 3.5)
    gap = rng.uniform(12, 16)
    drop = rng.uniform(45, 60)
    a = _ship(1, (gap, lat, alt), (gap + drop, lat, alt), slow)
    a.land = True
    b = _ship(2, (0, 0, alt), (gap + drop + 60, 0, alt), fast)
    if rng.random() < 0.5:
        a.system_id, b.system_id = 2, 1
    return [a, b]


def vertical(rng: np.random.Generator) -> list[Ship]:
    """One vehicle climbs (or descends) through the other's level as it passes."""
    alt, v1 = -rng.uniform(20, 30), rng.uniform(3, 7)
    x = 100.0 + rng.uniform(-5, 5)
    t_pass = x / v1
    climb = rng.choice((-1, 1))
    vz = rng.uniform(1.0, 2.5)
    start_z = alt + climb * vz * t_pass
    a = _ship(1, (0, 0, alt), (200, 0, alt), v1)
    b = _ship(2, (x, rng.uniform(-2, 2), start_z), (x, 0, alt - climb * 15), vz)
    if rng.random() < 0.5:
        a.system_id, b.system_id = 2, 1
    return [a, b]


def converging(rng: np.random.Generator, n: int) -> list[Ship]:
    """``n`` vehicles from a ring toward drop points across it, 30-40 m around the centre, one level."""
    alt = -rng.uniform(15, 30)
    phase = rng.uniform(0, 2 * math.pi)
    ships = []
    for i in range(n):
        a = phase + 2 * math.pi * i / n + rng.uniform(-0.2, 0.2)
        r = rng.uniform(110, 150)
        goal_a = phase + 2 * math.pi * ((i + n // 2) % n + 0.5) / n
        gr = max(30.0, 20.0 / math.sin(math.pi / n))
        start = (r * math.cos(a), r * math.sin(a), alt)
        goal = (gr * math.cos(goal_a), gr * math.sin(goal_a), alt)
        ships.append(_ship(i + 1, start, goal, rng.uniform(3, 6)))
    return ships


def depot_departures(rng: np.random.Generator, n: int) -> list[Ship]:
    """``n`` vehicles leave one depot (hovering 15 m apart at one level) for drop points 150-200 m away in random
    directions, 5-10 s apart, so that legs cross."""
    alt = -rng.uniform(15, 30)
    ships = []
    for i in range(n):
        start = (15.0 * (i % 3) - 15.0, 15.0 * (i // 3), alt)
        a, r = rng.uniform(0, 2 * math.pi), rng.uniform(150, 200)
        ship = _ship(i + 1, start, (r * math.cos(a), r * math.sin(a), alt), rng.uniform(3, 6))
        ship.start_s = float(i * rng.uniform(5, 10))
        ships.append(ship)
    return ships


def manned_crossing(rng: np.random.Generator) -> tuple[list[Ship], list[Manned]]:
    """A UAV on a delivery leg while a helicopter crosses it at 40 m/s near its level, both reaching the crossing
    point 35-45 s after the start (the helicopter first reported 1.4-1.8 km away)."""
    alt = -rng.uniform(15, 40)
    heading = rng.uniform(0, 2 * math.pi)
    speed = rng.uniform(3, 6)
    t_meet = rng.uniform(35, 45)
    leg = speed * t_meet
    u = np.array((math.cos(heading), math.sin(heading), 0.0))
    ship = _ship(1, (0, 0, alt), tuple(2 * leg * u + (0, 0, alt)), speed)
    cross = heading + rng.uniform(0.3, math.pi - 0.3) * rng.choice((-1, 1))
    vel = 40.0 * np.array((math.cos(cross), math.sin(cross), 0.0))
    meet = leg * u + np.array((0.0, 0.0, -40.0 + rng.uniform(-10, 10)))
    heli = Manned(0xA1B2C3, meet - vel * (t_meet + rng.uniform(-3, 3)), vel)
    return [ship], [heli]


# ---------------------------------------------------------------------- the encounter table (docs/traffic_avoidance.md)
def encounter_table(seeds: int, action: TrafficAction) -> list[tuple[str, int, float, int, int, int]]:
    """Per geometry: (name, encounters, worst separation ratio, losses of separation, missions completed, total)."""
    pair_kinds = {
        "head-on": head_on,
        "crossing": crossing,
        "overtaking": overtaking,
        "vertical": vertical,
        "overtaking a lander": overtaking_lander,
    }
    groups: list[tuple[str, list[tuple[list[Ship], list[Manned]]], float]] = []
    for name, make in pair_kinds.items():
        groups.append((name, [(make(np.random.default_rng(s)), []) for s in range(seeds)], 130.0))
    for n in (3, 4, 6):
        cases = [(converging(np.random.default_rng(s), n), []) for s in range(max(seeds // 2, 1))]
        groups.append((f"converging x{n}", cases, 130.0))
    for n in (4, 8):
        cases = [(depot_departures(np.random.default_rng(s), n), []) for s in range(max(seeds // 4, 1))]
        groups.append((f"depot departures x{n}", cases, 170.0))
    groups.append(("manned crossing", [manned_crossing(np.random.default_rng(s)) for s in range(seeds)], 150.0))
    rows = []
    for name, cases, duration_s in groups:
        worst, lost, done, total = math.inf, 0, 0, 0
        for ships, manned in cases:
            out = fly(ships, manned, action=action, duration_s=duration_s)
            ratio = out.min_manned_ratio if manned else out.min_uav_ratio
            worst, lost = min(worst, ratio), lost + (ratio < 1.0)
            done, total = done + out.completed, total + len(ships)
        rows.append((name, len(cases), worst, lost, done, total))
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(
        description="traffic encounters in the kinematic closed loop (docs/traffic_avoidance.md)"
    )
    parser.add_argument("--seeds", type=int, default=20, help="encounters per two-vehicle geometry")
    args = parser.parse_args()
    print("| geometry | encounters | NAV_TRAFF_AVOID | worst separation ratio | losses of separation | completed |")
    print("|---|---|---|---|---|---|")
    for action in (TrafficAction.AVOID, TrafficAction.WARN):
        for name, n, worst, lost, done, total in encounter_table(args.seeds, action):
            print(f"| {name} | {n} | {action.value} ({action.name.lower()}) | {worst:.2f} | {lost} | {done}/{total} |")


if __name__ == "__main__":
    main()
