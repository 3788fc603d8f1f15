"""Route planning on the known world: shortest paths around fences and known obstacles (SPEC §7, issue 13).

A visibility graph in the horizontal plane. Every exclusion zone (circles, polygons) is inflated by
``margin_m`` into a polygon that contains its offset region (a circle becomes the circumscribed
``circle_sides``-gon of radius ``r + margin``; a polygon's corners are mitred, or bevelled when sharp).
Known obstacles (the avoidance map's tracked cylinders and spheres) become inflated discs of radius
``r + r_safe + margin``, and block a leg only when their vertical extent (widened by ``r_safe``) meets the
leg's altitude band; what the vehicle can fly over does not block it. Inclusion zones are shrunk by the
margin (a circle becomes its inscribed polygon) and their edges may not be crossed.

Graph nodes are the inflated polygons' convex corners (the inclusion polygons' reflex corners), pushed
``NODE_PUSH_M`` off the boundary; an edge is a segment that properly crosses no polygon edge. A* with
the Euclidean heuristic expands lazily: visibility from a node to every open node is one vectorised test.
:class:`KnownWorld` is built once per event (fence upload, home, a newly tracked obstacle) and then answers
:meth:`KnownWorld.route` queries. Positions are NED about home (m); altitudes above home are ``-down``.
"""

from __future__ import annotations

import heapq
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from autopilot.geofence.fence import CircleZone, FenceZone, Geofence, PolygonZone, zone_label

#: Graph nodes sit this far outside the inflated boundary (so a path along a boundary never "crosses" it).
NODE_PUSH_M = 0.05
#: A corner whose mitre would reach further than this many margins is bevelled (two nodes) instead.
MITRE_LIMIT = 2.0


@dataclass(frozen=True, slots=True)
class ObstacleDisc:
    """A known obstacle as the route planner sees it: a vertical column (altitudes above home, m)."""

    center_ne_m: tuple[float, float]
    radius_m: float
    bottom_alt_m: float = -math.inf
    top_alt_m: float = math.inf
    label: str = "obstacle"


@dataclass(frozen=True, slots=True)
class RouteResult:
    """A planned route: ``path_ned_m`` (n, 3) from start to goal (both included), or why there is none."""

    path_ned_m: np.ndarray | None
    length_m: float
    reason: str = ""  # empty when a route was found

    @property
    def ok(self) -> bool:
        return self.path_ned_m is not None

    @property
    def vias_ned_m(self) -> np.ndarray:
        """The intermediate points (without start and goal), (k, 3); empty when the straight leg is clear."""
        if self.path_ned_m is None:
            return np.zeros((0, 3))
        return self.path_ned_m[1:-1]


def _signed_area(v: np.ndarray) -> float:
    x, y = v[:, 0], v[:, 1]
    return 0.5 * float(np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y))


def _offset_polygon(vertices: np.ndarray, offset_m: float) -> tuple[np.ndarray, np.ndarray]:
    """Polygon offset outward by ``offset_m`` (inward when negative), mitred corners, bevelled when sharp.

    Returns the offset vertices (counter-clockwise in (north, east) as x, y) and, per vertex, whether the
    corner is convex (True) seen from outside the original polygon.
    """
    v = np.asarray(vertices, float)
    if _signed_area(v) < 0.0:
        v = v[::-1]
    out: list[np.ndarray] = []
    convex: list[bool] = []
    n = len(v)
    for i in range(n):
        prev, cur, nxt = v[i - 1], v[i], v[(i + 1) % n]
        u1 = cur - prev
        u2 = nxt - cur
        l1, l2 = float(np.hypot(*u1)), float(np.hypot(*u2))
        if l1 < 1e-9 or l2 < 1e-9:
            continue
        u1, u2 = u1 / l1, u2 / l2
        n1 = np.array((u1[1], -u1[0]))  # outward normal of a CCW polygon
        n2 = np.array((u2[1], -u2[0]))
        is_convex = float(u1[0] * u2[1] - u1[1] * u2[0]) > 0.0
        bis = n1 + n2
        nb = float(np.hypot(*bis))
        cos_half = nb / 2.0
        if offset_m == 0.0:
            out.append(cur.copy())
        elif nb > 1e-9 and 1.0 / cos_half <= MITRE_LIMIT:
            out.append(cur + bis / nb * (offset_m / cos_half))
        elif (offset_m > 0.0) == is_convex:  # sharp corner pointing outward: bevel
            out.append(cur + offset_m * (n1 + u1))
            out.append(cur + offset_m * (n2 - u2))
            convex.append(is_convex)
        else:  # sharp corner pointing inward: the mitre point is safe
            out.append(cur + (bis / nb if nb > 1e-9 else n1) * (offset_m / max(cos_half, 1.0 / MITRE_LIMIT)))
        convex.append(is_convex)
    return np.array(out), np.array(convex, bool)


def _circle_polygon(center: Sequence[float], radius_m: float, sides: int, circumscribed: bool) -> np.ndarray:
    r = radius_m / math.cos(math.pi / sides) if circumscribed else radius_m
    k = np.arange(sides) * (2.0 * math.pi / sides)
    return np.column_stack((center[0] + r * np.cos(k), center[1] + r * np.sin(k)))


def _vertex_normals(poly: np.ndarray) -> np.ndarray:
    """Outward unit bisector at each vertex of a CCW polygon."""
    prev, nxt = np.roll(poly, 1, axis=0), np.roll(poly, -1, axis=0)
    u1, u2 = poly - prev, nxt - poly
    u1 /= np.maximum(np.linalg.norm(u1, axis=1), 1e-12)[:, None]
    u2 /= np.maximum(np.linalg.norm(u2, axis=1), 1e-12)[:, None]
    b = np.column_stack((u1[:, 1], -u1[:, 0])) + np.column_stack((u2[:, 1], -u2[:, 0]))
    return b / np.maximum(np.linalg.norm(b, axis=1), 1e-12)[:, None]


def _inside_polygon(points: np.ndarray, poly: np.ndarray) -> np.ndarray:
    """Even-odd test of points (m, 2) against one polygon (k, 2)."""
    x, y = points[:, 0][:, None], points[:, 1][:, None]
    xi, yi = poly[:, 0][None, :], poly[:, 1][None, :]
    xj, yj = np.roll(poly[:, 0], 1)[None, :], np.roll(poly[:, 1], 1)[None, :]
    with np.errstate(divide="ignore", invalid="ignore"):
        cross = ((yi > y) != (yj > y)) & (x < (xj - xi) * (y - yi) / (yj - yi) + xi)
    return (np.count_nonzero(cross, axis=1) % 2) == 1


@dataclass(frozen=True, slots=True)
class _Shape:
    poly: np.ndarray  # (k, 2) CCW, inflated (exclusion) or shrunk (inclusion)
    inclusion: bool
    bottom_alt_m: float
    top_alt_m: float
    label: str


class KnownWorld:
    """The fence and the known obstacles, inflated, ready for :meth:`route` queries (built once per event)."""

    def __init__(
        self,
        fence: Geofence,
        margin_m: float,
        obstacles: Sequence[ObstacleDisc] = (),
        *,
        circle_sides: int = 16,
        obstacle_sides: int = 8,
    ) -> None:
        if not (math.isfinite(margin_m) and margin_m >= 0.0):
            raise ValueError(f"route margin {margin_m} m must be finite and >= 0")
        self.fence = fence
        self.margin_m = margin_m
        self.obstacles = tuple(obstacles)
        shapes: list[_Shape] = []
        groups: dict[int, list[int]] = {}
        for k, zone in enumerate(fence.zones, start=1):
            label = zone_label(zone, k)
            if isinstance(zone, CircleZone):
                if zone.inclusion:
                    poly = _circle_polygon(zone.center_ne_m, max(zone.radius_m - margin_m, 0.0), circle_sides, False)
                else:
                    poly = _circle_polygon(zone.center_ne_m, zone.radius_m + margin_m, circle_sides, True)
            else:
                poly, _ = _offset_polygon(
                    np.asarray(zone.vertices_ne_m, float), -margin_m if zone.inclusion else margin_m
                )
            if zone.inclusion:
                groups.setdefault(zone.group, []).append(len(shapes))
            shapes.append(_Shape(poly, zone.inclusion, -math.inf, math.inf, label))
        for disc in self.obstacles:
            poly = _circle_polygon(disc.center_ne_m, disc.radius_m, obstacle_sides, True)
            shapes.append(_Shape(poly, False, disc.bottom_alt_m, disc.top_alt_m, disc.label))
        self._shapes = shapes
        self._groups = list(groups.values())
        starts, ends, owner, nodes, node_owner = [], [], [], [], []
        for s_i, shape in enumerate(shapes):
            poly = shape.poly
            if len(poly) < 3:
                continue
            starts.append(poly)
            ends.append(np.roll(poly, -1, axis=0))
            owner.append(np.full(len(poly), s_i))
            normals = _vertex_normals(poly)
            prev, nxt = np.roll(poly, 1, axis=0), np.roll(poly, -1, axis=0)
            turn = (poly[:, 0] - prev[:, 0]) * (nxt[:, 1] - poly[:, 1]) - (poly[:, 1] - prev[:, 1]) * (
                nxt[:, 0] - poly[:, 0]
            )
            if shape.inclusion:  # reflex corners of the allowed region, pushed inward
                keep = turn < 0.0
                pts = poly[keep] - NODE_PUSH_M * normals[keep]
            else:  # convex corners, pushed outward
                keep = turn > 0.0
                pts = poly[keep] + NODE_PUSH_M * normals[keep]
            nodes.append(pts)
            node_owner.append(np.full(len(pts), s_i))
        self._edge_a = np.concatenate(starts) if starts else np.zeros((0, 2))
        self._edge_b = np.concatenate(ends) if ends else np.zeros((0, 2))
        self._edge_owner = np.concatenate(owner) if owner else np.zeros(0, int)
        self._nodes = np.concatenate(nodes) if nodes else np.zeros((0, 2))
        self._node_owner = np.concatenate(node_owner) if node_owner else np.zeros(0, int)
        self._bottom = np.array([s.bottom_alt_m for s in shapes])
        self._top = np.array([s.top_alt_m for s in shapes])
        self._excl = np.array([not s.inclusion for s in shapes], bool)

    @property
    def empty(self) -> bool:
        return not self._shapes

    def polygons(self) -> list[tuple[np.ndarray, bool]]:
        """The inflated exclusion / shrunk inclusion polygons ((k, 2) north-east, inclusion flag), for drawing."""
        return [(s.poly, s.inclusion) for s in self._shapes]

    def _containing(self, p: np.ndarray, active: np.ndarray) -> np.ndarray:
        """Per shape: True when ``p`` is in its forbidden side (inside an inflated exclusion, outside a
        shrunk inclusion), among ``active`` shapes."""
        bad = np.zeros(len(self._shapes), bool)
        for s_i in np.flatnonzero(active):
            inside = bool(_inside_polygon(p[None, :2], self._shapes[s_i].poly)[0])
            bad[s_i] = inside if self._excl[s_i] else not inside
        return bad

    def route(self, start_ned: Sequence[float], goal_ned: Sequence[float], r_safe_m: float = 0.0) -> RouteResult:
        """The shortest horizontal path start → goal around the active shapes; altitude interpolated along it.

        Obstacles count when their extent widened by ``r_safe_m`` meets the leg's altitude band. A start or
        goal inside an inflated zone (but outside the zone itself) may leave / enter it. A goal inside an
        exclusion zone or outside every inclusion group, or a start/goal pair with no path, gives no route.
        """
        a = np.asarray(start_ned, float)[:3]
        b = np.asarray(goal_ned, float)[:3]
        if not (np.all(np.isfinite(a)) and np.all(np.isfinite(b))):
            return RouteResult(None, math.inf, "start or goal is not finite")
        lo_alt, hi_alt = -max(a[2], b[2]), -min(a[2], b[2])
        active = (self._bottom - r_safe_m <= hi_alt) & (self._top + r_safe_m >= lo_alt)
        fence = self.fence
        for k, zone in enumerate(fence.zones):
            if not zone.inclusion and zone.contains(b):
                return RouteResult(None, math.inf, f"goal inside {self._shapes[k].label}")
        if self._groups:
            group = self._group_for(a, b)
            if group is None:
                if fence.segment_clear(a, b):
                    return self._straight(a, b)
                return RouteResult(None, math.inf, "goal outside the inclusion fence")
            in_group = np.zeros(len(self._shapes), bool)
            in_group[group] = True
            active &= self._excl | in_group
        else:
            active &= self._excl
        free_a = ~self._containing(a, active)  # shapes the start may cross (it is already on their wrong side)
        free_b = ~self._containing(b, active)
        node_ok = active[self._node_owner] if len(self._nodes) else np.zeros(0, bool)
        nodes = self._nodes[node_ok]
        if len(nodes):  # drop nodes on the forbidden side of another active shape
            bad = np.zeros(len(nodes), bool)
            for s_i in np.flatnonzero(active):
                inside = _inside_polygon(nodes, self._shapes[s_i].poly)
                bad |= inside if self._excl[s_i] else ~inside
            nodes = nodes[~bad]
        pts = np.vstack((a[None, :2], b[None, :2], nodes))
        edge_on = active[self._edge_owner] if len(self._edge_owner) else np.zeros(0, bool)
        ea, eb, eo = self._edge_a[edge_on], self._edge_b[edge_on], self._edge_owner[edge_on]

        def exact(p: np.ndarray, q: np.ndarray) -> bool:
            return fence.segment_clear((p[0], p[1]), (q[0], q[1])) if fence.zones else True

        path = _astar(pts, ea, eb, eo, ~free_a, ~free_b, exact)
        if path is None:
            return RouteResult(None, math.inf, "no path around the fence and known obstacles")
        xy = pts[path]
        seg = np.linalg.norm(np.diff(xy, axis=0), axis=1)
        s = np.concatenate(([0.0], np.cumsum(seg)))
        total = float(s[-1])
        frac = s / total if total > 0.0 else np.zeros_like(s)
        down = a[2] + frac * (b[2] - a[2])
        return RouteResult(np.column_stack((xy, down)), total)

    def _straight(self, a: np.ndarray, b: np.ndarray) -> RouteResult:
        return RouteResult(np.vstack((a, b)), float(np.hypot(b[0] - a[0], b[1] - a[1])))

    def _group_for(self, a: np.ndarray, b: np.ndarray) -> list[int] | None:
        """The first inclusion group whose zones all contain both ends (the real zones, not shrunk)."""
        zones = self.fence.zones
        for group in self._groups:
            if all(zones[i].contains(a) and zones[i].contains(b) for i in group):
                return group
        return None


def _visible(
    p: np.ndarray, qs: np.ndarray, ea: np.ndarray, eb: np.ndarray, eo: np.ndarray, skip: np.ndarray
) -> np.ndarray:
    """For each q in ``qs``: True when segment p→q properly crosses no edge; edges of ``skip`` owners (shapes an
    end of the segment lies in) may be crossed once per such shape (leaving or entering it)."""
    if len(ea) == 0 or len(qs) == 0:
        return np.ones(len(qs), bool)
    d = qs - p  # (m, 2)
    ca, cb = ea - p, eb - p  # (k, 2)
    d1 = d[:, None, 0] * ca[None, :, 1] - d[:, None, 1] * ca[None, :, 0]
    d2 = d[:, None, 0] * cb[None, :, 1] - d[:, None, 1] * cb[None, :, 0]
    e = eb - ea
    pa = p - ea  # (k, 2)
    d3 = e[:, 0] * pa[:, 1] - e[:, 1] * pa[:, 0]  # (k,)
    qa = qs[:, None, :] - ea[None, :, :]
    d4 = e[None, :, 0] * qa[:, :, 1] - e[None, :, 1] * qa[:, :, 0]
    cross = (d1 * d2 <= 0.0) & (d3[None, :] * d4 <= 0.0) & ~((d1 == 0.0) & (d2 == 0.0))
    n_skip = int(np.count_nonzero(skip))
    if n_skip == 0:
        return ~cross.any(axis=1)
    on_skip = skip[eo]
    return ~cross[:, ~on_skip].any(axis=1) & (np.count_nonzero(cross[:, on_skip], axis=1) <= n_skip)


def _astar(
    pts: np.ndarray,
    ea: np.ndarray,
    eb: np.ndarray,
    eo: np.ndarray,
    skip_a: np.ndarray,
    skip_b: np.ndarray,
    exact: Callable[[np.ndarray, np.ndarray], bool],
) -> list[int] | None:
    """A* from node 0 to node 1 over the visibility graph of ``pts``; the node indices of the path.

    ``skip_a`` / ``skip_b``: shapes the start / goal lies in (their edges may be crossed once by a segment
    from the start / into the goal, which ``exact`` then checks against the zones themselves)."""
    n = len(pts)
    h = np.hypot(pts[:, 0] - pts[1, 0], pts[:, 1] - pts[1, 1])
    g = np.full(n, math.inf)
    g[0] = 0.0
    parent = np.full(n, -1)
    closed = np.zeros(n, bool)
    no_skip = np.zeros(len(skip_a), bool)
    start_skips, goal_skips = bool(skip_a.any()), bool(skip_b.any())
    heap = [(float(h[0]), 0)]
    while heap:
        _, u = heapq.heappop(heap)
        if closed[u]:
            continue
        if u == 1:
            path = [1]
            while path[-1] != 0:
                path.append(int(parent[path[-1]]))
            return path[::-1]
        closed[u] = True
        cand = np.flatnonzero(~closed)
        skip = skip_a if u == 0 else no_skip
        vis = _visible(pts[u], pts[cand], ea, eb, eo, skip)
        goal_j = int(np.searchsorted(cand, 1))
        has_goal = goal_j < len(cand) and cand[goal_j] == 1
        if goal_skips and has_goal:  # into the goal, its own containing shapes may be crossed once
            vis[goal_j] = bool(_visible(pts[u], pts[1:2], ea, eb, eo, skip | skip_b)[0])
        if (u == 0 and start_skips) or (goal_skips and has_goal):
            for j in np.flatnonzero(vis).tolist():
                if (u == 0 and start_skips) or j == goal_j:
                    vis[j] = exact(pts[u], pts[cand[j]])
        cand = cand[vis]
        if len(cand) == 0:
            continue
        cost = g[u] + np.hypot(pts[cand, 0] - pts[u, 0], pts[cand, 1] - pts[u, 1])
        better = cost < g[cand]
        for v, c in zip(cand[better].tolist(), cost[better].tolist(), strict=True):
            g[v] = c
            parent[v] = u
            heapq.heappush(heap, (c + float(h[v]), v))
    return None


def obstacle_discs(obstacles: Sequence[object], r_safe_m: float, margin_m: float) -> tuple[ObstacleDisc, ...]:
    """The avoidance map's tracked obstacles (``TrackedObstacle``) as discs inflated by ``r_safe + margin``."""
    discs = []
    for obs in obstacles:
        n, e, d = obs.center_ned  # type: ignore[attr-defined]
        r = float(obs.radius_m)  # type: ignore[attr-defined]
        kind = getattr(getattr(obs, "kind", None), "name", "")
        if kind == "SPHERE":
            bottom, top = -d - r, -d + r
        else:
            top_down = float(getattr(obs, "top_down", -math.inf))
            bottom, top = -math.inf, (-top_down if math.isfinite(top_down) else math.inf)
        oid = getattr(obs, "obstacle_id", -1)
        discs.append(ObstacleDisc((float(n), float(e)), r + r_safe_m + margin_m, bottom, top, f"obstacle {oid}"))
    return tuple(discs)


def zones_polygon_ne(zone: FenceZone, sides: int = 32) -> np.ndarray:
    """A zone's outline (north, east) for drawing: the polygon itself or a ``sides``-gon of a circle."""
    if isinstance(zone, PolygonZone):
        return np.asarray(zone.vertices_ne_m, float)
    return _circle_polygon(zone.center_ne_m, zone.radius_m, sides, False)
