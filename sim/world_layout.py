"""The layout (Rerun blueprint) a fleet recording opens with; the simulator's world recorder sends it, once.

A fleet recording is several files with one recording id (each autopilot's and the simulator's); only the
simulator knows every vehicle's name, so its file carries the layout. Left: the whole world in 3D (every vehicle
with its trail, route, separation volume, the manned traffic with its NMAC volume), seen from the south-west and
framed on where the vehicles flew, a top view and every vehicle's events. Right: the separation of each vehicle
pair, and tabs: ``fleet`` (one plot per quantity with every vehicle in it), then one tab per vehicle with its own
plots (the single-vehicle layout's panels).

The per-vehicle paths are the autopilot's recording contract (``plots/<name>/<group>``, see
``autopilot.telemetry.fleet_recording``); tests check that each panel names a path an autopilot writes.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import rerun.blueprint as rrb
from rerun.blueprint.components import LinkAxis

#: The application id of a fleet's recording parts: blueprints are per application id, so the fleet layout never
#: replaces a single-vehicle recording's (``quadsitl``) open in the same viewer.
FLEET_APPLICATION_ID = "quadsitl_fleet"
VEHICLES = "vehicles"
PLOTS = "plots"
TRAFFIC = "traffic"
SEPARATION = "separation"

#: One vehicle's panels: (path under ``plots/<name>``, title), as in the single-vehicle layout.
VEHICLE_PANELS: tuple[tuple[str, str], ...] = (
    ("errors/att_err_deg", "attitude error (deg)"),
    ("errors/pos_err_ned_m", "position error (m)"),
    ("position", "position vs setpoint (m)"),
    ("attitude", "attitude vs setpoint (deg)"),
    ("gains/position", "k(s) position loop"),
    ("gains/attitude", "k(s) attitude loop"),
    ("motors/motor_cmd", "motor commands (0-1)"),
    ("thrust", "thrust (N) / torque (N·m)"),
    ("battery/remaining_pct", "battery charge (%)"),
    ("battery/voltage_v", "battery voltage (V)"),
    ("planner", "clearance to obstacles (m)"),
    ("mission", "current mission item"),
)
#: The ``fleet`` tab: one plot per quantity, every vehicle's series in it: (path under ``plots/<name>``, title).
FLEET_PANELS: tuple[tuple[str, str], ...] = (
    ("position/pos_ned_m", "position north, east, down (m), every vehicle"),
    ("errors/pos_err_ned_m", "position error (m), every vehicle"),
    ("battery/remaining_pct", "battery charge (%), every vehicle"),
    ("mission/seq", "current mission item, every vehicle"),
)
LOG = "log"
TICKS = "home/ticks"  # a vehicle's top-view grid (under ``vehicles/<name>``)


def _whole_flight() -> dict[str, object]:
    """Time-series x axis: the whole flight, linked across plots."""
    everything = rrb.TimeRange(start=rrb.TimeRangeBoundary.infinite(), end=rrb.TimeRangeBoundary.infinite())
    return {"axis_x": rrb.TimeAxis(link=LinkAxis.LinkToGlobal, view_range=everything)}


def _series(name: str, origin: str, contents: Sequence[str] | None = None) -> rrb.TimeSeriesView:
    extra: dict[str, object] = {} if contents is None else {"contents": list(contents)}
    return rrb.TimeSeriesView(origin=origin, name=name, **extra, **_whole_flight())  # type: ignore[arg-type]


def framing(pos_ned_m: np.ndarray) -> tuple[tuple[float, float, float], float]:
    """Centre (NED, m) and span (m) of the positions (k, 3) about the world's home: their box, at least 40 m."""
    pts = np.asarray(pos_ned_m, dtype=np.float64).reshape(-1, 3)
    pts = pts[np.isfinite(pts).all(axis=1)]
    if not len(pts):
        return (0.0, 0.0, -10.0), 60.0
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    centre = (lo + hi) / 2.0
    span = max(40.0, 1.3 * float(max(hi[0] - lo[0], hi[1] - lo[1])))
    return (float(centre[0]), float(centre[1]), min(float(centre[2]), -5.0)), span


def _world_views(
    names: Sequence[str], centre: tuple[float, float, float], span_m: float
) -> tuple[rrb.Spatial3DView, rrb.Spatial3DView]:
    n, e, d = centre
    contents = ["+ /**", f"- /{PLOTS}/**", f"- /{SEPARATION}/**"]
    # each vehicle's labelled grid is about its own home: overlaid they would only clutter the world's views
    contents += [f"- /{VEHICLES}/{name}/{TICKS}/**" for name in names]
    oblique = rrb.Spatial3DView(
        origin="/",
        contents=contents,
        name="fleet world (NED)",
        eye_controls=rrb.EyeControls3D(
            kind=rrb.Eye3DKind.Orbital,
            position=(n - 0.8 * span_m, e - 0.5 * span_m, d - 0.6 * span_m),
            look_target=(n, e, d),
            eye_up=(0.0, 0.0, -1.0),
        ),
    )
    top = rrb.Spatial3DView(
        origin="/",
        contents=contents,
        name="top (north-east, m)",
        eye_controls=rrb.EyeControls3D(
            kind=rrb.Eye3DKind.Orbital,
            position=(n, e, -1.4 * span_m),
            look_target=(n, e, 0.0),
            eye_up=(1.0, 0.0, 0.0),
        ),
    )
    return oblique, top


def fleet_blueprint(names: Sequence[str], pos_ned_m: np.ndarray | None = None) -> rrb.Blueprint:
    """The fleet layout for vehicles ``names``, its 3D views framed on ``pos_ned_m`` (k, 3) about the world's home."""
    centre, span = framing(np.zeros((0, 3)) if pos_ned_m is None else pos_ned_m)
    oblique, top = _world_views(names, centre, span)
    events = rrb.TextLogView(
        origin=f"/{PLOTS}", contents=[f"+ /{PLOTS}/{n}/{LOG}" for n in names], name="events, every vehicle"
    )
    fleet_tab = rrb.Grid(
        *(_series(title, f"/{PLOTS}", [f"+ /{PLOTS}/{n}/{path}/**" for n in names]) for path, title in FLEET_PANELS),
        name="fleet",
    )
    vehicle_tabs = [
        rrb.Grid(*(_series(title, f"/{PLOTS}/{n}/{path}") for path, title in VEHICLE_PANELS), name=n) for n in names
    ]
    separation = _series("separation per pair: horizontal, vertical (m)", f"/{SEPARATION}")
    right = rrb.Vertical(separation, rrb.Tabs(fleet_tab, *vehicle_tabs, active_tab=0), row_shares=[1.0, 3.0])
    left = rrb.Vertical(oblique, top, events, row_shares=[3.0, 2.5, 1.5])
    return rrb.Blueprint(
        rrb.Horizontal(left, right, column_shares=[2.0, 3.0]),
        rrb.BlueprintPanel(state="collapsed"),
        rrb.SelectionPanel(state="collapsed"),
        rrb.TimePanel(state="collapsed"),
    )
