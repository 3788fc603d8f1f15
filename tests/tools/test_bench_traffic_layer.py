"""The traffic layer's per-step cost bench measures what it says: the fusion it times is fed detections that are
gated onto their tracks (a bench whose detections never matched would time the early return)."""

from __future__ import annotations

from autopilot.navigation.home_frame import HomeFrame
from autopilot.navigation.traffic_link import TrafficLink
from autopilot.param_schema import make_param_store
from mavlink_bridge.contract.frames import LocalNedFrame
from tools.benchmarks import traffic_layer as bench


def test_the_fused_detections_are_the_ring_s_vehicles_and_all_three_layers_are_timed() -> None:
    link = TrafficLink(make_param_store(), 1)
    link.avoidance.set_home(bench.HOME)
    t_s = 8.0  # the ring has closed to 12 m: every other vehicle within the camera's 25 m
    t_us = round(t_s * 1e6)
    own = (bench.RADIUS_M - bench.SPEED_M_S * t_s, 0.0, -15.0)
    link.avoidance.table.update(t_us, bench.ring_reports(8, t_s, LocalNedFrame(bench.HOME)), 5.0)
    detections = bench.ring_detections(8, t_s, own)
    assert len(detections) == bench.SENSOR_SLOTS
    state = bench.own_state(t_us, own, (-bench.SPEED_M_S, 0.0, 0.0))
    kept, vehicles = link.fuse(state, HomeFrame(bench.HOME), detections)
    assert kept == () and vehicles == {d.obstacle_id for d in detections}
    costs = bench.measure(8, 0.5)
    assert set(costs) == {"reactive_us", "strategic_us", "fusion_us"} and min(costs.values()) > 0.0
