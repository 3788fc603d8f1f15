"""Column checks (SPEC §13): when a track, flying straight, enters a vertical column about the vehicle: the climb-out
column above a pad, the column below a landing, the band of levels an altitude change crosses
(:class:`autopilot.navigation.traffic_guard.TrafficGuard` holds the take-off, the landing or the change while one
does)."""

from __future__ import annotations

from autopilot.traffic.cpa import predict_approach
from autopilot.traffic.param_decls import SeparationVolume, TrafficParams
from autopilot.traffic.tracks import TrafficTrack
from mavlink_bridge.contract.frames import Vec3
from mavlink_bridge.contract.traffic import TrafficSource


def column_conflict(track: TrafficTrack, t_us: int, pos_home_ned_m: Vec3, top_down_m: float, window_s: float,
                    params: TrafficParams, level: bool = False, bottom_down_m: float = 0.0,
                    own_vel_ned_m_s: Vec3 = (0.0, 0.0, 0.0)) -> float | None:  # fmt: skip
    """Seconds until ``track`` (flying straight; ``level``: at its altitude) enters the column above (or below) the
    vehicle, from ``bottom_down_m`` (default the ground) up to ``top_down_m`` (NED about home) grown by its class's
    volume, within ``window_s``; None if it does not. The column moves with the vehicle's horizontal velocity
    ``own_vel_ned_m_s`` (still by default). It is one cylinder about its middle, so the closest-approach prediction
    (:func:`predict_approach`) says."""
    volume = (params.manned if track.source is TrafficSource.MANNED else params.uav).grown(params.margin)
    middle_down_m = 0.5 * (top_down_m + bottom_down_m)
    p = track.position_at(t_us)
    rel = (p[0] - pos_home_ned_m[0], p[1] - pos_home_ned_m[1], p[2] - middle_down_m)
    column = SeparationVolume(volume.hor_m, 0.5 * abs(top_down_m - bottom_down_m) + volume.ver_m)
    v, own = track.vel_ned_m_s, own_vel_ned_m_s
    rel_vel = (v[0] - own[0], v[1] - own[1], 0.0 if level else v[2])
    approach = predict_approach(rel, rel_vel, window_s, column)
    return approach.loss_in_s if approach.conflict else None
