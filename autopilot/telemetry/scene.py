"""Static scene geometry for the recording: route, true obstacles and fence outlines, about home (SPEC §8-§9).

Pure conversions from the mission contract (``MissionItem`` lists, the ``world:`` mapping of a
mission YAML, fence zones) into NED arrays; the logger only draws them.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from enum import Enum
from typing import Any

import numpy as np

from autopilot.mission.plan import item_position_ned, uses_current_position
from mavlink_bridge.contract.frames import GeoPoint, LocalNedFrame
from mavlink_bridge.contract.mav_enums import MavCmd
from mavlink_bridge.contract.vehicle_api import MissionItem

#: Commands whose x/y/z is a place the vehicle flies to.
_ROUTE_COMMANDS = frozenset(
    {MavCmd.NAV_WAYPOINT, MavCmd.NAV_LOITER_UNLIM, MavCmd.NAV_LOITER_TURNS, MavCmd.NAV_LOITER_TIME, MavCmd.NAV_LAND,
     MavCmd.NAV_TAKEOFF}
)  # fmt: skip


class SceneError(ValueError):
    """A ``world:`` mapping that cannot be drawn (the message names the entry)."""


class ObstacleShape(Enum):
    CYLINDER = "cylinder"
    BOX = "box"
    SPHERE = "sphere"


@dataclass(frozen=True, slots=True)
class TrueObstacle:
    """One obstacle of the mission's ``world:`` section, as a centre and half sizes in NED about home.

    Cylinders and boxes stand on the ground (home altitude): their centre is at half height.
    ``yaw_rad`` rotates a box about down. ``half_size_m`` is (radius, radius, half height) for a
    cylinder and (r, r, r) for a sphere.
    """

    shape: ObstacleShape
    center_ned_m: tuple[float, float, float]
    half_size_m: tuple[float, float, float]
    yaw_rad: float = 0.0


def _num(entry: Mapping[str, Any], key: str, where: str) -> float:
    try:
        value = float(entry[key])
    except (KeyError, TypeError, ValueError) as exc:
        raise SceneError(f"{where}.{key}: expected a number") from exc
    if not math.isfinite(value):
        raise SceneError(f"{where}.{key}: expected a finite number, got {value}")
    return value


def true_obstacles(world: Mapping[str, Any] | None) -> tuple[TrueObstacle, ...]:
    """Obstacles of a mission ``world:`` mapping (SPEC §8 schema: cylinder, box, sphere about home)."""
    if not world:
        return ()
    out: list[TrueObstacle] = []
    for i, entry in enumerate(world.get("obstacles") or ()):
        if not isinstance(entry, Mapping) or len(entry) != 1:
            raise SceneError(f"world.obstacles[{i}]: expected one of cylinder/box/sphere: {{...}}")
        ((kind, spec),) = entry.items()
        where = f"world.obstacles[{i}].{kind}"
        if not isinstance(spec, Mapping):
            raise SceneError(f"{where}: expected a mapping")
        n, e = _num(spec, "north_m", where), _num(spec, "east_m", where)
        if kind == "sphere":
            r = _num(spec, "radius_m", where)
            out.append(TrueObstacle(ObstacleShape.SPHERE, (n, e, -_num(spec, "alt_m", where)), (r, r, r)))
        elif kind == "cylinder":
            r, h = _num(spec, "radius_m", where), _num(spec, "height_m", where)
            out.append(TrueObstacle(ObstacleShape.CYLINDER, (n, e, -h / 2.0), (r, r, h / 2.0)))
        elif kind == "box":
            size = spec.get("size_m")
            if not isinstance(size, Sequence) or len(size) != 3:
                raise SceneError(f"{where}.size_m: expected [length, width, height]")
            length, width, height = (float(v) for v in size)
            yaw = math.radians(float(spec.get("yaw_deg", 0.0)))
            out.append(
                TrueObstacle(ObstacleShape.BOX, (n, e, -height / 2.0), (length / 2.0, width / 2.0, height / 2.0), yaw)
            )
        else:
            raise SceneError(f"{where}: unknown shape (allowed cylinder, box, sphere)")
    return tuple(out)


def route_points_ned(items: Sequence[MissionItem], home: GeoPoint, *, rtl_alt_m: float | None = None) -> np.ndarray:
    """The reference route (k, 3) in NED about home: home, then every positional item in order.

    Items at "the current position" (lat = lon = 0) keep the previous horizontal position (and,
    except takeoff, the previous altitude when their altitude is 0); RTL climbs to ``rtl_alt_m`` above
    home first when it is lower (``MIS_RTL_ALT``, as the commander flies it; None: no climb), returns
    home at that height and descends; DO_* and other items draw nothing.
    """
    frame = LocalNedFrame(home)
    pts: list[tuple[float, float, float]] = [(0.0, 0.0, 0.0)]
    for item in items:
        cmd = item.command
        prev = pts[-1]
        if cmd == MavCmd.NAV_RETURN_TO_LAUNCH:
            down = min(prev[2], -rtl_alt_m) if rtl_alt_m is not None else prev[2]
            if down != prev[2]:
                pts.append((prev[0], prev[1], down))
            pts.append((0.0, 0.0, down))
            pts.append((0.0, 0.0, 0.0))
        elif cmd in _ROUTE_COMMANDS:
            n, e, d = item_position_ned(item, frame)
            if uses_current_position(item):
                n, e = prev[0], prev[1]
                if cmd != MavCmd.NAV_TAKEOFF and item.z_alt_m == 0.0:
                    d = prev[2]
            if cmd == MavCmd.NAV_LAND:
                d = 0.0
            pts.append((n, e, d))
    return np.asarray(pts, dtype=np.float64)


def fence_outlines(zones: Sequence[object], n_circle: int = 48) -> tuple[list[np.ndarray], list[bool]]:
    """Closed horizontal outlines (m, 2) north-east of fence zones, and whether each is an inclusion.

    Zones are duck-typed like ``autopilot.geofence.fence`` (``center_ne_m``, ``vertices_ne_m``) or
    ``autopilot.planner.geometry`` (``center_ne``, ``vertices_ne``): a circle has a centre and
    ``radius_m``, a polygon its vertices; both have ``inclusion``.
    """
    outlines: list[np.ndarray] = []
    inclusion: list[bool] = []
    angles = np.linspace(0.0, 2.0 * math.pi, n_circle, endpoint=False)
    for zone in zones:
        vertices = getattr(zone, "vertices_ne_m", None) or getattr(zone, "vertices_ne", None)
        if vertices is not None:
            ne = np.asarray(vertices, dtype=np.float64).reshape(-1, 2)
            ne = np.vstack([ne, ne[:1]])
        else:
            center = getattr(zone, "center_ne_m", None) or getattr(zone, "center_ne", None)
            if center is None:
                raise SceneError(f"fence zone {zone!r}: neither vertices nor a centre")
            c = np.asarray(center, dtype=np.float64)
            r = float(zone.radius_m)  # type: ignore[attr-defined]
            ne = np.column_stack([c[0] + r * np.cos(angles), c[1] + r * np.sin(angles)])
            ne = np.vstack([ne, ne[:1]])
        outlines.append(ne)
        inclusion.append(bool(getattr(zone, "inclusion", False)))
    return outlines, inclusion
