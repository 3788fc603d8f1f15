"""The uploaded FENCE as the avoidance planner's fence zones (SPEC §7: fences are planned around).

The planner (``autopilot.planner.geometry.FenceZone``) wants zones with ``violates(pos_ned)`` and
``segment_clear(a, b, margin_m)``, each checked on its own. The mission's
:class:`autopilot.geofence.fence.Geofence` has MAVLink semantics that single zones cannot express:
stay outside every exclusion zone and inside *all* inclusion zones of *at least one* inclusion
group. So the whole fence is handed over as one zone (:class:`GeofenceZone`): a detour that
enters an exclusion zone or leaves the inclusion fence is ruled out, and an inclusion fence is
never left. Positions are NED about home, as the planner and the geofence both use.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from autopilot.geofence.fence import Geofence


@dataclass(frozen=True, slots=True)
class GeofenceZone:
    """A whole :class:`Geofence` behind the planner's per-zone protocol."""

    fence: Geofence

    def violates(self, pos_ned: Sequence[float] | np.ndarray) -> bool:
        """Inside an exclusion zone or outside every inclusion group."""
        return self.fence.violates(pos_ned)

    def segment_clear(
        self, a: Sequence[float] | np.ndarray, b: Sequence[float] | np.ndarray, margin_m: float = 0.0
    ) -> bool:
        """The straight segment keeps ``margin_m`` from every exclusion zone and stays inside an inclusion group."""
        return self.fence.segment_clear(a, b, margin_m)

    def path_clear(self, points_ned: np.ndarray, margin_m: float) -> bool:
        """Every consecutive segment of a sampled path ``(n, 3)`` is clear."""
        return self.fence.path_clear(points_ned, margin_m)


def planner_fence_zones(fence: Geofence) -> tuple[GeofenceZone, ...]:
    """The zones to give ``AvoidancePlanner.set_fences``: empty for an empty fence."""
    return (GeofenceZone(fence),) if fence.zones else ()
