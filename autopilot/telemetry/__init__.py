"""Telemetry to Rerun: ``--rerun off|save:PATH|connect:URL`` and the passive step listener.

``make_listener(spec, vehicle=...)`` is what ``autopilot.cli`` calls; it returns a
:class:`RerunTelemetry` (``on_step(record)``, ``on_event``, ``on_mission``, ``on_fence``,
``on_world``, ``close()``) or None for ``off``.
"""

from __future__ import annotations

from pathlib import Path

from autopilot.telemetry.blueprint import Framing, flight_blueprint
from autopilot.telemetry.rerun_logger import (
    LIVE_BATCH_ROWS,
    LIVE_TRAIL_POINTS,
    SAVE_BATCH_ROWS,
    SAVE_TRAIL_POINTS,
    RerunTelemetry,
)
from autopilot.telemetry.scene import route_points_ned
from autopilot.telemetry.sinks import (
    APPLICATION_ID,
    FLEET_APPLICATION_ID,
    RerunSink,
    RerunSpecError,
    SinkKind,
    open_recording,
    parse_rerun_spec,
)

__all__ = [
    "RerunSink",
    "RerunSpecError",
    "RerunTelemetry",
    "SinkKind",
    "make_listener",
    "open_recording",
    "parse_rerun_spec",
]


def make_listener(
    spec: str,
    *,
    vehicle: str | None = None,
    mission_file: str | Path | None = None,
    safety_radius_m: float = 2.0,
    recording_id: str | None = None,
    rate_3d_hz: float = 25.0,
    rtl_alt_m: float | None = None,
    fleet_name: str | None = None,
    home_offset_ned_m: tuple[float, float, float] = (0.0, 0.0, 0.0),
) -> RerunTelemetry | None:
    """The Rerun listener for a ``--rerun`` value (None for ``off``). Raises :class:`RerunSpecError`.

    ``vehicle`` names the airframe drawn (rotor positions); ``mission_file`` (YAML/.plan/.waypoints)
    draws its route and fence about its home, and its ``world:`` obstacles as the *true* obstacles
    (which the autopilot itself never uses). Raises ``MissionFileError`` for a bad mission file.
    ``fleet_name``: this autopilot flies vehicle ``fleet_name`` of a fleet: its entities go under its name and
    its positions about the world's home (``home_offset_ned_m``, :mod:`autopilot.telemetry.fleet_recording`), with
    its own separation volume drawn, under the fleet's application id (the simulator's part carries the layout).
    """
    sink = parse_rerun_spec(spec)
    if sink.kind is SinkKind.OFF:
        return None
    plan = None
    framing = None
    if mission_file is not None:
        from autopilot.mission.files import load_mission_file

        plan = load_mission_file(mission_file)
        obstacles = bool((plan.world or {}).get("obstacles"))  # the simulator reads the same world
        route = route_points_ned(plan.items, plan.home, rtl_alt_m=rtl_alt_m)
        framing = Framing.of_route(route, obstacles)
    # one blueprint: framed on the route now when it is known, else on the first uploaded mission
    blueprint = flight_blueprint(framing) if framing is not None and fleet_name is None else None
    app_id = APPLICATION_ID if fleet_name is None else FLEET_APPLICATION_ID
    rec = open_recording(sink, blueprint, recording_id=recording_id, application_id=app_id)
    assert rec is not None
    if fleet_name is not None:
        from autopilot.telemetry.fleet_recording import VehicleRecording

        rec = VehicleRecording(rec, fleet_name, home_offset_ned_m)  # type: ignore[assignment]
    live = sink.kind is SinkKind.CONNECT
    rotors = None
    if vehicle:
        from autopilot.control.airframe import AirframeError, load_airframe

        try:
            rotors = load_airframe(vehicle).rotor_pos_frd_m
        except AirframeError:
            rotors = None
    telemetry = RerunTelemetry(
        rec,
        safety_radius_m=safety_radius_m,
        rotor_pos_frd_m=rotors,
        rate_3d_hz=rate_3d_hz,
        batch_rows=LIVE_BATCH_ROWS if live else SAVE_BATCH_ROWS,
        trail_segment_points=LIVE_TRAIL_POINTS if live else SAVE_TRAIL_POINTS,
        blueprint_sent=framing is not None or fleet_name is not None,
        rtl_alt_m=rtl_alt_m,
        obstacles_known=framing.obstacles if framing is not None else None,
        separation_volume=fleet_name is not None,
    )
    if plan is not None:
        from autopilot.geofence.fence import geofence_from_items

        telemetry.on_world(plan.world)
        if plan.items:
            telemetry.on_mission(plan.items, plan.home)
        if plan.fence:
            telemetry.on_fence(geofence_from_items(plan.fence, plan.home).zones)
    return telemetry
