"""The layout a recording opens with, arranged like the paper's figures (paper §4 figures).

Left: the 3D world (NED) seen obliquely from the south-west, framed on the route (not on a fence that may
be hundreds of metres wide), a top (north-east) view looking straight down with a labelled grid, and the
event log. Right: attitude and position errors (the paper's error plots), position and attitude against
their setpoints, the live variable gains k(s) of the position and attitude loops (one panel per term:
k_p, k_i, k_d), motor commands, thrust/torque, battery charge and voltage (each on its own axis) and the
clearance to obstacles. Every time plot shows the whole flight, its y range following the data.

A recording holds one blueprint: :func:`flight_blueprint` is sent once, with the framing of the route when
it is known when the recording starts (``--rerun-world``), else when the first mission arrives.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import rerun.blueprint as rrb
from rerun.blueprint.components import LinkAxis

from autopilot.telemetry import entities as ent


@dataclass(frozen=True, slots=True)
class Framing:
    """What the 3D views look at: the route's horizontal centre about the origin, its extent and height.

    ``obstacles``: the world is known to have obstacles (True), known to have none (False: the clearance
    panel says so), or not known (None).
    """

    center_ne_m: tuple[float, float] = (0.0, 0.0)
    span_m: float = 60.0
    alt_m: float = 10.0
    obstacles: bool | None = None

    @classmethod
    def of_route(cls, points_ned: np.ndarray, obstacles: bool | None = None) -> Framing:
        """Framing for a route (k, 3) NED about the origin: its bounding box plus a margin, at least 30 m."""
        pts = np.asarray(points_ned, dtype=np.float64).reshape(-1, 3)
        if not len(pts):
            return cls(obstacles=obstacles)
        lo, hi = pts.min(axis=0), pts.max(axis=0)
        center = (float(lo[0] + hi[0]) / 2.0, float(lo[1] + hi[1]) / 2.0)
        span = max(30.0, 1.25 * float(max(hi[0] - lo[0], hi[1] - lo[1])))
        return cls(center, span, max(0.0, -float(lo[2] + hi[2]) / 2.0), obstacles)


def tick_spacing_m(span_m: float) -> float:
    """A round grid spacing (1, 2 or 5 x 10^k m) giving about 6 to 12 lines across ``span_m``."""
    raw = max(span_m, 1.0) / 8.0
    power = 10.0 ** math.floor(math.log10(raw))
    return next(step * power for step in (1.0, 2.0, 5.0, 10.0) if step * power >= raw)


def _whole_flight() -> dict[str, object]:
    """Time-series options: the whole flight on the x axis (not a trailing window); the query range (every
    time) and the y range following the data are the defaults of a view that fixes neither."""
    everything = rrb.TimeRange(start=rrb.TimeRangeBoundary.infinite(), end=rrb.TimeRangeBoundary.infinite())
    return {"axis_x": rrb.TimeAxis(link=LinkAxis.LinkToGlobal, view_range=everything)}


def _series(origin: str, name: str) -> rrb.TimeSeriesView:
    return rrb.TimeSeriesView(origin=origin, name=name, **_whole_flight())  # type: ignore[arg-type]


def world_view(framing: Framing) -> rrb.Spatial3DView:
    """The 3D world seen from the south-west and above, the route filling the view."""
    n, e = framing.center_ne_m
    d = -framing.alt_m
    s = framing.span_m
    return rrb.Spatial3DView(
        origin=ent.WORLD,
        contents=["+ $origin/**", f"- /{ent.TICKS}/**"],
        name="3D world (NED)",
        eye_controls=rrb.EyeControls3D(
            kind=rrb.Eye3DKind.Orbital,
            position=(n - 0.8 * s, e - 0.5 * s, d - 0.6 * s),
            look_target=(n, e, d),
            eye_up=(0.0, 0.0, -1.0),
        ),
    )


def top_view(framing: Framing) -> rrb.Spatial3DView:
    """A 3D view looking straight down on NED (north up on screen) with a labelled north/east grid."""
    n, e = framing.center_ne_m
    return rrb.Spatial3DView(
        origin=ent.WORLD,
        name="top (north-east, m)",
        eye_controls=rrb.EyeControls3D(
            kind=rrb.Eye3DKind.Orbital,
            position=(n, e, -1.4 * framing.span_m),
            look_target=(n, e, 0.0),
            eye_up=(1.0, 0.0, 0.0),
        ),
    )


def flight_blueprint(framing: Framing | None = None) -> rrb.Blueprint:
    """The flight layout, its 3D views framed by ``framing`` (default: 60 m about the origin)."""
    framing = framing or Framing()
    clearance = {
        None: "clearance to obstacles (m)",
        True: "clearance to obstacles (m)",
        False: "clearance (m): no obstacles in this world",
    }[framing.obstacles]
    series = rrb.Grid(
        _series(ent.ATT_ERR, "attitude error (deg)"),
        _series(ent.POS_ERR_NED, "position error (m)"),
        _series("position", "position vs setpoint (m)"),
        _series("attitude", "attitude vs setpoint (deg)"),
        _series(ent.GAINS_POSITION, "k(s) position loop: k_p, k_i, k_d of x, y, z"),
        _series(ent.GAINS_ATTITUDE, "k(s) attitude loop: k_p, k_i, k_d of roll, pitch, yaw"),
        _series(ent.MOTORS, "motor commands (0-1)"),
        _series("thrust", "thrust (N) / torque (N·m)"),
        _series(ent.BATTERY_REMAINING, "battery charge (%)"),
        _series(ent.BATTERY_VOLTAGE, "battery voltage (V)"),
        _series("planner", clearance),
        _series("mission", "current mission item"),
    )
    left = rrb.Vertical(
        world_view(framing),
        top_view(framing),
        rrb.TextLogView(origin=ent.LOG, name="events"),
        row_shares=[3.0, 2.5, 1.5],
    )
    return rrb.Blueprint(
        rrb.Horizontal(left, series, column_shares=[2.0, 3.0]),
        rrb.BlueprintPanel(state="collapsed"),  # the flight fills the window; the panels open from the top bar
        rrb.SelectionPanel(state="collapsed"),
        rrb.TimePanel(state="collapsed"),
    )


def monitor_blueprint() -> rrb.Blueprint:
    """The layout of ``tools/monitor.py`` recordings (any MAVLink vehicle)."""
    return rrb.Blueprint(
        rrb.Horizontal(
            rrb.Vertical(
                rrb.Spatial3DView(origin=ent.WORLD, name="3D world (NED)"),
                rrb.TextLogView(origin=ent.LOG, name="STATUSTEXT / events"),
                row_shares=[3.0, 1.0],
            ),
            rrb.Vertical(
                _series(ent.MON_ATT, "attitude (deg)"),
                _series(ent.MON_POS, "position NED (m)"),
                _series(ent.MON_ALT, "altitude above home (m)"),
                _series(ent.MON_MISSION, "mission item"),
            ),
        ),
    )
