"""Positions about home and about the estimator origin: the one object that converts between them.

The estimator's local NED is about its *origin* (the first good fix): ``VehicleState.pos_ned_m`` and every
commander, setpoint and controller vector. Missions, fences and the avoidance planner work about *home*
(where the vehicle armed; SPEC §8: mission altitudes are above home). Both frames share the NED axes, so the
conversion is a translation by home's position about the origin (``home_origin_ned_m``).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

from autopilot.mission.plan import HomeTolerance
from mavlink_bridge.contract.frames import GeoPoint, Vec3


@dataclass(frozen=True, slots=True)
class HomeFrame:
    """Home as a frame: its geodetic point and its position about the estimator origin (NED, m)."""

    geo: GeoPoint
    home_origin_ned_m: Vec3 = (0.0, 0.0, 0.0)
    gps_eph_m: float = math.inf  # the GPS accuracy (m) at the fix that set home: how far a WPL home line may lie
    gps_epv_m: float = math.inf

    @property
    def home_tol(self) -> HomeTolerance:
        """How far a WPL file's home line may lie from home and still be taken for it."""
        return HomeTolerance.from_gps(self.gps_eph_m, self.gps_epv_m)

    def home_from_origin(self, pos_origin_ned_m: Sequence[float]) -> Vec3:
        """A position about the origin, expressed about home."""
        h = self.home_origin_ned_m
        return (pos_origin_ned_m[0] - h[0], pos_origin_ned_m[1] - h[1], pos_origin_ned_m[2] - h[2])

    def origin_from_home(self, pos_home_ned_m: Sequence[float]) -> Vec3:
        """A position about home, expressed about the origin."""
        h = self.home_origin_ned_m
        return (pos_home_ned_m[0] + h[0], pos_home_ned_m[1] + h[1], pos_home_ned_m[2] + h[2])
