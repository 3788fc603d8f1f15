"""The vehicles' pairwise separations of one step in one numba call: the implementation of ``FleetSim``'s contact
and separation-volume bookkeeping (``sim.fleet``).

Per unordered pair (i < j), every step, with no allocation: the surface-to-surface gap (centre distance minus
both collision radii) folds into both vehicles' ``min_separation_m``; with both airborne, the separation in the
UAV volume's own measure, ``max(horizontal, vertical * hor / ver)`` between centres, folds into both vehicles'
``min_volume_sep_m``. A pair that touches for the first time (gap <= 0), or comes inside the volume for the first
time (measure < hor) while both fly or while one of them stands on the ground, is written to ``events`` for the
caller to name; the ``seen`` matrices keep each pair to one event of each kind.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

#: ``events`` row kinds
EVENT_CONTACT = 0
EVENT_VOLUME_AIRBORNE = 1
EVENT_VOLUME_GROUND = 2


@njit(cache=True)
def pair_separation_step(
    pos_ned: np.ndarray,
    radius_m: np.ndarray,
    on_ground: np.ndarray,
    volume_hor_m: float,
    volume_ver_m: float,
    min_separation_m: np.ndarray,
    min_volume_sep_m: np.ndarray,
    touching: np.ndarray,
    inside_seen: np.ndarray,
    inside_seen_ground: np.ndarray,
    events: np.ndarray,
) -> int:
    """Fold one step's pairs of ``pos_ned`` (n, 3) in; the number of new events written to ``events`` (rows of
    (i, j, kind), i < j, in pair order). ``radius_m`` (n,), ``on_ground`` (n,) bool; ``min_separation_m`` and
    ``min_volume_sep_m`` (n,), ``touching``, ``inside_seen`` and ``inside_seen_ground`` (n, n) bool are updated
    in place. With no vehicle airborne the volume is not measured at all."""
    n = pos_ned.shape[0]
    ratio = volume_hor_m / volume_ver_m
    any_airborne = False
    for i in range(n):
        if not on_ground[i]:
            any_airborne = True
    n_events = 0
    for i in range(n):
        for j in range(i + 1, n):
            dn = pos_ned[i, 0] - pos_ned[j, 0]
            de = pos_ned[i, 1] - pos_ned[j, 1]
            dd = pos_ned[i, 2] - pos_ned[j, 2]
            gap = math.sqrt(dn * dn + de * de + dd * dd) - radius_m[i] - radius_m[j]
            if gap < min_separation_m[i]:
                min_separation_m[i] = gap
            if gap < min_separation_m[j]:
                min_separation_m[j] = gap
            if gap <= 0.0 and not touching[i, j]:
                touching[i, j] = True
                touching[j, i] = True
                events[n_events, 0] = i
                events[n_events, 1] = j
                events[n_events, 2] = EVENT_CONTACT
                n_events += 1
            if not any_airborne:
                continue
            sep = max(math.hypot(dn, de), abs(dd) * ratio)
            both_airborne = not on_ground[i] and not on_ground[j]
            if both_airborne:
                if sep < min_volume_sep_m[i]:
                    min_volume_sep_m[i] = sep
                if sep < min_volume_sep_m[j]:
                    min_volume_sep_m[j] = sep
            if sep < volume_hor_m:
                seen = inside_seen if both_airborne else inside_seen_ground
                if not seen[i, j]:
                    seen[i, j] = True
                    events[n_events, 0] = i
                    events[n_events, 1] = j
                    events[n_events, 2] = EVENT_VOLUME_AIRBORNE if both_airborne else EVENT_VOLUME_GROUND
                    n_events += 1
    return n_events
