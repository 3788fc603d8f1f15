"""--rerun parsing (SPEC §12) and the scene geometry drawn in recordings."""

from __future__ import annotations

import math

import numpy as np
import pytest

from autopilot.telemetry.scene import ObstacleShape, SceneError, fence_outlines, route_points_ned, true_obstacles
from autopilot.telemetry.sinks import DEFAULT_CONNECT_URL, RerunSink, RerunSpecError, SinkKind, parse_rerun_spec
from mavlink_bridge.contract.frames import GeoPoint, LocalNedFrame
from mavlink_bridge.contract.mav_enums import MavCmd
from mavlink_bridge.contract.vehicle_api import MissionItem


@pytest.mark.parametrize(
    ("text", "sink"),
    [
        ("off", RerunSink(SinkKind.OFF)),
        (" off ", RerunSink(SinkKind.OFF)),
        ("save:runs/1/flight.rrd", RerunSink(SinkKind.SAVE, "runs/1/flight.rrd")),
        ("save:/tmp/a b.rrd", RerunSink(SinkKind.SAVE, "/tmp/a b.rrd")),
        ("connect", RerunSink(SinkKind.CONNECT, DEFAULT_CONNECT_URL)),
        ("connect:default", RerunSink(SinkKind.CONNECT, DEFAULT_CONNECT_URL)),
        ("connect:rerun+http://10.0.0.2:9876/proxy", RerunSink(SinkKind.CONNECT, "rerun+http://10.0.0.2:9876/proxy")),
    ],
)
def test_parse_rerun_spec(text: str, sink: RerunSink) -> None:
    assert parse_rerun_spec(text) == sink
    assert parse_rerun_spec(str(sink)) == sink  # round trip


@pytest.mark.parametrize("text", ["", "on", "save", "save:", "save:flight.txt", "connect:http://x:1", "file:a.rrd"])
def test_bad_rerun_specs_say_what_is_expected(text: str) -> None:
    with pytest.raises(RerunSpecError, match="--rerun"):
        parse_rerun_spec(text)


def test_true_obstacles_from_the_world_section() -> None:
    obs = true_obstacles(
        {
            "obstacles": [
                {"cylinder": {"north_m": 20, "east_m": 1, "radius_m": 3, "height_m": 25}},
                {"box": {"north_m": 50, "east_m": -2, "size_m": [6, 8, 30], "yaw_deg": 90}},
                {"sphere": {"north_m": 70, "east_m": 0, "alt_m": 10, "radius_m": 2.5}},
            ]
        }
    )
    assert [o.shape for o in obs] == [ObstacleShape.CYLINDER, ObstacleShape.BOX, ObstacleShape.SPHERE]
    assert obs[0].center_ned_m == (20.0, 1.0, -12.5) and obs[0].half_size_m == (3.0, 3.0, 12.5)  # stands on the ground
    assert obs[1].half_size_m == (3.0, 4.0, 15.0) and obs[1].yaw_rad == pytest.approx(math.pi / 2)
    assert obs[2].center_ned_m == (70.0, 0.0, -10.0)
    assert true_obstacles(None) == ()
    with pytest.raises(SceneError, match=r"obstacles\[0\]\.cone"):
        true_obstacles({"obstacles": [{"cone": {"north_m": 1, "east_m": 2}}]})
    with pytest.raises(SceneError, match="radius_m"):
        true_obstacles({"obstacles": [{"sphere": {"north_m": 1, "east_m": 2, "alt_m": 3}}]})


def test_route_from_mission_items() -> None:
    home = GeoPoint(30.0, 120.0, 10.0)
    frame = LocalNedFrame(home)
    wp = frame.geodetic_from_ned(40.0, 30.0, 0.0)
    items = [
        MissionItem(0, MavCmd.NAV_TAKEOFF, z_alt_m=15.0),
        MissionItem(1, MavCmd.DO_CHANGE_SPEED, param2=3.0),
        MissionItem(2, MavCmd.NAV_WAYPOINT, x_lat_deg=wp.lat_deg, y_lon_deg=wp.lon_deg, z_alt_m=20.0),
        MissionItem(3, MavCmd.NAV_LOITER_TIME, param1=2.0),  # at the current position and altitude
        MissionItem(4, MavCmd.NAV_RETURN_TO_LAUNCH),
    ]
    pts = route_points_ned(items, home)
    np.testing.assert_allclose(
        pts, [[0, 0, 0], [0, 0, -15], [40, 30, -20], [40, 30, -20], [0, 0, -20], [0, 0, 0]], atol=1e-3
    )


def test_fence_outlines_are_closed() -> None:
    class Circle:
        center_ne_m = (60.0, 10.0)
        radius_m = 8.0
        inclusion = False

    class Polygon:
        vertices_ne = ((80.0, -5.0), (80.0, 5.0), (90.0, 5.0))
        inclusion = True

    outlines, inclusion = fence_outlines([Circle(), Polygon()], n_circle=16)
    assert inclusion == [False, True]
    circle, poly = outlines
    np.testing.assert_allclose(np.hypot(circle[:, 0] - 60.0, circle[:, 1] - 10.0), 8.0)
    np.testing.assert_array_equal(circle[0], circle[-1])
    assert poly.shape == (4, 2) and tuple(poly[-1]) == (80.0, -5.0)
