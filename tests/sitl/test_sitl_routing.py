"""Routing around no-fly zones over the real processes (issue 13 "Must show"; issue 15 item 4).

The three user stories of issue 13, each with sim + autopilot over loopback UDP and the bundled ground station:
a FENCE upload right after the first heartbeat is accepted; a leg across an exclusion circle with a tall
building just past it is flown around both and `tools.gcs fly` succeeds (no breach, no collision); a waypoint
900 m out with a 500 m inclusion fence is refused at upload with the item and the reason, and `fly` fails
saying so. Plus the bundled no-fly-corridor delivery, flown clean.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from conftest import REPO_ROOT
from sitl_procs import connect_gcs, read_json, sitl_pair

from autopilot.mission.files import load_mission_file
from mavlink_bridge.contract.vehicle_api import MissionType
from tools import gcs

pytestmark = [pytest.mark.sitl, pytest.mark.slow]

CIRCLE_AND_TOWER = """
name: circle_and_tower
home: {lat_deg: 30.2635, lon_deg: 120.1233, alt_m: 12.0}
vehicle: x500
speed_m_s: 5.0
mission:
  - takeoff: {alt_m: 12}
  - waypoint: {north_m: 90, east_m: 0, alt_m: 12, accept_radius_m: 1.5}
  - land: {}
fence:
  - exclusion_circle: {north_m: 40, east_m: 0, radius_m: 10}
world:
  obstacles:
    - cylinder: {north_m: 58, east_m: 9, radius_m: 4, height_m: 60}
"""

FAR_WAYPOINT = """
name: far_waypoint
home: {lat_deg: 30.2635, lon_deg: 120.1233, alt_m: 12.0}
vehicle: x500
mission:
  - takeoff: {alt_m: 10}
  - waypoint: {north_m: 100, east_m: 0, alt_m: 20}
  - waypoint: {north_m: 900, east_m: 0, alt_m: 20}
  - land: {}
fence:
  - inclusion_circle: {north_m: 0, east_m: 0, radius_m: 500}
"""


def _fly(tmp_path: Path, mission: Path, timeout_s: float = 240.0) -> tuple[int, dict[str, object], str]:
    """`tools.gcs fly` against a fresh SITL pair: exit code, fly summary, sim summary path's parent logs."""
    summary_path = tmp_path / "gcs_summary.json"
    with sitl_pair(tmp_path, mission, seed=1) as s:
        args = ["--connect", s.gcs_url, "fly", str(mission), "--summary", str(summary_path), "--no-progress"]
        rc = gcs.main([*args, "--timeout-s", str(timeout_s)])
    return rc, json.loads(summary_path.read_text()), str(tmp_path)


def test_fence_upload_right_after_the_first_heartbeat_is_accepted(tmp_path: Path) -> None:
    mission = REPO_ROOT / "missions" / "no_fly_corridor.yaml"
    plan = load_mission_file(mission)
    with sitl_pair(tmp_path, mission) as s, connect_gcs(s.gcs_url) as client:
        serial = client.statustext_serial
        client.upload_mission(plan.fence, MissionType.FENCE)  # as QGC and scripts do on connect; raises if refused
        client.upload_mission(plan.items, MissionType.MISSION)
        assert len(client.download_mission(MissionType.FENCE)) == len(plan.fence)
        status = client.wait_until(lambda st: st.home is not None and st.gps_fix_type >= 3, 60.0)
        client.pump(1.0)
        texts = [t.text for t in client.statustexts_since(serial)]
        assert len(client.download_mission(MissionType.MISSION)) == len(plan.items)
    assert status.home is not None
    assert not [t for t in texts if "refused" in t or "not flyable" in t], texts
    # whether the vehicle had its first fix when the upload arrived is a race at --speed max (the GCS's telemetry
    # lags); storing before the fix and placing once home is known is tested in-process (test_autopilot_routing)


def test_leg_across_an_exclusion_circle_with_a_tall_building_past_it(tmp_path: Path, capsys) -> None:  # type: ignore[no-untyped-def]
    mission = tmp_path / "circle_and_tower.yaml"
    mission.write_text(CIRCLE_AND_TOWER)
    rc, summary, _ = _fly(tmp_path, mission)
    sim = read_json(tmp_path / "sim_summary.json")
    assert rc == 0 and summary["ok"] is True, (summary, capsys.readouterr().err)
    assert sim["collisions"] == 0 and float(sim["min_clearance_m"]) > 1.0, sim
    assert summary["items_reached"] == summary["items_total"] == len(load_mission_file(mission).items)
    ap = read_json(tmp_path / "autopilot_summary.json")
    assert ap["items_bypassed"] == 0 and "AUTO_RTL" not in str(ap["mode_history"]), ap


def test_waypoint_outside_the_500m_inclusion_fence_is_refused_with_the_reason(tmp_path: Path, capsys) -> None:  # type: ignore[no-untyped-def]
    mission = tmp_path / "far_waypoint.yaml"
    mission.write_text(FAR_WAYPOINT)
    rc, summary, _ = _fly(tmp_path, mission, timeout_s=60.0)
    assert rc != 0 and summary["ok"] is False
    reason = str(summary["reason"])
    assert "item 2" in reason and "outside the inclusion fence" in reason, reason
    assert "outside the inclusion fence" in capsys.readouterr().err


def test_no_fly_corridor_delivery_flies_clean(tmp_path: Path, capsys) -> None:  # type: ignore[no-untyped-def]
    mission = REPO_ROOT / "missions" / "no_fly_corridor.yaml"
    rc, summary, _ = _fly(tmp_path, mission)
    sim = read_json(tmp_path / "sim_summary.json")
    assert rc == 0 and summary["ok"] is True, (summary, capsys.readouterr().err)
    assert sim["collisions"] == 0 and sim["payload_released_at_s"] is not None, sim
