"""Seeded encounter worlds for the traffic Monte Carlo (issues 23, 28): 2 to 8 vehicles on conflicting routes.

``encounter_world(seed, kind=None, vehicles=None, manned=None)`` draws one fleet world from
``numpy.random.default_rng([seed, 23])``, a pure function of its arguments: the same seed gives the same world.
Kinds (drawn with ``KIND_WEIGHTS`` when not given):

- ``head_on``: pairs on lanes 20 m apart fly towards each other along a random course (each lands 20 m past
  the other's pad);
- ``crossing``: every route passes near the area's centre, the courses spread over 180 deg with random angles;
- ``overtaking``: one course, the slowest at 2.5-3.5 m/s, the fastest up to 3 times as fast (at most 10 m/s);
  the faster vehicles start further back and must pass the slower ones;
- ``vertical``: head-on pairs, one climbing from 10 m to 24 m while the other descends from 24 m to 10 m, both
  between waypoints 8 m either side of the point where they meet (so they cross altitudes there);
- ``converging``: pads on a 90 m circle, every vehicle lands at the one depot (a 3 x 3 grid of pads 20 m apart),
  take-offs staggered by ``stagger_s`` (2-6 s drawn; the ground station's ``--stagger-s``);
- ``ring_swap`` (4-8 vehicles; ORCA's benchmark): pads on a 35-60 m circle, at least 20 m apart; each vehicle
  flies at one altitude (12-30 m, the same for all) to the antipodal pad and lands there (its owner has left it),
  all at once;
- ``crossing_climb``: courses at random angles over the whole turn, each vehicle at its own altitude (10-40 m)
  changing to another one between two waypoints 15 m either side of the centre, so climbs and descents happen
  inside the conflict;
- ``depot``: take-offs and landings interleaved at one depot (the 3 x 3 grid): some vehicles arrive from a 90 m
  circle and land on free depot pads while the others depart from depot pads to that circle, arrivals started
  first, every start ``stagger_s`` (3-7 s) after the previous one.

With ``manned`` (drawn true for ``MANNED_P`` of the worlds when not given) a helicopter (20-50 m/s) or a light
aircraft (40-70 m/s), in one manned world of five both, crosses the area within 30 m of its centre at 20-120 m
above the ground: in ``BELOW_P`` of the manned worlds the vehicles' routes are raised 15-30 m and the first aircraft
flies below their cruise (20 m up to 5 m under their lowest route), else it flies 20-45 m up (inside the NMAC
half-height of the cruise) or, in a quarter, 45-120 m. It passes the centre 8-14 s after the start (vehicles
taking off or still on their pads), 15-50 s after it, or 60-110 s after it (vehicles landing or landed).

Each vehicle: take off on its pad, its waypoints, land at the far end; a 300 m inclusion fence about the centre.
Every pad (home or landing point) is at least ``MIN_PAD_GAP_M`` (20 m: the 10 m UAV volume and a margin) from
every other vehicle's pad and landing point, but for a ring swap's own partner (a draw that is not is drawn again
from the same stream, so the world stays a function of the seed).

``python -m tools.encounters --seed K [--kind KIND] [--vehicles N] [--manned|--no-manned] --out W.yaml`` writes
one; ``python -m tools.run --world W.yaml --stagger-s S`` flies it (S printed by the first command).
"""

from __future__ import annotations

import argparse
import itertools
import math
import sys
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np
import yaml

KINDS = ("head_on", "crossing", "overtaking", "vertical", "converging", "ring_swap", "crossing_climb", "depot")
#: How often each kind is drawn (KINDS' order): the shipped campaign's >= 10 % ring swaps and the new kinds' share.
KIND_WEIGHTS = (0.10, 0.10, 0.11, 0.10, 0.09, 0.16, 0.17, 0.17)
#: The fewest vehicles of a kind (a ring swap is 4 to 8; every other kind 2 to 8).
MIN_VEHICLES = {kind: 4 if kind == "ring_swap" else 2 for kind in KINDS}
#: Share of drawn worlds with 8 vehicles (the rest: uniform from the kind's minimum to 7).
EIGHT_P = 0.27
#: Share of drawn worlds with manned traffic; of those, the share where it flies below the vehicles' cruise.
MANNED_P = 0.22
BELOW_P = 0.3
#: Traffic classes of a world (the row's ``vary.encounter.traffic``).
TRAFFIC_CLASSES = ("none", "rotorcraft", "light", "both")
HOME = {"lat_deg": 47.3977, "lon_deg": 8.5456, "alt_m": 488.0}
CRUISE_ALT_M = 15.0
HALF_LEG_M = 60.0
MIN_PAD_GAP_M = 20.0  # the UAV separation volume (10 m) and a margin: neighbouring pads and landings stay clear
LANE_M = 25.0  # head-on lanes: pads >= 21 m apart whatever the +-2 m jitter
DEPOT_PAD_GAP_M = 22.0  # the depot's grid, 2 m above the minimum (positions are rounded to 1 cm)
OUTER_RADIUS_M = 1.5 * HALF_LEG_M  # the circle converging and depot vehicles come from or go to
FENCE_RADIUS_M = 300.0
VERTICAL_LOW_M = 10.0
VERTICAL_HIGH_M = 24.0
VERTICAL_WINDOW_M = 8.0
CLIMB_WINDOW_M = 15.0
MAX_SPEED_M_S = 10.0
_ROUTE_TRIES = 40
_STREAM = 23  # the second word of the generator's seed: this module's own stream
#: The depot's pads, a 3 x 3 grid about the centre, the centre pad first.
_DEPOT = [((k // 3 - 1) * DEPOT_PAD_GAP_M, (k % 3 - 1) * DEPOT_PAD_GAP_M) for k in (4, 1, 7, 3, 5, 0, 2, 6, 8)]


@dataclass(frozen=True, slots=True)
class Encounter:
    """One drawn encounter: its fleet world document and the take-off stagger to fly it with."""

    seed: int
    kind: str
    vehicles: int
    manned: bool
    stagger_s: float
    world: dict[str, Any]
    traffic: str = "none"  # TRAFFIC_CLASSES: the manned aircraft's classes

    def yaml_text(self) -> str:
        head = f"# encounter seed {self.seed}: {self.kind}, {self.vehicles} vehicles, manned {self.manned}"
        head += f" ({self.traffic}), stagger {self.stagger_s:g} s (python -m tools.encounters)\n"
        return head + yaml.safe_dump(self.world, sort_keys=False, default_flow_style=None, width=120)


@dataclass(frozen=True, slots=True)
class _Route:
    start_ne_m: tuple[float, float]
    end_ne_m: tuple[float, float]
    alt_start_m: float = CRUISE_ALT_M
    alt_end_m: float = CRUISE_ALT_M
    speed_m_s: float = 5.0
    via: tuple[tuple[float, float, float], ...] = ()  # (north, east, alt) waypoints before the far end
    partner: int | None = None  # a ring swap: the vehicle whose pad this one lands on (it has left it)


def encounter_world(
    seed: int, kind: str | None = None, vehicles: int | None = None, manned: bool | None = None
) -> Encounter:
    """The encounter of ``seed`` (ValueError for an unknown kind or a count outside the kind's range)."""
    rng = np.random.default_rng([seed, _STREAM])
    u_kind, u_n, u_manned = (float(u) for u in rng.random(3))
    if vehicles is not None and not 2 <= vehicles <= 8:
        raise ValueError(f"an encounter has 2 to 8 vehicles, got {vehicles}")
    if kind is not None and kind not in KINDS:
        raise ValueError(f"unknown encounter kind {kind!r}; choose one of {', '.join(KINDS)}")
    kind = kind or _pick(u_kind, [k for k in KINDS if vehicles is None or vehicles >= MIN_VEHICLES[k]])
    low = MIN_VEHICLES[kind]
    if vehicles is not None and vehicles < low:
        raise ValueError(f"a {kind} encounter has {low} to 8 vehicles, got {vehicles}")
    n = (
        vehicles
        if vehicles is not None
        else (8 if u_n < EIGHT_P else low + int((u_n - EIGHT_P) / (1 - EIGHT_P) * (8 - low)))
    )
    manned = u_manned < MANNED_P if manned is None else manned
    course_rad = float(rng.uniform(0.0, 2.0 * math.pi))
    stagger_s = 0.0
    if kind == "converging":
        stagger_s = round(float(rng.uniform(2.0, 6.0)), 1)
    elif kind == "depot":
        stagger_s = round(float(rng.uniform(3.0, 7.0)), 1)
    for _ in range(_ROUTE_TRIES):  # a draw that puts pads too close (rare: many crossing courses) is drawn again
        routes = [_rotated(r, course_rad) for r in _ROUTES[kind](rng, n)]
        if _pads_clear(routes):
            break
    else:
        raise AssertionError(f"seed {seed}: no {kind} geometry with pads {MIN_PAD_GAP_M} m apart (generator bug)")
    traffic: list[dict[str, Any]] = []
    classes = "none"
    if manned:
        routes, traffic, classes = _manned_traffic(rng, routes)
    world: dict[str, Any] = {
        "name": f"encounter_{seed}",
        "home": dict(HOME),
        "vehicle": "x500",
        "world": {"wind": {"north_m_s": 0.0, "east_m_s": 0.0, "down_m_s": 0.0, "gust_m_s": 0.3, "seed": seed}},
        "vehicles": [_vehicle(f"uav{i}", r) for i, r in enumerate(routes)],
    }
    if traffic:
        world["traffic"] = traffic
    return Encounter(seed, kind, n, manned, stagger_s, world, classes)


def _pick(u: float, kinds: list[str]) -> str:
    """The kind ``u`` in [0, 1) falls on, ``kinds`` weighted by ``KIND_WEIGHTS``."""
    weights = np.array([KIND_WEIGHTS[KINDS.index(k)] for k in kinds])
    return kinds[min(int(np.searchsorted(np.cumsum(weights / weights.sum()), u, side="right")), len(kinds) - 1)]


def _lanes(n_pairs: int) -> list[float]:
    return [(k - (n_pairs - 1) / 2.0) * LANE_M for k in range(n_pairs)]


def _head_on(rng: np.random.Generator, n: int, climb: bool = False) -> list[_Route]:
    routes = []
    for k, lane in enumerate(_lanes(math.ceil(n / 2))):
        jitter = float(rng.uniform(-2.0, 2.0))  # a near-miss as often as a dead-centre collision course
        far = HALF_LEG_M + LANE_M  # each lands a lane beyond the other's pad
        if not climb:
            routes.append(_Route((-HALF_LEG_M, lane), (far, lane + jitter)))
            if 2 * k + 1 < n:
                routes.append(_Route((HALF_LEG_M, lane + jitter), (-far, lane)))
            continue
        # vertical: the climb and the descent happen between two waypoints VERTICAL_WINDOW_M either side of the
        # meeting point, so both cross the other's altitude where they meet (not before, whatever the climb rate)
        w = VERTICAL_WINDOW_M
        up = ((-w, lane + jitter / 2, VERTICAL_LOW_M), (w, lane + jitter / 2, VERTICAL_HIGH_M))
        routes.append(_Route((-HALF_LEG_M, lane), (far, lane + jitter), VERTICAL_LOW_M, VERTICAL_HIGH_M, via=up))
        if 2 * k + 1 < n:
            down = ((w, lane + jitter / 2, VERTICAL_HIGH_M), (-w, lane + jitter / 2, VERTICAL_LOW_M))
            routes.append(_Route((HALF_LEG_M, lane + jitter), (-far, lane), VERTICAL_HIGH_M, VERTICAL_LOW_M, via=down))
    return routes


def _crossing(rng: np.random.Generator, n: int) -> list[_Route]:
    spacing = math.pi / n  # courses over half a turn, each jittered inside its own slice
    near, far = HALF_LEG_M + 10.0, HALF_LEG_M + 10.0 + LANE_M  # pads, and landings past the circle of pads
    routes = []
    for i in range(n):
        course = i * spacing + float(rng.uniform(-0.15, 0.15)) * spacing
        u = (math.cos(course), math.sin(course))
        offset = float(rng.uniform(-4.0, 4.0))  # across the course: they meet near, not at, the centre
        side = (-u[1] * offset, u[0] * offset)
        start = (-near * u[0] + side[0], -near * u[1] + side[1])
        end = (far * u[0] + side[0], far * u[1] + side[1])
        routes.append(_Route(start, end))
    return routes


def _overtaking(rng: np.random.Generator, n: int) -> list[_Route]:
    slowest = float(rng.uniform(2.5, 3.5))
    ratio = min(float(rng.uniform(1.5, 3.0)), MAX_SPEED_M_S / slowest)
    routes = []
    for i in range(n):  # vehicle i starts i lanes back, flies faster and lands i lanes further on
        lateral = float(rng.uniform(-2.0, 2.0))
        speed = slowest * (1.0 + (ratio - 1.0) * i / (n - 1))
        routes.append(_Route((-HALF_LEG_M - i * LANE_M, lateral), (HALF_LEG_M + i * LANE_M, lateral), speed_m_s=speed))
    return routes


def _on_circle(rng: np.random.Generator, n: int, radius_m: float, jitter: float = 0.25) -> list[tuple[float, float]]:
    """``n`` points on a circle, one per equal slice, each jittered inside its slice."""
    slice_rad = 2.0 * math.pi / n
    out = []
    for i in range(n):
        bearing = i * slice_rad + float(rng.uniform(-jitter, jitter)) * slice_rad
        out.append((radius_m * math.cos(bearing), radius_m * math.sin(bearing)))
    return out


def _converging(rng: np.random.Generator, n: int) -> list[_Route]:
    return [_Route(start, _DEPOT[i]) for i, start in enumerate(_on_circle(rng, n, OUTER_RADIUS_M))]


def _ring_swap(rng: np.random.Generator, n: int) -> list[_Route]:
    radius = max(float(rng.uniform(35.0, 60.0)), (MIN_PAD_GAP_M + 2.0) / (2.0 * math.sin(math.pi / n)))
    alt = round(float(rng.uniform(12.0, 30.0)), 1)
    speed = float(rng.uniform(4.0, 6.0))
    phase = float(rng.uniform(0.0, 2.0 * math.pi))
    pads = [
        (radius * math.cos(phase + 2.0 * math.pi * i / n), radius * math.sin(phase + 2.0 * math.pi * i / n))
        for i in range(n)
    ]
    routes = []
    for i in range(n):  # vehicle i lands on the pad diametrically opposite (an odd ring: the nearest to it)
        j = (i + n // 2) % n
        routes.append(_Route(pads[i], pads[j], alt, alt, speed, partner=j))
    return routes


def _crossing_climb(rng: np.random.Generator, n: int) -> list[_Route]:
    starts = _on_circle(rng, n, HALF_LEG_M + 10.0, jitter=0.3)
    ends = _on_circle(rng, n, OUTER_RADIUS_M + 5.0, jitter=0.3)
    third = math.ceil(n / 3)
    shift = int(rng.integers(third, n - third + 1))  # 120-240 deg round the circle: every course crosses the area
    routes = []
    for i, start in enumerate(starts):
        end = ends[(i + shift) % n]
        alt_a, alt_b = (round(float(a), 1) for a in rng.uniform(10.0, 40.0, 2))
        dn, de = end[0] - start[0], end[1] - start[1]
        length = math.hypot(dn, de)
        # the closest point of the course to the centre, and the altitude change across it
        t = max(0.2, min(0.8, -(start[0] * dn + start[1] * de) / (length * length)))
        mid = (start[0] + t * dn, start[1] + t * de)
        w = CLIMB_WINDOW_M / length
        a = (round(mid[0] - w * dn, 2), round(mid[1] - w * de, 2), alt_a)
        b = (round(mid[0] + w * dn, 2), round(mid[1] + w * de, 2), alt_b)
        routes.append(_Route(start, end, alt_a, alt_b, float(rng.uniform(4.0, 7.0)), via=(a, b)))
    return routes


def _depot(rng: np.random.Generator, n: int) -> list[_Route]:
    arrivals = int(rng.integers(1, n)) if n > 2 else 1  # 1 .. n-1 arrive, the rest depart
    outer = _on_circle(rng, n, OUTER_RADIUS_M)
    pads = [_DEPOT[int(k)] for k in rng.permutation(len(_DEPOT))[:n]]
    routes = [_Route(outer[i], pads[i]) for i in range(arrivals)]  # started first: they land as the others leave
    routes += [_Route(pads[i], outer[i]) for i in range(arrivals, n)]
    return routes


_ROUTES: dict[str, Callable[[np.random.Generator, int], list[_Route]]] = {
    "head_on": _head_on,
    "crossing": _crossing,
    "overtaking": _overtaking,
    "vertical": lambda rng, n: _head_on(rng, n, climb=True),
    "converging": _converging,
    "ring_swap": _ring_swap,
    "crossing_climb": _crossing_climb,
    "depot": _depot,
}


def _rotated(route: _Route, course_rad: float) -> _Route:
    c, s = math.cos(course_rad), math.sin(course_rad)

    def rot(p: tuple[float, float]) -> tuple[float, float]:
        return (round(c * p[0] - s * p[1], 2), round(s * p[0] + c * p[1], 2))

    via = tuple((*rot((n, e)), alt) for n, e, alt in route.via)
    return replace(route, start_ne_m=rot(route.start_ne_m), end_ne_m=rot(route.end_ne_m), via=via)


def _pads_clear(routes: list[_Route]) -> bool:
    """Every pad and landing point at least MIN_PAD_GAP_M from every other vehicle's (a ring swap lands on its
    partner's pad, which the partner has left)."""
    for (_, a), (j, b) in itertools.permutations(enumerate(routes), 2):
        if math.dist(a.start_ne_m, b.start_ne_m) < MIN_PAD_GAP_M - 1e-6:
            return False
        if math.dist(a.end_ne_m, b.end_ne_m) < MIN_PAD_GAP_M - 1e-6:
            return False
        if a.partner != j and math.dist(a.end_ne_m, b.start_ne_m) < MIN_PAD_GAP_M - 1e-6:
            return False
    return True


def _vehicle(name: str, r: _Route) -> dict[str, Any]:
    north, east = r.start_ne_m
    to_north, to_east = r.end_ne_m
    return {
        "name": name,
        "home": {"north_m": north, "east_m": east},
        "speed_m_s": round(r.speed_m_s, 2),
        "mission": [
            {"takeoff": {"alt_m": r.alt_start_m}},
            *({"waypoint": {"north_m": n, "east_m": e, "alt_m": alt, "accept_radius_m": 2.0}} for n, e, alt in r.via),
            {"waypoint": {"north_m": to_north, "east_m": to_east, "alt_m": r.alt_end_m, "accept_radius_m": 2.0}},
            {"land": {}},
        ],
        "fence": [{"inclusion_circle": {"north_m": 0.0, "east_m": 0.0, "radius_m": FENCE_RADIUS_M}}],
    }


def _raised(route: _Route, dz_m: float) -> _Route:
    via = tuple((n, e, round(alt + dz_m, 1)) for n, e, alt in route.via)
    return replace(
        route, alt_start_m=round(route.alt_start_m + dz_m, 1), alt_end_m=round(route.alt_end_m + dz_m, 1), via=via
    )


def _manned_traffic(rng: np.random.Generator, routes: list[_Route]) -> tuple[list[_Route], list[dict[str, Any]], str]:
    """The manned aircraft of a world (one, or one of each class), the routes (raised when the first flies below
    their cruise) and the world's traffic class."""
    u_class, u_both, u_below = (float(u) for u in rng.random(3))
    classes = ["rotorcraft" if u_class < 0.5 else "light"]
    if u_both < 0.2:
        classes = ["rotorcraft", "light"]
    below = u_below < BELOW_P
    if below:
        dz = round(float(rng.uniform(15.0, 30.0)), 1)
        routes = [_raised(r, dz) for r in routes]
    lowest = min(min(r.alt_start_m, r.alt_end_m, *(alt for _, _, alt in r.via)) for r in routes)
    aircraft = []
    for k, emitter in enumerate(classes):
        if below and k == 0:
            alt = float(rng.uniform(20.0, max(20.0, lowest - 5.0)))
        else:
            alt = float(rng.uniform(45.0, 120.0)) if rng.random() < 0.25 else float(rng.uniform(20.0, 45.0))
        aircraft.append(_aircraft(rng, emitter, k, alt))
    return routes, aircraft, classes[0] if len(classes) == 1 else "both"


def _aircraft(rng: np.random.Generator, emitter: str, k: int, alt_m: float) -> dict[str, Any]:
    """A manned aircraft flying straight over the area (within 30 m of its centre) at ``alt_m``, starting at sim
    time 0 as far before the centre as it flies in the drawn time and as far past it."""
    speed = float(rng.uniform(20.0, 50.0) if emitter == "rotorcraft" else rng.uniform(40.0, 70.0))
    window = int(rng.integers(3))
    over_centre_s = float(rng.uniform(*((8.0, 14.0), (15.0, 50.0), (60.0, 110.0))[window]))
    course = float(rng.uniform(0.0, 2.0 * math.pi))
    offset = float(rng.uniform(-30.0, 30.0))
    u, side = (math.cos(course), math.sin(course)), (-math.sin(course) * offset, math.cos(course) * offset)
    reach = speed * over_centre_s
    alt = round(alt_m, 1)
    point = [
        {"north_m": round(side[0] + s * reach * u[0], 1), "east_m": round(side[1] + s * reach * u[1], 1), "alt_m": alt}
        for s in (-1, 1)
    ]
    return {
        "callsign": f"HELI{k + 1}" if emitter == "rotorcraft" else f"PLANE{k + 1}",
        "icao": 0xA1B2C3 + k,
        "emitter": emitter,
        "path": point,
        "speed_m_s": round(speed, 1),
        "start_s": 0,
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m tools.encounters", description=__doc__.split("\n", 1)[0])
    parser.add_argument("--seed", type=int, required=True, help="the encounter's seed")
    parser.add_argument("--kind", choices=KINDS, default=None, help="default: drawn from the seed")
    parser.add_argument("--vehicles", type=int, default=None, help="2..8 (default: drawn from the seed)")
    parser.add_argument("--manned", action=argparse.BooleanOptionalAction, default=None, help="add manned traffic")
    parser.add_argument("--out", required=True, help="the world file to write")
    args = parser.parse_args(argv)
    try:
        enc = encounter_world(args.seed, args.kind, args.vehicles, args.manned)
        Path(args.out).write_text(enc.yaml_text())
    except (ValueError, OSError) as exc:
        print(f"encounters: error: {exc}", file=sys.stderr)
        return 2
    print(f"{args.out}: {enc.kind}, {enc.vehicles} vehicles, manned {enc.manned} ({enc.traffic}); fly it with: "
          f"python -m tools.run --world {args.out} --stagger-s {enc.stagger_s:g}")  # fmt: skip
    return 0


if __name__ == "__main__":
    sys.exit(main())
