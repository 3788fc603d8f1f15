"""Which obstacle-sensor detections are tracked vehicles (SPEC §13): a detection whose volume centre lies where a
track is predicted to be is that vehicle, seen (DAA sensor fusion: the cooperative report says who it is, the
sensor where it is now).

A fleet vehicle's camera sees its neighbours as it sees obstacles; kept as obstacles, a moving vehicle is a static
volume smeared along its path to the obstacle planner (which then detours around, and bypasses waypoints inside,
where the vehicle was), while the traffic layer, which does avoid it, flies on a report a second old. Associated,
the detection is a fix of the track (:meth:`TrackTable.observe`) and is not an obstacle.

Gating (per frame, greedy by distance, one detection per track and one track per detection): the distance from the
detection's centre to the track's position at the detection's time must be within ``GATE_M`` plus the track's
accuracy (twice its 1-sigma) plus how far an unreported manoeuvre takes it since its report
(``MANOEUVRE_M_S2 · age² / 2``); a sensor id associated before keeps its track within twice that (a tracker's
object id is stable). Only sphere-like detections (a column stands on the ground), and for a UAV track only one
no larger than a small UAS (``MAX_UAV_RADIUS_M``): a floating obstacle the vehicle passes near is not taken for it
(the gate of a report 2 s old reaches 8 m).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

from autopilot.traffic.tracks import TrackKey, TrafficTrack
from mavlink_bridge.contract.frames import Vec3
from mavlink_bridge.contract.traffic import TrafficSource

#: The gate's fixed part (m): a quad's size and the camera's and both estimators' position errors.
GATE_M = 2.0
#: The acceleration (m/s^2) a track may have flown since its report without saying it.
MANOEUVRE_M_S2 = 3.0
#: A track's fix accuracy (1-sigma, m): ``FIX_SIGMA_M + FIX_SIGMA_PER_M2 · range²`` (stereo depth noise grows with
#: the square of the range; the fixed part is this vehicle's own estimator error).
FIX_SIGMA_M = 0.3
FIX_SIGMA_PER_M2 = 0.001
#: A detection larger than this (radius, m) is not a UAV: a 25 kg multirotor spans under 3 m.
MAX_UAV_RADIUS_M = 1.5
#: The gate of a sensor id associated with the track before (a tracker's object id is stable).
HELD_GATE_FACTOR = 2.0


def gate_m(track: TrafficTrack, t_us: int) -> float:
    """How far (m) a detection at ``t_us`` may lie from ``track``'s prediction and still be it (a sensor id
    associated with this track before: ``HELD_GATE_FACTOR`` times that)."""
    age_s = max(t_us - track.t_us, 0) * 1e-6
    acc = track.h_acc_m if math.isfinite(track.h_acc_m) else 0.0
    return GATE_M + 2.0 * acc + 0.5 * MANOEUVRE_M_S2 * age_s * age_s


def fix_sigma_m(range_m: float) -> float:
    """1-sigma (m) of a fix seen at ``range_m``."""
    return FIX_SIGMA_M + FIX_SIGMA_PER_M2 * range_m * range_m


def associate(tracks: Sequence[TrafficTrack], t_us: int, centers_home_ned_m: Sequence[Vec3 | None],
              radii_m: Sequence[float], sensor_ids: Sequence[int],
              held: Mapping[int, TrackKey]) -> dict[int, TrackKey]:  # fmt: skip
    """Detection index -> track key for the detections (centres about home, None: not a vehicle's shape; radii)
    that are tracked vehicles; ``held``: sensor id -> track key of earlier associations."""
    pairs: list[tuple[float, int, int]] = []
    predicted = [track.position_at(t_us) for track in tracks]
    gates = [gate_m(track, t_us) for track in tracks]
    for i, (center, radius, sensor_id) in enumerate(zip(centers_home_ned_m, radii_m, sensor_ids, strict=True)):
        if center is None:
            continue
        key = held.get(sensor_id)
        for k, (track, p) in enumerate(zip(tracks, predicted, strict=True)):
            if track.source is TrafficSource.UAV and radius > MAX_UAV_RADIUS_M:
                continue
            d = math.dist(center, p)
            if d <= (HELD_GATE_FACTOR * gates[k] if key == track.key else gates[k]):
                pairs.append((d, i, k))
    pairs.sort()
    out: dict[int, TrackKey] = {}
    taken: set[int] = set()
    for _, i, k in pairs:
        if i in out or k in taken:
            continue
        out[i] = tracks[k].key
        taken.add(k)
    return out
