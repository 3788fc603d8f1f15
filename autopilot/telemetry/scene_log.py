"""The rare things of a Rerun flight recording: the text log (events) and the scene about home.

Route, grid ticks, fence, true and sensed obstacles and the detour are logged when they change;
the per-step listener (``rerun_logger.RerunTelemetry``) builds on :class:`SceneLog`.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
import rerun as rr

from autopilot.telemetry import entities as ent
from autopilot.telemetry.blueprint import Framing, flight_blueprint, tick_spacing_m
from autopilot.telemetry.scene import TrueObstacle, fence_outlines, route_points_ned, true_obstacles
from mavlink_bridge.contract.frames import GeoPoint
from mavlink_bridge.contract.vehicle_api import MissionItem, Severity

_LEVEL = {
    Severity.EMERGENCY: rr.TextLogLevel.CRITICAL,
    Severity.ALERT: rr.TextLogLevel.CRITICAL,
    Severity.CRITICAL: rr.TextLogLevel.CRITICAL,
    Severity.ERROR: rr.TextLogLevel.ERROR,
    Severity.WARNING: rr.TextLogLevel.WARN,
    Severity.NOTICE: rr.TextLogLevel.INFO,
    Severity.INFO: rr.TextLogLevel.INFO,
    Severity.DEBUG: rr.TextLogLevel.DEBUG,
}

_COLOR_ROUTE = (240, 200, 40)
_COLOR_DETOUR = (40, 220, 120)
_COLOR_PLANNED = (255, 170, 0)  # the routed leg around the no-fly zones
_COLOR_SENSED = (255, 120, 40, 200)
_COLOR_SAFETY = (255, 60, 60, 120)
_COLOR_TRUE = (150, 150, 160, 160)
_COLOR_FENCE_EXCL = (255, 40, 40)
_COLOR_FENCE_INCL = (40, 200, 255)
_COLOR_TICKS = (140, 140, 140, 160)


class SceneLog:
    """Events and the scene of one flight in a Rerun recording stream, at sim time.

    Things "about home" are drawn under ``world/home`` whose transform follows the home position.
    """

    def __init__(
        self,
        rec: rr.RecordingStream,
        *,
        safety_radius_m: float = 2.0,
        blueprint_sent: bool = False,
        rtl_alt_m: float | None = None,
        obstacles_known: bool | None = None,
    ) -> None:
        """See :class:`~autopilot.telemetry.rerun_logger.RerunTelemetry`."""
        self.rec = rec
        self.safety_radius_m = float(safety_radius_m)
        self._last_t_us = -1  # the sim time of the latest step
        self._last_home: tuple[float, float, float] | None = None  # home about the origin, NED
        self._blueprint_sent = blueprint_sent
        self.rtl_alt_m = rtl_alt_m
        self._obstacles_known = obstacles_known

    def _set_time(self, t_us: int) -> None:
        self.rec.set_time(ent.TIMELINE, duration=np.timedelta64(int(t_us), "us"))

    def on_event(self, text: str, severity: Severity = Severity.INFO, time_us: int | None = None) -> None:
        """A text-log line (mode change, mission item, avoidance decision, failsafe) at sim time."""
        self._set_time(self._last_t_us if time_us is None else time_us)
        self.rec.log(ent.LOG, rr.TextLog(text, level=_LEVEL.get(severity, rr.TextLogLevel.INFO)))

    def on_route(self, points_ned_home: np.ndarray | Sequence[Sequence[float]]) -> None:
        """The reference route (k, 3) NED about home, as a line with its waypoints (static)."""
        pts = np.asarray(points_ned_home, dtype=np.float64).reshape(-1, 3)
        self.rec.log(
            ent.ROUTE,
            rr.LineStrips3D([pts], colors=[_COLOR_ROUTE], radii=0.08),
            rr.Points3D(pts, colors=[_COLOR_ROUTE], radii=0.3),
            static=True,
        )
        if not len(pts):
            return
        framing = Framing.of_route(pts + np.asarray(self._last_home or (0.0, 0.0, 0.0)), self._obstacles_known)
        self.on_ticks(framing)
        if not self._blueprint_sent:  # one blueprint per recording, framed on the first route
            self._blueprint_sent = True
            self.rec.send_blueprint(flight_blueprint(framing), make_active=True, make_default=True)

    def on_ticks(self, framing: Framing) -> None:
        """The top view's labelled grid about home (static; shown in the top view only)."""
        step = tick_spacing_m(framing.span_m)
        (cn, ce), half = framing.center_ne_m, 0.6 * framing.span_m
        home = self._last_home or (0.0, 0.0, 0.0)
        n_lines = np.arange(math.floor((cn - half - home[0]) / step), math.ceil((cn + half - home[0]) / step) + 1)
        e_lines = np.arange(math.floor((ce - half - home[1]) / step), math.ceil((ce + half - home[1]) / step) + 1)
        n_vals, e_vals = n_lines * step, e_lines * step
        n_lo, n_hi, e_lo, e_hi = float(n_vals[0]), float(n_vals[-1]), float(e_vals[0]), float(e_vals[-1])
        strips = [[(n, e_lo, 0.0), (n, e_hi, 0.0)] for n in n_vals]
        strips += [[(n_lo, e, 0.0), (n_hi, e, 0.0)] for e in e_vals]
        labels = [f"N {n:g}" for n in n_vals] + [f"E {e:g}" for e in e_vals]
        points = [(n, e_lo, 0.0) for n in n_vals] + [(n_lo, e, 0.0) for e in e_vals]
        self.rec.log(
            ent.TICKS,
            rr.LineStrips3D(strips, colors=[_COLOR_TICKS], radii=0.03),
            rr.Points3D(points, labels=labels, colors=[_COLOR_TICKS], radii=0.01, show_labels=True),
            static=True,
        )

    def on_mission(self, items: Sequence[MissionItem], home: GeoPoint) -> None:
        """The uploaded mission as the reference route (see :func:`scene.route_points_ned`)."""
        self.on_route(route_points_ned(items, home, rtl_alt_m=self.rtl_alt_m))

    def on_fence(self, zones: Sequence[object], ceiling_alt_m: float = 0.0) -> None:
        """Fence zones (circles/polygons) as outlines on the ground (and at ``ceiling_alt_m`` if > 0); static."""
        outlines, inclusion = fence_outlines(zones)
        strips, colors = [], []
        for ne, inc in zip(outlines, inclusion, strict=True):
            color = _COLOR_FENCE_INCL if inc else _COLOR_FENCE_EXCL
            for down in (0.0, -ceiling_alt_m) if ceiling_alt_m > 0.0 else (0.0,):
                strips.append(np.column_stack([ne, np.full(len(ne), down)]))
                colors.append(color)
        self.rec.log(ent.FENCE, rr.LineStrips3D(strips, colors=colors, radii=0.1), static=True)

    def on_world(self, world: Mapping[str, Any] | None) -> None:
        """True obstacles of a mission ``world:`` mapping (what the simulator knows; the autopilot does not)."""
        self.on_true_obstacles(true_obstacles(world))

    def on_true_obstacles(self, obstacles: Sequence[TrueObstacle]) -> None:
        """True obstacles about home (static): cylinders, boxes and spheres."""
        by_shape: dict[str, list[TrueObstacle]] = {"cylinder": [], "box": [], "sphere": []}
        for o in obstacles:
            by_shape[o.shape.value].append(o)
        cyl, box, sph = by_shape["cylinder"], by_shape["box"], by_shape["sphere"]
        base = ent.OBSTACLES_TRUE
        rec = self.rec
        if cyl:
            rec.log(
                f"{base}/cylinders",
                rr.Cylinders3D(
                    lengths=[2.0 * o.half_size_m[2] for o in cyl],
                    radii=[o.half_size_m[0] for o in cyl],
                    centers=[o.center_ned_m for o in cyl],
                    colors=[_COLOR_TRUE],
                    fill_mode=rr.components.FillMode.Solid,
                ),
                static=True,
            )
        if box:
            rec.log(
                f"{base}/boxes",
                rr.Boxes3D(
                    centers=[o.center_ned_m for o in box],
                    half_sizes=[o.half_size_m for o in box],
                    rotation_axis_angles=[rr.RotationAxisAngle(axis=(0, 0, 1), radians=o.yaw_rad) for o in box],
                    colors=[_COLOR_TRUE],
                    fill_mode=rr.components.FillMode.Solid,
                ),
                static=True,
            )
        if sph:
            rec.log(
                f"{base}/spheres",
                rr.Ellipsoids3D(
                    centers=[o.center_ned_m for o in sph],
                    half_sizes=[o.half_size_m for o in sph],
                    colors=[_COLOR_TRUE],
                    fill_mode=rr.components.FillMode.Solid,
                ),
                static=True,
            )

    def on_obstacles(self, tracked: Sequence[Any], time_us: int) -> None:
        """Sensed (tracked) obstacles about home and their safety spheres (radius + ``safety_radius_m``).

        Each item needs ``obstacle_id``, ``center_ned`` (about home) and ``radius_m``
        (``autopilot.planner.obstacle_map.TrackedObstacle``).
        """
        self._set_time(time_us)
        if not tracked:
            self.rec.log(ent.OBSTACLES_SENSED, rr.Clear(recursive=False))
            self.rec.log(ent.OBSTACLES_SAFETY, rr.Clear(recursive=False))
            return
        centers = [tuple(o.center_ned) for o in tracked]
        radii = [float(o.radius_m) for o in tracked]
        labels = [f"obs {o.obstacle_id}" for o in tracked]
        self.rec.log(
            ent.OBSTACLES_SENSED,
            rr.Ellipsoids3D(centers=centers, radii=radii, colors=[_COLOR_SENSED], labels=labels,
                            fill_mode=rr.components.FillMode.Solid),
        )  # fmt: skip
        self.rec.log(
            ent.OBSTACLES_SAFETY,
            rr.Ellipsoids3D(centers=centers, radii=[r + self.safety_radius_m for r in radii], colors=[_COLOR_SAFETY]),
        )

    def on_detour(self, points_ned_home: np.ndarray | None, time_us: int) -> None:
        """The planned detour (m, 3) about home; None clears it (back on the route)."""
        self._set_time(time_us)
        if points_ned_home is None or len(points_ned_home) < 2:
            self.rec.log(ent.DETOUR, rr.Clear(recursive=False))
            return
        self.rec.log(ent.DETOUR, rr.LineStrips3D([points_ned_home], colors=[_COLOR_DETOUR], radii=0.12))

    def on_planned_route(self, points_ned_home: np.ndarray | None, time_us: int) -> None:
        """The leg routed around the fence and known obstacles (m, 3) about home; None clears it (direct leg)."""
        self._set_time(time_us)
        if points_ned_home is None or len(points_ned_home) < 2:
            self.rec.log(ent.PLANNED_ROUTE, rr.Clear(recursive=False))
            return
        self.rec.log(ent.PLANNED_ROUTE, rr.LineStrips3D([points_ned_home], colors=[_COLOR_PLANNED], radii=0.15),
                     rr.Points3D(points_ned_home, colors=[_COLOR_PLANNED], radii=0.35))  # fmt: skip
