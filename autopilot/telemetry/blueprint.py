"""The layout a recording opens with, arranged like the paper's figures (SPEC §9; paper §4 figures).

Left: the 3D world (NED), a top (north-east) view looking straight down, and the event log.
Right: attitude and position errors (the paper's error plots), position vs setpoint, the live
variable gains k(s) of the position and attitude loops, motor commands, thrust/torque and battery.
"""

from __future__ import annotations

import rerun.blueprint as rrb

from autopilot.telemetry import entities as ent


def top_view(center_ne_m: tuple[float, float] = (0.0, 0.0), span_m: float = 120.0) -> rrb.Spatial3DView:
    """A 3D view looking straight down on NED (north up on screen) from ``span_m`` above ``center_ne_m``."""
    n, e = center_ne_m
    return rrb.Spatial3DView(
        origin=ent.WORLD,
        name="top (north-east)",
        eye_controls=rrb.EyeControls3D(
            kind=rrb.Eye3DKind.Orbital,
            position=(n, e, -abs(span_m)),
            look_target=(n, e, 0.0),
            eye_up=(1.0, 0.0, 0.0),
        ),
    )


def flight_blueprint(center_ne_m: tuple[float, float] = (0.0, 0.0), span_m: float = 120.0) -> rrb.Blueprint:
    """The flight layout; ``center_ne_m``/``span_m`` frame the top view (about the local origin)."""
    series = rrb.Grid(
        rrb.TimeSeriesView(origin=ent.ATT_ERR, name="attitude error (deg)"),
        rrb.TimeSeriesView(origin=ent.POS_ERR_NED, name="position error (m)"),
        rrb.TimeSeriesView(origin="position", name="position vs setpoint (m)"),
        rrb.TimeSeriesView(origin="attitude", name="attitude vs setpoint (deg)"),
        rrb.TimeSeriesView(origin=ent.GAINS_POSITION, name="k(s) position loop"),
        rrb.TimeSeriesView(origin=ent.GAINS_ATTITUDE, name="k(s) attitude loop"),
        rrb.TimeSeriesView(origin=ent.MOTORS, name="motor commands"),
        rrb.TimeSeriesView(origin="thrust", name="thrust (N) / torque (N·m)"),
        rrb.TimeSeriesView(origin="battery", name="battery"),
        rrb.TimeSeriesView(origin="planner", name="clearance (m)"),
    )
    left = rrb.Vertical(
        rrb.Spatial3DView(origin=ent.WORLD, name="3D world (NED)"),
        top_view(center_ne_m, span_m),
        rrb.TextLogView(origin=ent.LOG, name="events"),
        row_shares=[3.0, 2.0, 1.5],
    )
    return rrb.Blueprint(
        rrb.Horizontal(left, series, column_shares=[2.0, 3.0]),
        rrb.TimePanel(state="collapsed"),
        collapse_panels=False,
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
                rrb.TimeSeriesView(origin=ent.MON_ATT, name="attitude (deg)"),
                rrb.TimeSeriesView(origin=ent.MON_POS, name="position NED (m)"),
                rrb.TimeSeriesView(origin=ent.MON_ALT, name="altitude above home (m)"),
                rrb.TimeSeriesView(origin=ent.MON_MISSION, name="mission item"),
            ),
        ),
    )
