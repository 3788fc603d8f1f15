"""Failsafes: GCS link loss, offboard setpoint loss, low battery, geofence breach (SPEC §10).

:class:`FailsafeMonitor` is a pure function of its inputs per step: it raises a
:class:`FailsafeEvent` once when a condition starts (edge-triggered, like PX4's
commander) and forgets it when the condition clears. The commander applies the event's
:class:`FailsafeAction`; sim loss is not a flight failsafe here because without the
simulator there is no vehicle: the runner stops and reports it.

The lockstep wire carries no battery telemetry, so :class:`BatteryModel` estimates the
remaining charge from the commanded thrust: at hover thrust the pack lasts
``BAT_HOVER_ENDUR`` seconds and the drain scales with thrust^1.5 (momentum theory:
rotor power ∝ T^1.5). Voltage is a linear 4S curve (16.8 V full, 14.0 V empty).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from enum import Enum, IntEnum

from autopilot.params import ParamStore
from mavlink_bridge.frames import LocalNedFrame
from mavlink_bridge.gcs_types import MissionItem

_FENCE_POLY_INCLUSION = 5001
_FENCE_POLY_EXCLUSION = 5002
_FENCE_CIRCLE_INCLUSION = 5003
_FENCE_CIRCLE_EXCLUSION = 5004

BATTERY_FULL_V = 16.8
BATTERY_EMPTY_V = 14.0


class FailsafeAction(IntEnum):
    """What to do when a failsafe triggers (values of NAV_DLL_ACT, COM_LOW_BAT_ACT, GF_ACTION, ...)."""

    NONE = 0
    WARN = 1
    HOLD = 2
    RTL = 3
    LAND = 4


class FailsafeKind(Enum):
    """Which condition triggered."""

    GCS_LOSS = "gcs link lost"
    OFFBOARD_LOSS = "offboard setpoints lost"
    BATTERY_LOW = "battery low"
    BATTERY_CRITICAL = "battery critical"
    GEOFENCE = "geofence breach"


@dataclass(frozen=True, slots=True)
class FailsafeEvent:
    """A failsafe that just triggered, the action to take and a message for STATUSTEXT."""

    kind: FailsafeKind
    action: FailsafeAction
    message: str


@dataclass(frozen=True, slots=True)
class FailsafeInputs:
    """One step of what the monitor looks at. Ages are wall-clock seconds (SPEC §3); None = not applicable."""

    armed: bool
    in_air: bool
    gcs_heartbeat_age_s: float | None  # None until a GCS has been heard
    offboard_setpoint_age_s: float | None  # None unless in OFFBOARD
    battery_remaining: float  # fraction 0..1
    pos_ned_m: tuple[float, float, float]  # about the local origin (the fence's frame)
    home_ned_m: tuple[float, float, float]


class BatteryModel:
    """Remaining charge estimated from commanded collective thrust (see module docstring)."""

    def __init__(self, hover_endurance_s: float) -> None:
        self.hover_endurance_s = hover_endurance_s
        self.remaining = 1.0

    def update(self, thrust_ratio: float, dt_s: float) -> float:
        """Drain for ``dt_s`` at ``thrust_ratio`` (collective thrust / hover thrust); returns the fraction left."""
        t = max(0.0, thrust_ratio)
        self.remaining = max(0.0, self.remaining - dt_s * t * math.sqrt(t) / self.hover_endurance_s)
        return self.remaining

    @property
    def voltage_v(self) -> float:
        return BATTERY_EMPTY_V + (BATTERY_FULL_V - BATTERY_EMPTY_V) * self.remaining

    def current_a(self, thrust_ratio: float) -> float:
        """Estimated current: 5000 mAh pack emptied in the endurance at that thrust."""
        t = max(0.0, thrust_ratio)
        return 5.0 * 3600.0 * t * math.sqrt(t) / self.hover_endurance_s


@dataclass(frozen=True, slots=True)
class _Circle:
    n_m: float
    e_m: float
    radius_m: float
    inclusion: bool


@dataclass(frozen=True, slots=True)
class _Polygon:
    vertices_ne_m: tuple[tuple[float, float], ...]
    inclusion: bool


def _inside_polygon(n: float, e: float, vertices: Sequence[tuple[float, float]]) -> bool:
    """Even-odd ray casting (north axis ray)."""
    inside = False
    count = len(vertices)
    for i in range(count):
        n1, e1 = vertices[i]
        n2, e2 = vertices[(i + 1) % count]
        if (e1 > e) != (e2 > e):
            n_cross = n1 + (e - e1) * (n2 - n1) / (e2 - e1)
            if n < n_cross:
                inside = not inside
    return inside


class FenceError(ValueError):
    """A FENCE item list is malformed (polygon vertex counts, unknown command)."""


class Geofence:
    """Inclusion/exclusion circles and polygons (mission_type FENCE) plus the GF_MAX_* limits."""

    def __init__(self, circles: Sequence[_Circle] = (), polygons: Sequence[_Polygon] = ()) -> None:
        self._circles = tuple(circles)
        self._polygons = tuple(polygons)
        self._has_inclusion = any(c.inclusion for c in self._circles) or any(p.inclusion for p in self._polygons)

    @classmethod
    def from_items(cls, items: Sequence[MissionItem], frame: LocalNedFrame) -> Geofence:
        """Build from NAV_FENCE_* items (lat/lon in degrees); FenceError on a malformed list."""
        circles: list[_Circle] = []
        polygons: list[_Polygon] = []
        i = 0
        while i < len(items):
            item = items[i]
            if item.command in (_FENCE_CIRCLE_INCLUSION, _FENCE_CIRCLE_EXCLUSION):
                n, e, _ = frame.ned_from_geodetic(item.x_lat_deg, item.y_lon_deg, frame.home.alt_amsl_m)
                if not item.param1 > 0.0:
                    raise FenceError(f"fence item {item.seq}: circle radius must be > 0")
                circles.append(_Circle(n, e, item.param1, item.command == _FENCE_CIRCLE_INCLUSION))
                i += 1
            elif item.command in (_FENCE_POLY_INCLUSION, _FENCE_POLY_EXCLUSION):
                count = int(item.param1)
                group = items[i : i + count]
                if count < 3 or len(group) != count or any(g.command != item.command for g in group):
                    raise FenceError(f"fence item {item.seq}: polygon needs {count} (>= 3) consecutive vertices")
                verts = []
                for g in group:
                    n, e, _ = frame.ned_from_geodetic(g.x_lat_deg, g.y_lon_deg, frame.home.alt_amsl_m)
                    verts.append((n, e))
                polygons.append(_Polygon(tuple(verts), item.command == _FENCE_POLY_INCLUSION))
                i += count
            elif item.command == 5000:  # NAV_FENCE_RETURN_POINT: not a boundary
                i += 1
            else:
                raise FenceError(f"fence item {item.seq}: command {item.command} is not a fence item")
        return cls(circles, polygons)

    def breach(self, n_m: float, e_m: float) -> str | None:
        """Why (n, e) violates the fence, or None when it is allowed."""
        for c in self._circles:
            if not c.inclusion and math.hypot(n_m - c.n_m, e_m - c.e_m) < c.radius_m:
                return f"inside exclusion circle at ({c.n_m:.0f}, {c.e_m:.0f}) m"
        for p in self._polygons:
            if not p.inclusion and _inside_polygon(n_m, e_m, p.vertices_ne_m):
                return "inside an exclusion polygon"
        if not self._has_inclusion:
            return None
        for c in self._circles:
            if c.inclusion and math.hypot(n_m - c.n_m, e_m - c.e_m) <= c.radius_m:
                return None
        for p in self._polygons:
            if p.inclusion and _inside_polygon(n_m, e_m, p.vertices_ne_m):
                return None
        return "outside every inclusion zone"


class FailsafeMonitor:
    """Edge-triggered failsafe conditions, actions taken from parameters (see :mod:`autopilot.nav_params`)."""

    def __init__(self, params: ParamStore) -> None:
        self._params = params
        self.geofence = Geofence()  # replaced by the runner when a FENCE list is uploaded
        self.active: set[FailsafeKind] = set()

    def _action(self, name: str) -> FailsafeAction:
        return FailsafeAction(round(self._params.get(name)))

    def _conditions(self, inp: FailsafeInputs) -> dict[FailsafeKind, tuple[str, str]]:
        """Conditions true now: kind -> (action parameter, message)."""
        p = self._params.get
        out: dict[FailsafeKind, tuple[str, str]] = {}
        if inp.gcs_heartbeat_age_s is not None and inp.gcs_heartbeat_age_s > p("COM_DL_LOSS_T"):
            out[FailsafeKind.GCS_LOSS] = ("NAV_DLL_ACT", f"no GCS heartbeat for {inp.gcs_heartbeat_age_s:.1f} s")
        if inp.offboard_setpoint_age_s is not None and inp.offboard_setpoint_age_s > p("COM_OF_LOSS_T"):
            out[FailsafeKind.OFFBOARD_LOSS] = ("COM_OBL_ACT", f"no setpoint for {inp.offboard_setpoint_age_s:.1f} s")
        pct = 100.0 * inp.battery_remaining
        if inp.battery_remaining < p("BAT_CRIT_THR"):
            out[FailsafeKind.BATTERY_CRITICAL] = ("COM_LOW_BAT_ACT", f"battery critical ({pct:.0f} %)")
        elif inp.battery_remaining < p("BAT_LOW_THR"):
            out[FailsafeKind.BATTERY_LOW] = ("", f"battery low ({pct:.0f} %)")
        n, e, d = (inp.pos_ned_m[i] - inp.home_ned_m[i] for i in range(3))
        max_hor, max_ver = p("GF_MAX_HOR_DIST"), p("GF_MAX_VER_DIST")
        if max_hor > 0.0 and math.hypot(n, e) > max_hor:
            reason = f"{math.hypot(n, e):.0f} m from home (max {max_hor:g})"
        elif max_ver > 0.0 and -d > max_ver:
            reason = f"{-d:.0f} m above home (max {max_ver:g})"
        else:
            reason = self.geofence.breach(inp.pos_ned_m[0], inp.pos_ned_m[1])
        if reason is not None:
            out[FailsafeKind.GEOFENCE] = ("GF_ACTION", reason)
        return out

    def update(self, inp: FailsafeInputs) -> list[FailsafeEvent]:
        """Events for conditions that started this step (only while armed and in the air)."""
        now = self._conditions(inp) if (inp.armed and inp.in_air) else {}
        events = []
        for kind, (param, message) in now.items():
            if kind not in self.active:
                action = self._action(param) if param else FailsafeAction.WARN
                events.append(FailsafeEvent(kind, action, f"Failsafe: {kind.value}: {message}"))
        self.active = set(now)
        return events
