"""Losses of separation as pair-events (SPEC §13, issue 28; the way DEGAS counts for ACAS X): a pair of aircraft
that comes inside a volume during a run is one event, however long or often it stays inside, first time kept.

Two volumes: the UAV separation volume between two quadsitl vehicles (``sim.fleet.UAV_VOLUME_HOR_M`` /
``UAV_VOLUME_VER_M``, counted by :class:`~sim.fleet.FleetSim`) and the NMAC volume between a vehicle and a scripted
manned aircraft (``sim.traffic.NMAC_HOR_M`` / ``NMAC_VER_M``, counted here by :class:`MannedPairs`). An event
while a vehicle of the pair stands on the ground (or, against manned traffic, is within
``sim.traffic.IN_FLIGHT_MIN_AGL_M`` of it) is not a loss of separation in flight: it is kept apart, excluded from
the events and written with its count, so nothing is dropped silently.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from sim.traffic import IN_FLIGHT_MIN_AGL_M, NMAC_HOR_M, NMAC_VER_M, ScriptedTraffic


@dataclass(frozen=True, slots=True)
class PairEvent:
    """One pair inside a volume: vehicle ``a``, the other vehicle or manned aircraft ``b`` (a callsign), the sim
    time of its first step inside."""

    a: str
    b: str
    at_s: float


class MannedPairs:
    """The (vehicle, manned aircraft) pairs that came inside the NMAC volume: in flight, and with the vehicle on the
    ground (excluded). Keyed by index pair; the first sim time is kept."""

    def __init__(self, traffic: ScriptedTraffic, n: int) -> None:
        self.traffic = traffic
        self.airborne: dict[tuple[int, int], float] = {}
        self.ground: dict[tuple[int, int], float] = {}
        self._seen = np.zeros((n, len(traffic)), dtype=bool)  # pairs inside in flight already
        self._seen_ground = np.zeros((n, len(traffic)), dtype=bool)

    def update(self, t_s: float, pos_ned: np.ndarray, on_ground: np.ndarray) -> None:
        """Fold the vehicles' positions ``pos_ned`` (n, 3) at ``t_s`` in; ``on_ground`` (n,) bool."""
        if not len(self.traffic):
            return
        air = self.traffic.positions(t_s)  # (m, 3), NaN rows for aircraft not flying
        d = pos_ned[:, None, :] - air[None, :, :]
        inside = (np.hypot(d[..., 0], d[..., 1]) < NMAC_HOR_M) & (np.abs(d[..., 2]) < NMAC_VER_M)  # NaN: False
        if not inside.any():
            return
        grounded = (pos_ned[:, 2] > -IN_FLIGHT_MIN_AGL_M) | np.asarray(on_ground, dtype=bool)
        for seen, first, rows in ((self._seen, self.airborne, ~grounded), (self._seen_ground, self.ground, grounded)):
            new = inside & rows[:, None] & ~seen
            for i, k in zip(*np.nonzero(new), strict=True):
                first[(int(i), int(k))] = t_s
            seen |= new


def pair_events(pairs: dict[tuple[int, int], float], names_a: list[str], names_b: list[str]) -> list[PairEvent]:
    """The events of ``pairs`` ((index a, index b) -> first sim time) with names, in the order they happened."""
    return [PairEvent(names_a[a], names_b[b], t) for (a, b), t in sorted(pairs.items(), key=lambda kv: kv[1])]
