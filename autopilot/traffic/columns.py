"""Column checks (SPEC §13): when a track, flying straight, enters a vertical column about the vehicle: the climb-out
column above a pad, the column below a landing, the band of levels an altitude change crosses
(:class:`autopilot.navigation.traffic_guard.TrafficGuard` holds the take-off, the landing or the change while one
does)."""

from __future__ import annotations

import math

from autopilot.traffic.cpa import predict_approach
from autopilot.traffic.param_decls import SeparationVolume, TrafficParams
from autopilot.traffic.rules import COLUMN_SPEED_M_S, parked
from autopilot.traffic.tracks import TrafficTrack
from mavlink_bridge.contract.frames import Vec3
from mavlink_bridge.contract.traffic import TrafficSource

#: The column checks look this far past the time to climb or descend through the column (s).
COLUMN_MARGIN_S = 5.0
#: The altitude-change corridor: a climb or descent faster than CORRIDOR_MIN_M_S is checked over the band it would
#: cross in CORRIDOR_S (s), within CORRIDOR_S + COLUMN_MARGIN_S, against tracks passing by (relative horizontal
#: speed at least COLUMN_SPEED_M_S: one that keeps station over or under the vehicle is the reactive layer's).
CORRIDOR_S = 5.0
CORRIDOR_MIN_M_S = 0.5


def column_conflict(track: TrafficTrack, t_us: int, pos_home_ned_m: Vec3, top_down_m: float, window_s: float,
                    params: TrafficParams, level: bool = False, bottom_down_m: float = 0.0,
                    own_vel_ned_m_s: Vec3 = (0.0, 0.0, 0.0)) -> float | None:  # fmt: skip
    """Seconds until ``track`` (flying straight; ``level``: at its altitude) enters the column above (or below) the
    vehicle, from ``bottom_down_m`` (default the ground) up to ``top_down_m`` (NED about home) grown by its class's
    volume, within ``window_s``; None if it does not. The column moves with the vehicle's horizontal velocity
    ``own_vel_ned_m_s`` (still by default); the track flies its :attr:`~TrafficTrack.steady_vel_ned_m_s`. It is
    one cylinder about its middle, so the closest-approach prediction (:func:`predict_approach`) says."""
    volume = (params.manned if track.source is TrafficSource.MANNED else params.uav).grown(params.margin)
    middle_down_m = 0.5 * (top_down_m + bottom_down_m)
    p = track.position_at(t_us)
    rel = (p[0] - pos_home_ned_m[0], p[1] - pos_home_ned_m[1], p[2] - middle_down_m)
    column = SeparationVolume(volume.hor_m, 0.5 * abs(top_down_m - bottom_down_m) + volume.ver_m)
    v, own = track.steady_vel_ned_m_s, own_vel_ned_m_s
    rel_vel = (v[0] - own[0], v[1] - own[1], 0.0 if level else v[2])
    approach = predict_approach(rel, rel_vel, window_s, column)
    return approach.loss_in_s if approach.conflict else None


def corridor_threat(t_us: int, pos_home_ned_m: Vec3, pref_ned_m_s: list[float], tracks: tuple[TrafficTrack, ...],
                    params: TrafficParams) -> str | None:  # fmt: skip
    """The altitude-change corridor: the track passing by that is predicted through the band of levels the climb or
    descent ``pref_ned_m_s[2]`` enters within ``CORRIDOR_S`` (from the edge of the vehicle's own volume on, moving
    with its horizontal velocity); None when clear or the change is within its own volume."""
    own_ver_m = params.uav.grown(params.margin).ver_m
    pref = pref_ned_m_s
    change_m = pref[2] * CORRIDOR_S
    if abs(change_m) <= own_ver_m:
        return None
    near = pos_home_ned_m[2] + (own_ver_m if pref[2] > 0.0 else -own_ver_m)
    far = pos_home_ned_m[2] + change_m
    window = CORRIDOR_S + COLUMN_MARGIN_S
    for track in tracks:
        if parked(track, t_us):
            continue
        v = track.steady_vel_ned_m_s
        if math.hypot(v[0] - pref[0], v[1] - pref[1]) < COLUMN_SPEED_M_S:
            continue  # keeps station over or under the vehicle: holding would wait for ever (the layer's)
        own_vel = (pref[0], pref[1], 0.0)
        if column_conflict(track, t_us, pos_home_ned_m, far, window, params, False, near, own_vel) is not None:
            return track.name
    return None
