"""The reactive layer: every navigator step, the velocity that keeps separation from every track at once (SPEC §13).

Over all tracks together (not one conflict at a time), 3D optimal reciprocal collision avoidance (ORCA, van den
Berg et al. 2011; RVO2-3D): each track adds one half-space of admissible velocities (:func:`orca_planes`), the
vehicle's own limits add theirs (horizontal speed, climb and descent rates, the altitude floor and ceiling, no
sideways motion on the ground), and the admissible velocity closest to the one the vehicle would fly is taken
(:func:`closest_admissible`). When the preferred velocity is admissible nothing changes (no override).

- Responsibility: half of every change between two quadsitl vehicles that are both flying on (the other takes
  the other half: reciprocity); all of it toward manned traffic and toward a UAV that is taking off, landing or
  holding (horizontal speed below ``COLUMN_SPEED_M_S``), which may not react.
- Volumes: the class's separation cylinder (NAV_TRAFF_U_*/M_*, grown by NAV_TRAFF_MARGIN) is covered by a sphere
  in a space stretched vertically (:func:`covering_sphere`: a 10 m / 5 m volume needs 11.2 m level or 11.2 m
  stacked; the 150 m / 30 m NMAC volume 201 m level or 45 m stacked), grown by the report's age times the
  closing speed and by the vehicle's braking distance ``v^2 / (2 a)``.
- Horizons: ``UAV_TAU_S`` between vehicles, ``MANNED_TAU_S`` for manned aircraft (they are fast: leaving their
  path takes time).
- Fallback, when no admissible velocity exists: brake to a hover and escape vertically away from the most urgent
  track (above: down; below: up; level: the lower system id up, the higher down, manned traffic: away from it
  where the floor allows), never below the floor; both vehicles apply the same rule. The planes that stay hard
  are the UAVs', nearest first, then the manned aircraft's: a manned plane is given up before a UAV pair's.

Pure: no clock, no I/O; the compiled kernels do the arithmetic in preallocated arrays.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from enum import Enum
from typing import Protocol

import numpy as np

from autopilot.traffic.orca_kernel import (
    N_TRACK_COLS,
    T_RADIUS,
    T_SCALE,
    closest_admissible,
    least_violating,
    orca_planes,
)
from autopilot.traffic.param_decls import SeparationVolume, TrafficParams
from autopilot.traffic.rules import parked, reciprocates
from autopilot.traffic.tracks import TrafficTrack
from mavlink_bridge.contract.frames import Vec3
from mavlink_bridge.contract.traffic import TrafficSource

#: ORCA time horizons (s): between UAVs, and toward manned aircraft.
UAV_TAU_S = 8.0
MANNED_TAU_S = 40.0
#: How far, in half-heights, the sphere covering a volume reaches vertically: between UAVs the horizontal distance
#: matters most (sqrt(5): 1.118 x the radius level, 2.24 x the half-height stacked); toward manned aircraft the
#: vertical one (1.5 x the half-height, 1.34 x the radius level): a multirotor cannot outrun them.
UAV_REACH = math.sqrt(5.0)
MANNED_REACH = 1.5
#: The position uncertainty assumed of ADS-B reports (95 %, m): NACp 10 (EPU < 10 m, VEPU < 15 m; RTCA DO-242A,
#: DO-260A), what an SBAS position source declares.
ADSB_EPU_M = 10.0
ADSB_VEPU_M = 15.0
#: Sides of the polygon bounding the horizontal speed (circumscribed about the speed circle).
SPEED_SIDES = 16
#: The floor and ceiling are approached at most at this rate: the distance left over this time (s).
FLOOR_TIME_S = 2.0
#: Below this height above home the vehicle moves only vertically (m): no sideways motion near the ground.
GROUND_LOCK_AGL_M = 2.0
#: A velocity this close (m/s) to the preferred one is the preferred one (no override).
SAME_M_S = 0.02
#: Braking distance is counted up to this (m).
MAX_BRAKE_GROW_M = 8.0
#: Tracks held at most (the arrays are sized once).
MAX_TRACKS = 64
#: The vehicle's own half-spaces: the speed polygon, descent and climb rates, floor, ceiling, the ground lock's 4.
OWN_ROWS = SPEED_SIDES + 8
_ROWS = MAX_TRACKS + OWN_ROWS + 8
#: Fence zones nearer than this (m) bound the velocity (at most MAX_FENCE_ROWS of them); the edge's normal is
#: taken over FENCE_STEP_M.
FENCE_LOOK_M = 40.0
MAX_FENCE_ROWS = 8
FENCE_STEP_M = 0.5
#: A fence row counts the room from where the vehicle will be once it answers (s): its speed toward the edge times
#: this is taken off the room (a vehicle at 6-8 m/s with the room counted from where it was crossed a 300 m circle
#: by 2 m past a 3 m margin: encounter case 41).
FENCE_RESPONSE_S = 1.0
#: In the fallback every UAV's plane ranks before every manned aircraft's (added to the manned ratio).
MANNED_AFTER = 1.0e6
#: The offset of a half-space not in force (every velocity is on its side).
OFF = -1e9


class Phase(Enum):
    """What the vehicle is doing, for the reactive layer: the autonomous phases avoid; manual ones only warn."""

    TAKEOFF = "take-off"
    MISSION = "mission"
    HOLD = "hold"
    RETURN = "return"
    LAND = "landing"
    MANUAL = "manual"


class FenceZoneLike(Protocol):
    """What the layer reads of a geofence zone (``autopilot.geofence.fence.CircleZone``, ``PolygonZone``)."""

    def allowed_distance_m(self, pos_ned: Sequence[float]) -> float: ...


@dataclass(frozen=True, slots=True)
class ReactiveLimits:
    """What the vehicle can fly (m/s, m/s^2) and where (NED down about home, m: floor > ceiling numerically)."""

    speed_xy_m_s: float
    up_m_s: float
    down_m_s: float
    acc_m_s2: float
    floor_down_m: float
    ceiling_down_m: float
    fences: tuple[FenceZoneLike, ...] = ()  # the geofence's zones about home
    fence_margin_m: float = 3.0


@dataclass(frozen=True, slots=True)
class ReactiveCommand:
    """The velocity to fly instead of the preferred one (NED, m/s), why, and whether it is the fallback."""

    vel_ned_m_s: Vec3
    threat: str  # the track whose plane binds (or the most urgent one, in the fallback)
    fallback: bool
    escape: str = ""  # the fallback's vertical sense: "climbing", "descending" or "holding"


def uncertainty_m(track: TrafficTrack) -> tuple[float, float]:
    """How far (horizontal, vertical; m, about 95 %) the track may be from where it says: twice the 1-sigma
    accuracy a UAV's UTM report carries; for ADS-B, which carries none on MAVLink, an SBAS source's NACp 10 bounds."""
    if track.source is TrafficSource.MANNED:
        return ADSB_EPU_M, ADSB_VEPU_M
    h, v = track.h_acc_m, track.v_acc_m
    return (2.0 * h if math.isfinite(h) else 0.0), (2.0 * v if math.isfinite(v) else 0.0)


def covering_sphere(volume: SeparationVolume, reach: float) -> tuple[float, float]:
    """(radius, vertical stretch) of the sphere that covers the cylinder ``volume`` in the stretched space and
    reaches ``reach`` times its half-height vertically (> 1; its horizontal radius is then
    ``hor reach / sqrt(reach^2 - 1)``: a flat sphere for a flat volume, a round one for a tall one)."""
    scale = volume.hor_m / (volume.ver_m * math.sqrt(reach * reach - 1.0))
    return math.hypot(volume.hor_m, volume.ver_m * scale), scale


class ReactiveLayer:
    """ORCA over every track, one compiled solve per call; arrays allocated once."""

    def __init__(self, system_id: int) -> None:
        self.system_id = system_id
        self._tracks = np.zeros((MAX_TRACKS, N_TRACK_COLS))
        self._normals = np.zeros((_ROWS, 3))
        self._offsets = np.zeros(_ROWS)
        self._scratch = np.zeros(_ROWS)
        self._index = np.zeros(_ROWS, dtype=np.int64)
        self._pos = np.zeros(3)
        self._vel = np.zeros(3)
        self._pref = np.zeros(3)
        self._out = np.zeros(3)
        self._limits_out = np.zeros(3)
        self._params: TrafficParams | None = None
        self._rows: list[TrafficTrack] = []
        self._version: int | None = None
        self._m_hard = OWN_ROWS
        #: After a solve: by how much (m/s) the velocity flown keeps clear of the nearest track's plane (inf: no
        #: track in reach, 0: the layer binds); the guard solves less often while it is large.
        self.slack_m_s = math.inf
        angles = np.arange(SPEED_SIDES) * 2.0 * math.pi / SPEED_SIDES
        self._normals[:SPEED_SIDES] = np.stack((-np.cos(angles), -np.sin(angles), np.zeros(SPEED_SIDES)), axis=1)
        self._normals[SPEED_SIDES : OWN_ROWS] = ((0, 0, -1), (0, 0, 1), (0, 0, -1), (0, 0, 1), (1, 0, 0), (-1, 0, 0),
                                                 (0, 1, 0), (0, -1, 0))  # fmt: skip

    def solve(self, t_us: int, pos_home_ned_m: Vec3, vel_ned_m_s: Vec3, pref_ned_m_s: Vec3,
              tracks: Sequence[TrafficTrack], params: TrafficParams, limits: ReactiveLimits, phase: Phase,
              version: int | None = None, over_pad: bool = True) -> ReactiveCommand | None:  # fmt: skip
        """The velocity to fly now instead of ``pref_ned_m_s``, or None when the preferred one keeps separation.
        ``over_pad``: the vehicle is over a pad (leaving or coming to one): below ``GROUND_LOCK_AGL_M`` it moves only
        vertically there; elsewhere it keeps its sideways moves at any height above the floor.
        ``version``: the track table's (:attr:`TrackTable.version`); the same as last time reuses the rows."""
        if version is None or version != self._version or params is not self._params:
            self._load(t_us, tracks, params)
            self._version = version
        rows = self._rows
        pos, vel, pref = self._pos, self._vel, self._pref
        pos[:], vel[:], pref[:] = pos_home_ned_m, vel_ned_m_s, pref_ned_m_s
        self._own_limits(pos, limits, phase, over_pad)
        m = self._m_hard = OWN_ROWS + self._fence_rows(pos, vel, limits)
        closest_admissible(self._normals, self._offsets, m, pref, self._limits_out)
        if not rows:
            self.slack_m_s = math.inf
            return None
        speed2 = vel[0] * vel[0] + vel[1] * vel[1] + vel[2] * vel[2]
        brake_m = min(speed2 / (2.0 * limits.acc_m_s2), MAX_BRAKE_GROW_M)
        total = orca_planes(t_us * 1e-6, pos, vel, self._tracks, len(rows), brake_m, self._normals, self._offsets, m,
                            self._index)  # fmt: skip
        if total == m:
            self.slack_m_s = math.inf
            return None
        failed = closest_admissible(self._normals, self._offsets, total, pref, self._out)
        if failed >= 0:
            self.slack_m_s = 0.0
            return self._fallback(t_us, pos, rows, limits, phase, total)
        out, lim = self._out, self._limits_out
        if abs(out[0] - lim[0]) + abs(out[1] - lim[1]) + abs(out[2] - lim[2]) < SAME_M_S:
            self.slack_m_s = float((self._normals[m:total] @ out - self._offsets[m:total]).min())
            return None
        self.slack_m_s = 0.0
        return ReactiveCommand((float(out[0]), float(out[1]), float(out[2])), self._binding(rows, m, total), False)

    @property
    def limited_ned_m_s(self) -> Vec3:
        """After a solve: the admissible velocity closest to the preferred one under the vehicle's own limits and
        the fence alone (what a guard still engaged flies when no track binds: never toward the fence)."""
        out = self._limits_out
        return (float(out[0]), float(out[1]), float(out[2]))

    def keep_inside_fence(self, vel_ned_m_s: list[float]) -> bool:
        """Moves ``vel_ned_m_s`` (in place) onto the fence rows of the last solve: the velocity flown while it slews
        toward a command never heads toward the fence faster than the room allows. Each command keeps the fence,
        but the way to it need not: a command along the fence reversed while the velocity slewed at the acceleration
        limit per axis went through outward velocities for seconds (failure search of the depot with a
        helicopter, case 0: 9.6 m past a 300 m fence). True when it moved it."""
        normals, offsets = self._normals, self._offsets
        moved = False
        for row in range(OWN_ROWS, self._m_hard):
            n0, n1, n2 = float(normals[row, 0]), float(normals[row, 1]), float(normals[row, 2])
            short = float(offsets[row]) - (n0 * vel_ned_m_s[0] + n1 * vel_ned_m_s[1] + n2 * vel_ned_m_s[2])
            if short > 1e-9:
                vel_ned_m_s[0] += short * n0
                vel_ned_m_s[1] += short * n1
                vel_ned_m_s[2] += short * n2
                moved = True
        return moved

    def _load(self, t_us: int, tracks: Sequence[TrafficTrack], params: TrafficParams) -> None:
        """The rows of the tracks to avoid (parked ones left out), columns ``T_*`` of :mod:`orca_kernel`: each
        track's report, its class's volume grown by the margin and by its position uncertainty
        (:func:`uncertainty_m`), covered by its sphere."""
        self._params = params
        uav, manned = params.uav.grown(params.margin), params.manned.grown(params.margin)
        rows: list[TrafficTrack] = []
        table = self._tracks
        for track in tracks:
            if len(rows) == MAX_TRACKS or parked(track, t_us):
                continue
            is_manned = track.source is TrafficSource.MANNED
            base = manned if is_manned else uav
            hor_m, ver_m = uncertainty_m(track)
            radius, scale = covering_sphere(SeparationVolume(base.hor_m + hor_m, base.ver_m + ver_m),
                                            MANNED_REACH if is_manned else UAV_REACH)  # fmt: skip
            # the report itself: over ORCA's few seconds its velocity says more than its next waypoint (the kernel
            # extrapolates it and grows the sphere by what its age hides)
            resp, tau = 0.5 if reciprocates(track) else 1.0, MANNED_TAU_S if is_manned else UAV_TAU_S
            table[len(rows)] = (*track.pos_home_ned_m, *track.vel_ned_m_s, track.t_us * 1e-6, radius, scale, resp, tau)
            rows.append(track)
        self._rows = rows

    def _own_limits(self, pos: np.ndarray, limits: ReactiveLimits, phase: Phase, over_pad: bool = True) -> None:
        """The offsets of the vehicle's own half-spaces (rows 0..OWN_ROWS-1, normals set once; always feasible
        together: zero velocity satisfies them); a row not in force has an offset no velocity misses."""
        offsets = self._offsets
        # MPC_XY_VEL_MAX bounds any cruise asked for; the preferred velocity is no bound (while the layer flies, the
        # reference goes on from its own velocity: a bound from it would ratchet)
        offsets[:SPEED_SIDES] = -limits.speed_xy_m_s
        k = SPEED_SIDES
        offsets[k] = -limits.down_m_s  # vd <= down
        offsets[k + 1] = -limits.up_m_s  # vd >= -up
        # approach the floor at most at the rate that stops on it (none below it but in a landing), and the ceiling
        floor = -max((limits.floor_down_m - pos[2]) / FLOOR_TIME_S, 0.0)
        offsets[k + 2] = floor if phase is not Phase.LAND else OFF
        offsets[k + 3] = min((limits.ceiling_down_m - pos[2]) / FLOOR_TIME_S, 0.0)
        # up or down only near the ground (never skid across the pads): no horizontal velocity at all. Not "toward
        # the preferred one": while the layer flies, that is its own velocity, and a bound from it would ratchet.
        # Away from the pads a vehicle pushed down to the floor keeps its sideways moves (failure search of the depot
        # with a helicopter, case 3: two at the floor 260 m from their pads, one of them locked, came within 4.4 m).
        lock = 0.0 if over_pad and -pos[2] < GROUND_LOCK_AGL_M else OFF
        offsets[k + 4 : k + 8] = lock  # vn >= 0, -vn >= 0, ve >= 0, -ve >= 0

    def _fence_rows(self, pos: np.ndarray, vel: np.ndarray, limits: ReactiveLimits) -> int:
        """Half-spaces after the own limits for each fence zone within ``FENCE_LOOK_M``: no velocity toward its
        edge faster than crosses the room left beyond ``limits.fence_margin_m`` in ``FLOOR_TIME_S`` or than brakes
        to a stop in it at ``limits.acc_m_s2`` (none once there), the room counted from where the vehicle's own
        velocity takes it in ``FENCE_RESPONSE_S``;
        the edge's normal from the zone's distance, numerically. Zero velocity meets them all. Their count."""
        k = 0
        for zone in limits.fences:
            if k == MAX_FENCE_ROWS:
                break
            n, e = float(pos[0]), float(pos[1])
            room = zone.allowed_distance_m((n, e))
            if room > FENCE_LOOK_M:
                continue
            gn = (zone.allowed_distance_m((n + FENCE_STEP_M, e)) - room) / FENCE_STEP_M
            ge = (zone.allowed_distance_m((n, e + FENCE_STEP_M)) - room) / FENCE_STEP_M
            norm = math.hypot(gn, ge)
            if norm < 1e-6:
                continue
            row = OWN_ROWS + k  # g . v >= -speed: toward the edge only as fast as stops before it
            toward = max(-(gn * float(vel[0]) + ge * float(vel[1])) / norm, 0.0)  # m/s, to the edge
            left = max(room - limits.fence_margin_m - toward * FENCE_RESPONSE_S, 0.0)
            self._normals[row] = (gn / norm, ge / norm, 0.0)
            self._offsets[row] = -min(left / FLOOR_TIME_S, math.sqrt(2.0 * limits.acc_m_s2 * left))
            k += 1
        return k

    def _binding(self, rows: list[TrafficTrack], m: int, total: int) -> str:
        """The track whose plane the solution lies on (the most binding), for the texts."""
        slack = self._normals[m:total] @ self._out - self._offsets[m:total]
        return rows[int(self._index[m + int(np.argmin(slack))])].name

    def _vertical_reach(self, track: TrafficTrack) -> float:
        """How far (m) the sphere about ``track`` reaches vertically (its radius over its stretch)."""
        for k, row in enumerate(self._rows):
            if row is track:
                return float(self._tracks[k, T_RADIUS] / self._tracks[k, T_SCALE])
        return 0.0

    def _fallback(self, t_us: int, pos: np.ndarray, rows: list[TrafficTrack], limits: ReactiveLimits,
                  phase: Phase, total: int) -> ReactiveCommand:  # fmt: skip
        """Brake to a hover and escape vertically away from the most urgent track, never below the floor: that is
        the velocity wanted, and the one flown is the closest to it that keeps the vehicle's limits and violates
        every track's plane least (:func:`least_violating`), so the escape from one never runs into another."""
        worst, ratio = rows[0], math.inf
        params = self._params or TrafficParams()
        for track in rows:
            p = track.position_at(t_us)
            volume = params.manned if track.source is TrafficSource.MANNED else params.uav  # the volumes in force
            r = max(math.hypot(p[0] - pos[0], p[1] - pos[1]) / volume.hor_m, abs(p[2] - pos[2]) / volume.ver_m)
            if r < ratio:
                worst, ratio = track, r
        other = worst.position_at(t_us)
        below = other[2] - pos[2]  # > 0: the other is below (NED down)
        if abs(below) >= 1.0:
            up = below > 0.0
        elif worst.source is TrafficSource.MANNED:
            up = -pos[2] - (-limits.floor_down_m) < 5.0  # near the floor: up; else down
        else:
            up = self.system_id < worst.target_id
        # escape until the other's sphere is cleared vertically (not further), at most at the climb/descent rate
        reach_m = self._vertical_reach(worst)
        if phase is Phase.LAND or (phase is Phase.TAKEOFF and -pos[2] < GROUND_LOCK_AGL_M):
            vd, escape = 0.0, "holding"  # at the pad: hold the height (the column above is the other's)
        elif up:
            room = min(pos[2] - limits.ceiling_down_m, reach_m - below)  # > 0: to climb
            vd, escape = (-min(limits.up_m_s, room / FLOOR_TIME_S), "climbing") if room > 0.5 else (0.0, "holding")
        else:
            room = min(limits.floor_down_m - pos[2], reach_m + below)  # > 0: to descend
            vd, escape = (min(limits.down_m_s, room / FLOOR_TIME_S), "descending") if room > 0.5 else (0.0, "holding")
        if phase is Phase.TAKEOFF and -pos[2] < GROUND_LOCK_AGL_M:
            return ReactiveCommand((0.0, 0.0, 0.0), worst.name, True, escape)  # on the pad: stay there
        want, out = self._pref, self._out
        want[0], want[1], want[2] = 0.0, 0.0, vd
        hard = self._nearest_first(t_us, pos, rows, want, total)
        least_violating(self._normals, self._offsets, hard, total, want, self._scratch, out)
        return ReactiveCommand((float(out[0]), float(out[1]), float(out[2])), worst.name, True, escape)

    def _nearest_first(self, t_us: int, pos: np.ndarray, rows: list[TrafficTrack], want: np.ndarray,
                       total: int) -> int:  # fmt: skip
        """Orders the tracks' planes, every UAV's before every manned aircraft's, each nearest first (by the
        separation ratio in its volume), and returns how many rows, from the vehicle's own limits on, can be met
        together: those stay hard in the fallback and only the later planes are violated (least), instead of all
        of them alike (a crowd's far planes made the nearest pair's loose: encounter case 142). A UAV's plane
        before a manned one's: a helicopter 200 m off is nearer in its 150 m volume's measure than a UAV 16 m off
        in its 10 m one, but only the UAV can be met in seconds, and both vehicles of a pair keep their planes
        alike (failure search of the depot with a helicopter, case 3: two vehicles fleeing it at the floor, each
        keeping its plane and giving up the other's, came within 3.5 m)."""
        m = self._m_hard
        params = self._params or TrafficParams()
        ratio = self._scratch
        for row in range(m, total):
            track = rows[int(self._index[row])]
            p = track.position_at(t_us)
            volume = params.manned if track.source is TrafficSource.MANNED else params.uav
            ratio[row] = max(math.hypot(p[0] - pos[0], p[1] - pos[1]) / volume.hor_m, abs(p[2] - pos[2]) / volume.ver_m)
            if track.source is TrafficSource.MANNED:
                ratio[row] += MANNED_AFTER
        order = m + np.argsort(ratio[m:total], kind="stable")
        self._normals[m:total] = self._normals[order]
        self._offsets[m:total] = self._offsets[order]
        self._index[m:total] = self._index[order]
        failed = closest_admissible(self._normals, self._offsets, total, want, self._out)
        return total if failed < 0 else failed
