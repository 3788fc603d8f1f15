"""Every return routed, over the real processes (issue 22 item 2 "Must show").

Sim and autopilot over loopback UDP with the bundled GCS client: the vehicle waits at a drop point 90 m north
of home with an exclusion circle half-way between; a GCS ``rtl`` (MAV_CMD_NAV_RETURN_TO_LAUNCH), and on another
flight a low battery (BAT_HOVER_ENDUR lowered in flight: the pack runs down in seconds, BAT_CRIT_THR triggers
COM_LOW_BAT_ACT 3 = return), each fly the return around the circle and land at home: no position sampled from
telemetry inside the zone, no geofence failsafe (the autopilot's own check, every 0.1 s of sim time), a
"Route: ..." STATUSTEXT.
"""

from __future__ import annotations

import math
from pathlib import Path

import pytest
from sitl_procs import connect_gcs, fence_world_yaml, landed_disarmed, read_json, sitl_pair, upload_arm_start

from autopilot.geofence.fence import geofence_from_items
from autopilot.mission.files import load_mission_file
from mavlink_bridge.contract.frames import LocalNedFrame
from mavlink_bridge.contract.vehicle_api import FlightMode
from mavlink_bridge.gcs_client.client import VehicleStatus

pytestmark = [pytest.mark.sitl, pytest.mark.slow]

CIRCLE_BETWEEN = fence_world_yaml(
    "circle_between",
    speed_m_s=6.0,
    mission=[
        "takeoff: {alt_m: 10}",
        "waypoint: {north_m: 90, east_m: 0, alt_m: 10, accept_radius_m: 1.5, hold_s: 120}",
        "land: {}",
    ],
    fence=["exclusion_circle: {north_m: 45, east_m: 0, radius_m: 10}"],
)


@pytest.mark.parametrize("trigger", ["gcs_rtl", "low_battery"])
def test_a_return_with_an_exclusion_zone_between_vehicle_and_home_flies_around_it(tmp_path: Path, trigger: str) -> None:
    mission = tmp_path / "circle_between.yaml"
    mission.write_text(CIRCLE_BETWEEN)
    plan = load_mission_file(mission)
    fence = geofence_from_items(plan.fence, plan.home)
    home_frame = LocalNedFrame(plan.home)
    track: list[tuple[float, float, float]] = []

    def sample(st: VehicleStatus) -> bool:
        if st.lat_deg is not None and st.lon_deg is not None and st.alt_rel_m is not None:
            track.append(home_frame.ned_from_geodetic(st.lat_deg, st.lon_deg, plan.home.alt_amsl_m + st.alt_rel_m))
        return landed_disarmed(st)

    with sitl_pair(tmp_path, mission) as s, connect_gcs(s.gcs_url) as client:
        client.set_param("MIS_RTL_ALT", 12.0)  # a short climb
        upload_arm_start(client, plan)
        client.wait_until(lambda st: st.pos_ned_m is not None and st.pos_ned_m[0] > 85.0, 180.0)
        serial = client.statustext_serial
        if trigger == "gcs_rtl":
            client.rtl()
        else:
            client.set_param("BAT_HOVER_ENDUR", 10.0)  # the pack drains ~10 %/s from here
        client.wait_until(lambda st: st.mode is FlightMode.AUTO_RTL, 30.0)
        client.wait_until(sample, 180.0)
        texts = [t.text for t in client.statustexts_since(serial)]
    ap, sim = read_json(tmp_path / "autopilot_summary.json"), read_json(tmp_path / "sim_summary.json")
    assert ap["landed"] and ap["disarmed"] and sim["collisions"] == 0, (ap, sim)
    final_ned = sim["final_pos_ned_m"]
    assert isinstance(final_ned, list) and math.hypot(final_ned[0], final_ned[1]) < 1.5, final_ned  # at home
    # sampled from the drop point home: streams run in sim time but are capped at their rate in wall time, so
    # at --speed max an idle machine sees fewer samples than a loaded one; the
    # autopilot's own fence check below runs at 10 Hz of sim time and covers every step between them
    assert len(track) >= 5 and max(p[0] for p in track) > 80.0 and min(p[0] for p in track) < 20.0
    breaches = [p for p in track if fence.violates(p)]
    assert not breaches, breaches[:3]
    # the autopilot checks the fence at 10 Hz of sim time (GF_ACTION 1 warns: "Failsafe: geofence breach: ...")
    assert not [t for t in texts if "geofence" in t.lower()], texts
    assert any(t.startswith("Route: ") and "around the fence" in t for t in texts), texts
    if trigger == "low_battery":
        assert any("battery critical" in t for t in texts), texts
