"""A small kinematic closed loop for traffic-avoidance tests: point-mass "own ships", each running its own
:class:`TrafficAvoidance` on the others' 1 Hz reports and flying its decision (the detour reference exactly, else
straight to its goal with an acceleration limit), plus scripted straight-flying manned aircraft."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from autopilot.traffic import AvoidLimits, OwnShip, TrafficAvoidance, TrafficParams
from autopilot.traffic.param_decls import SeparationVolume, TrafficAction
from mavlink_bridge.contract.frames import GeoPoint, LocalNedFrame
from mavlink_bridge.contract.traffic import AdsbEmitterType, TrafficReport, TrafficSource

HOME = GeoPoint(47.397742, 8.545594, 488.0)
FRAME = LocalNedFrame(HOME)
DT_S = 0.1
ACC_M_S2 = 3.0


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

    @property
    def done(self) -> bool:
        return float(np.linalg.norm(self.goal - self.pos)) < 1.0


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


def fly(ships: list[Ship], manned: list[Manned] = (), *, action: TrafficAction = TrafficAction.AVOID,
        duration_s: float = 120.0, limits: AvoidLimits | None = None, params: TrafficParams | None = None) -> Outcome:  # fmt: skip
    """Fly everyone for ``duration_s``; the smallest separation ratios (>= 1: separation kept) and completions."""
    params = params or TrafficParams(action=action)
    limits = limits or AvoidLimits(down_max_m=-2.0, down_min_m=-120.0)
    for s in ships:
        s.avoidance = TrafficAvoidance(params, s.system_id)
        s.avoidance.set_home(HOME)
    min_uav = min_man = math.inf
    steps = round(duration_s / DT_S)
    for k in range(steps):
        t_us = round(k * DT_S * 1e6)
        for i, s in enumerate(ships):
            reports = []
            if k % 10 == i % 10:  # each receiver at 1 Hz, staggered
                reports = [report(TrafficSource.UAV, o.system_id, o.pos, o.vel, t_us) for o in ships if o is not s]
                reports += [report(TrafficSource.MANNED, m.icao, m.pos, m.vel, t_us) for m in manned]
            route = () if s.done else (tuple(float(x) for x in s.goal),)
            own = OwnShip(t_us, tuple(map(float, s.pos)), tuple(map(float, s.vel)), route, s.cruise_m_s, s.system_id)
            decision = s.avoidance.update(own, reports, limits)
            s.texts += [t.text for t in decision.texts]
            sp = decision.setpoint(t_us)
            if sp is not None:
                s._next = (np.array(sp[0]), np.array(sp[1]))  # type: ignore[attr-defined]
                s.detour_steps += 1
            else:
                s._next = None  # type: ignore[attr-defined]
        for s in ships:
            nxt = s._next  # type: ignore[attr-defined]
            if nxt is not None:  # the detour reference one step on
                s.pos = nxt[0] + nxt[1] * DT_S
                s.vel = nxt[1]
                continue
            to_goal = s.goal - s.pos
            dist = float(np.linalg.norm(to_goal))
            speed = min(s.cruise_m_s, math.sqrt(2.0 * ACC_M_S2 * dist))
            want = to_goal / dist * speed if dist > 1e-6 else np.zeros(3)
            dv = want - s.vel
            n = float(np.linalg.norm(dv))
            s.vel = s.vel + (dv if n <= ACC_M_S2 * DT_S else dv / n * ACC_M_S2 * DT_S)
            s.pos = s.pos + s.vel * DT_S
        for m in manned:
            m.pos = m.pos + m.vel * DT_S
        for i, a in enumerate(ships):
            for b in ships[i + 1 :]:
                min_uav = min(min_uav, ratio(a.pos, b.pos, params.uav))
            for m in manned:
                min_man = min(min_man, ratio(a.pos, m.pos, params.manned))
    return Outcome(min_uav, min_man, sum(s.done for s in ships), ships)
