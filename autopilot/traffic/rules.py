"""Right of way and the sense of a resolution: rules two quadsitl vehicles apply alike without talking.

- Who gives way (:func:`role`): manned traffic always has right of way; a UAV hovering or landing (slower than
  ``COLUMN_SPEED_M_S``, :func:`owns_column`) has it over a moving one (ICAO Annex 2 3.2.2.5: aircraft landing have
  right of way), and its separation volume reaches down to the ground, because a multirotor at a drop point may
  descend to land at any moment and its report says nothing of that; between two UAVs otherwise the higher
  system id gives way (one total order both agree on whatever each measures), and in a head-on encounter both
  give way (ICAO rules of the air). The stand-on vehicle keeps its route unless the conflict is still there
  ``LAST_RESORT_S`` before the loss of separation; then it resolves too, with the same rules.
- Which way (:func:`lateral_sense`, :func:`climbs`): away from where the other will be at the closest approach
  (widen the predicted miss: once one vehicle has moved, the other, seeing the grown miss, moves the same way
  apart, never back across). When the miss is too small to have a side (a collision course), to the right of the
  vehicle's velocity *relative to the other* (``v_own − v_other``): the other vehicle's relative velocity is the
  exact opposite, so its "right" is the opposite world direction (ICAO: both turn right). Vertically likewise:
  away from the other's level, and on one level the lower system id climbs, the higher descends. In every case
  the two displacements are opposite and add up, never cancel (no mirroring); ``docs/traffic_avoidance.md`` argues it.
"""

from __future__ import annotations

import math
from enum import Enum

from autopilot.traffic.tracks import TrafficTrack
from mavlink_bridge.contract.frames import Vec3
from mavlink_bridge.contract.traffic import TrafficSource

#: The stand-on vehicle resolves a conflict still predicted this soon (s before the loss of separation).
LAST_RESORT_S = 8.0
#: Head-on: the velocities differ by more than this angle and the other lies within HEAD_ON_CONE_DEG of the nose.
HEAD_ON_DEG = 150.0
HEAD_ON_CONE_DEG = 30.0
#: Below this horizontal speed (m/s) a velocity has no direction.
MIN_SPEED_M_S = 0.5
#: A UAV slower than this horizontally (m/s) hovers, stops or lands: it owns the column below it.
COLUMN_SPEED_M_S = 1.0
#: A track lower than this above home (m) and slower than PARKED_SPEED_M_S (m/s) stands on the ground.
PARKED_AGL_M = 1.5
PARKED_SPEED_M_S = 0.5
#: A predicted miss smaller than this has no side: horizontal (m) and vertical (m).
MISS_DEADBAND_M = 2.0
VER_DEADBAND_M = 1.0


class Role(Enum):
    GIVE_WAY = "giving way"
    STAND_ON = "standing on"


def _angle_deg(a: tuple[float, float], b: tuple[float, float]) -> float:
    na, nb = math.hypot(*a), math.hypot(*b)
    cos = (a[0] * b[0] + a[1] * b[1]) / (na * nb)
    return math.degrees(math.acos(max(-1.0, min(1.0, cos))))


def head_on(own_vel_ned_m_s: Vec3, track_vel_ned_m_s: Vec3, rel_pos_ned_m: Vec3) -> bool:
    """Both moving, nearly opposite courses, the other ahead within the cone of the nose."""
    vo, vt = own_vel_ned_m_s[:2], track_vel_ned_m_s[:2]
    if math.hypot(*vo) < MIN_SPEED_M_S or math.hypot(*vt) < MIN_SPEED_M_S or math.hypot(*rel_pos_ned_m[:2]) < 1e-6:
        return False
    return _angle_deg(vo, vt) > HEAD_ON_DEG and _angle_deg(vo, rel_pos_ned_m[:2]) < HEAD_ON_CONE_DEG


def owns_column(track: TrafficTrack) -> bool:
    """A UAV hovering, stopping or landing (horizontal speed below ``COLUMN_SPEED_M_S``): it may descend to land
    at any moment, so its separation volume reaches down to the ground and it has right of way over moving UAVs."""
    return track.source is TrafficSource.UAV and math.hypot(*track.steady_vel_ned_m_s[:2]) < COLUMN_SPEED_M_S


def parked(track: TrafficTrack, t_us: int) -> bool:
    """Standing still at home level (a vehicle on its pad): surface traffic, not avoided in the air and never a
    conflict (the operator's business; it still counts for the simulator's contacts)."""
    n, e, d = track.steady_vel_ned_m_s
    return -track.position_at(t_us)[2] < PARKED_AGL_M and math.hypot(n, e) < PARKED_SPEED_M_S and abs(d) < 0.5


def reciprocates(track: TrafficTrack) -> bool:
    """A quadsitl vehicle flying on: it takes half of every change. Manned traffic and a UAV that owns its column
    (taking off, landing, holding: :func:`owns_column`) do not, so the vehicle takes all of it."""
    return track.source is TrafficSource.UAV and not owns_column(track)


def role(own_system_id: int, track: TrafficTrack, own_vel_ned_m_s: Vec3, rel_pos_ned_m: Vec3) -> Role:
    """Give way to manned traffic always; to a hovering or landing UAV when moving; to a UAV with a lower system
    id; both give way head-on. (The hovering rule only adds give-way duties: two vehicles that classify each
    other's speed differently near the threshold at worst both give way, never both stand on.)"""
    if track.source is TrafficSource.MANNED or own_system_id >= track.target_id:
        return Role.GIVE_WAY
    if owns_column(track) and math.hypot(*own_vel_ned_m_s[:2]) >= COLUMN_SPEED_M_S:
        return Role.GIVE_WAY
    if head_on(own_vel_ned_m_s, track.steady_vel_ned_m_s, rel_pos_ned_m):
        return Role.GIVE_WAY
    return Role.STAND_ON


def right_of_encounter(
    rel_pos_ned_m: Vec3, rel_vel_ned_m_s: Vec3, own_system_id: int, other_id: int
) -> tuple[float, float]:
    """Unit horizontal (north, east) direction the vehicle moves to resolve: right of its velocity relative to
    the other (``−rel_vel``, ``rel_*`` = other − own); with no relative motion, away from the other; with
    neither, east for the lower system id and west for the higher."""
    un, ue = -rel_vel_ned_m_s[0], -rel_vel_ned_m_s[1]
    speed = math.hypot(un, ue)
    if speed >= MIN_SPEED_M_S:
        return (-ue / speed, un / speed)  # right of (n, e) is (-e, n)
    dist = math.hypot(rel_pos_ned_m[0], rel_pos_ned_m[1])
    if dist > 1e-3:
        return (-rel_pos_ned_m[0] / dist, -rel_pos_ned_m[1] / dist)
    return (0.0, 1.0) if own_system_id < other_id else (0.0, -1.0)


def lateral_sense(miss_ne_m: tuple[float, float], rel_pos_ned_m: Vec3, rel_vel_ned_m_s: Vec3, own_system_id: int,
                  other_id: int) -> tuple[float, float]:  # fmt: skip
    """Unit horizontal direction to move: away from the other's predicted position at the closest approach
    (``miss_ne_m``, other − own), or :func:`right_of_encounter` when the miss is inside the deadband."""
    miss = math.hypot(*miss_ne_m)
    if miss >= MISS_DEADBAND_M:
        return (-miss_ne_m[0] / miss, -miss_ne_m[1] / miss)
    return right_of_encounter(rel_pos_ned_m, rel_vel_ned_m_s, own_system_id, other_id)


def climbs(own_system_id: int, track: TrafficTrack, ver_cpa_m: float, up_m: float, down_m: float) -> bool:
    """The vertical sense. From manned traffic: the sense needing the smaller altitude change (``up_m``/``down_m``).
    From a UAV: away from its level at the closest approach (``ver_cpa_m``, other − own, NED down: > 0 when it is
    below); on one level (deadband) the lower system id climbs."""
    if track.source is TrafficSource.MANNED:
        return up_m <= down_m
    if abs(ver_cpa_m) >= VER_DEADBAND_M:
        return ver_cpa_m > 0.0
    return own_system_id < track.target_id
