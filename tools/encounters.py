"""Seeded encounter worlds for the traffic Monte Carlo (issue 23): 2 to 8 vehicles on conflicting routes.

``encounter_world(seed, kind=None, vehicles=None, manned=None)`` draws one fleet world from
``numpy.random.default_rng([seed, 23])``, a pure function of its arguments: the same seed gives the same world.
Kinds (drawn when not given):

- ``head_on``: pairs on lanes 14 m apart fly towards each other along a random course (each lands 14 m past
  the other's pad);
- ``crossing``: every route passes near the area's centre, the courses spread over 180 deg with random angles;
- ``overtaking``: one course, the faster vehicles start further back and must pass the slower ones;
- ``vertical``: head-on pairs, one climbing from 10 m to 24 m while the other descends from 24 m to 10 m, both
  between waypoints 8 m either side of the point where they meet (so they cross altitudes there);
- ``converging``: pads on a 90 m circle, every vehicle lands at the one depot (pads 14 m apart: the 10 m UAV
  volume and a margin), take-offs staggered by ``stagger_s`` (2-6 s drawn; the ground station's ``--stagger-s``).

With ``manned`` (drawn true for one world in six when not given) a helicopter or light aircraft crosses the area
at 30-60 m/s, 25-50 m above the ground (inside the 30 m NMAC half-height of the 15 m cruise), over the centre
20-50 s after the start. Each vehicle: take off on its pad, one waypoint at the far end, land there; a 300 m
inclusion fence about the centre. Every pad is at least 10 m from every other pad and every landing point (a draw
that is not is drawn again from the same stream, so the world stays a function of the seed).

``python -m tools.encounters --seed K [--kind KIND] [--vehicles N] [--manned|--no-manned] --out W.yaml`` writes
one; ``python -m tools.run --world W.yaml --stagger-s S`` flies it (S printed by the first command).
"""

from __future__ import annotations

import argparse
import itertools
import math
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import yaml

KINDS = ("head_on", "crossing", "overtaking", "vertical", "converging")
HOME = {"lat_deg": 47.3977, "lon_deg": 8.5456, "alt_m": 488.0}
CRUISE_ALT_M = 15.0
HALF_LEG_M = 60.0
LANE_M = 14.0
MIN_PAD_GAP_M = 10.0
DEPOT_PAD_GAP_M = 14.0  # the UAV separation volume (10 m) and a margin: neighbouring depot landings stay clear
FENCE_RADIUS_M = 300.0
MANNED_ONE_IN = 6
VERTICAL_LOW_M = 10.0
VERTICAL_HIGH_M = 24.0
VERTICAL_WINDOW_M = 8.0
_ROUTE_TRIES = 20
_STREAM = 23  # the second word of the generator's seed: this module's own stream


@dataclass(frozen=True, slots=True)
class Encounter:
    """One drawn encounter: its fleet world document and the take-off stagger to fly it with."""

    seed: int
    kind: str
    vehicles: int
    manned: bool
    stagger_s: float
    world: dict[str, Any]

    def yaml_text(self) -> str:
        head = f"# encounter seed {self.seed}: {self.kind}, {self.vehicles} vehicles, manned {self.manned}, "
        head += f"stagger {self.stagger_s:g} s (python -m tools.encounters)\n"
        return head + yaml.safe_dump(self.world, sort_keys=False, default_flow_style=None, width=120)


@dataclass(frozen=True, slots=True)
class _Route:
    start_ne_m: tuple[float, float]
    end_ne_m: tuple[float, float]
    alt_start_m: float = CRUISE_ALT_M
    alt_end_m: float = CRUISE_ALT_M
    speed_m_s: float = 5.0
    via: tuple[tuple[float, float, float], ...] = ()  # (north, east, alt) waypoints before the far end


def encounter_world(
    seed: int, kind: str | None = None, vehicles: int | None = None, manned: bool | None = None
) -> Encounter:
    """The encounter of ``seed`` (ValueError for an unknown kind or a count outside 2..8)."""
    rng = np.random.default_rng([seed, _STREAM])
    drawn_kind = KINDS[int(rng.integers(len(KINDS)))]
    drawn_n = int(rng.integers(2, 9))
    drawn_manned = bool(rng.integers(MANNED_ONE_IN) == 0)
    kind = kind or drawn_kind
    n = vehicles if vehicles is not None else drawn_n
    manned = drawn_manned if manned is None else manned
    if kind not in KINDS:
        raise ValueError(f"unknown encounter kind {kind!r}; choose one of {', '.join(KINDS)}")
    if not 2 <= n <= 8:
        raise ValueError(f"an encounter has 2 to 8 vehicles, got {n}")
    course_rad = float(rng.uniform(0.0, 2.0 * math.pi))
    stagger_s = round(float(rng.uniform(2.0, 6.0)), 1) if kind == "converging" else 0.0
    for _ in range(_ROUTE_TRIES):  # a draw that puts pads too close (rare: many crossing courses) is drawn again
        routes = [_rotated(r, course_rad) for r in _ROUTES[kind](rng, n)]
        if _pads_clear(routes):
            break
    else:
        raise AssertionError(f"seed {seed}: no {kind} geometry with pads {MIN_PAD_GAP_M} m apart (generator bug)")
    world: dict[str, Any] = {
        "name": f"encounter_{seed}",
        "home": dict(HOME),
        "vehicle": "x500",
        "world": {"wind": {"north_m_s": 0.0, "east_m_s": 0.0, "down_m_s": 0.0, "gust_m_s": 0.3, "seed": seed}},
        "vehicles": [_vehicle(f"uav{i}", r) for i, r in enumerate(routes)],
    }
    if manned:
        world["traffic"] = [_manned(rng)]
    return Encounter(seed, kind, n, manned, stagger_s, world)


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
    routes = []
    for i in range(n):
        course = i * spacing + float(rng.uniform(-0.3, 0.3)) * spacing
        u = (math.cos(course), math.sin(course))
        offset = float(rng.uniform(-4.0, 4.0))  # across the course: they meet near, not at, the centre
        side = (-u[1] * offset, u[0] * offset)
        start = (-HALF_LEG_M * u[0] + side[0], -HALF_LEG_M * u[1] + side[1])
        far = HALF_LEG_M + LANE_M  # past the circle of pads: never on another's pad
        end = (far * u[0] + side[0], far * u[1] + side[1])
        routes.append(_Route(start, end))
    return routes


def _overtaking(rng: np.random.Generator, n: int) -> list[_Route]:
    routes = []
    for i in range(n):  # vehicle i starts i lanes back, flies faster and lands i lanes further on
        lateral = float(rng.uniform(-2.0, 2.0))
        speed = 3.0 + 5.0 * i / (n - 1)
        routes.append(_Route((-HALF_LEG_M - i * LANE_M, lateral), (HALF_LEG_M + i * LANE_M, lateral), speed_m_s=speed))
    return routes


def _converging(rng: np.random.Generator, n: int) -> list[_Route]:
    radius = 1.5 * HALF_LEG_M
    slice_rad = 2.0 * math.pi / n
    depot = [((k // 3 - 1) * DEPOT_PAD_GAP_M, (k % 3 - 1) * DEPOT_PAD_GAP_M) for k in (4, 1, 7, 3, 5, 0, 2, 6, 8)]
    routes = []
    for i in range(n):
        bearing = i * slice_rad + float(rng.uniform(-0.25, 0.25)) * slice_rad
        start = (radius * math.cos(bearing), radius * math.sin(bearing))
        routes.append(_Route(start, depot[i]))
    return routes


_ROUTES = {
    "head_on": _head_on,
    "crossing": _crossing,
    "overtaking": _overtaking,
    "vertical": lambda rng, n: _head_on(rng, n, climb=True),
    "converging": _converging,
}


def _rotated(route: _Route, course_rad: float) -> _Route:
    c, s = math.cos(course_rad), math.sin(course_rad)

    def rot(p: tuple[float, float]) -> tuple[float, float]:
        return (round(c * p[0] - s * p[1], 2), round(s * p[0] + c * p[1], 2))

    via = tuple((*rot((n, e)), alt) for n, e, alt in route.via)
    return _Route(rot(route.start_ne_m), rot(route.end_ne_m), route.alt_start_m, route.alt_end_m, route.speed_m_s, via)


def _pads_clear(routes: list[_Route]) -> bool:
    """Every pad at least MIN_PAD_GAP_M from every other pad and from every other vehicle's landing point."""
    return all(
        math.dist(point, b.start_ne_m) >= MIN_PAD_GAP_M - 1e-6
        for a, b in itertools.permutations(routes, 2)
        for point in (a.start_ne_m, a.end_ne_m)
    )


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


def _manned(rng: np.random.Generator) -> dict[str, Any]:
    rotorcraft = bool(rng.integers(2) == 0)
    speed = float(rng.uniform(30.0, 60.0))
    course = float(rng.uniform(0.0, 2.0 * math.pi))
    over_centre_s = float(rng.uniform(20.0, 50.0))
    alt = round(float(rng.uniform(25.0, 50.0)), 1)
    offset = float(rng.uniform(-30.0, 30.0))
    u, side = (math.cos(course), math.sin(course)), (-math.sin(course) * offset, math.cos(course) * offset)
    reach = speed * over_centre_s  # it starts at sim time 0 this far before the centre and flies as far past it
    point = [
        {"north_m": round(side[0] + k * reach * u[0], 1), "east_m": round(side[1] + k * reach * u[1], 1), "alt_m": alt}
        for k in (-1, 1)
    ]
    return {
        "callsign": "HELI1" if rotorcraft else "PLANE1",
        "icao": 0xA1B2C3,
        "emitter": "rotorcraft" if rotorcraft else "light",
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
    print(f"{args.out}: {enc.kind}, {enc.vehicles} vehicles, manned {enc.manned}; fly it with: python -m "
          f"tools.run --world {args.out} --stagger-s {enc.stagger_s:g}")  # fmt: skip
    return 0


if __name__ == "__main__":
    sys.exit(main())
