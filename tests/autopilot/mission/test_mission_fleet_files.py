"""A fleet world's per-vehicle missions (SPEC §13): the same entries as ``mission:``, about the world's home."""

from __future__ import annotations

from pathlib import Path

import pytest

from autopilot.mission.files import MissionFileError, load_fleet_missions, load_mission_file
from autopilot.preflight import InputFileError, check_autopilot_inputs
from mavlink_bridge.contract.frames import LocalNedFrame
from mavlink_bridge.contract.mav_enums import MavCmd

FLEET = """\
name: pair
home: {lat_deg: 47.3977, lon_deg: 8.5456, alt_m: 488}
vehicles:
  - name: alpha
    home: {north_m: 0, east_m: 0}
    mission:
      - takeoff: {alt_m: 10}
      - waypoint: {north_m: 40, east_m: 8, alt_m: 10}
  - name: bravo
    vehicle: quad250
    home: {north_m: 0, east_m: 8}
    speed_m_s: 6
    mission:
      - takeoff: {alt_m: 15}
      - waypoint: {north_m: 40, east_m: 0, alt_m: 15}
traffic: []
"""


def test_each_vehicle_gets_its_plan_about_the_worlds_home(tmp_path: Path) -> None:
    path = tmp_path / "pair.yaml"
    path.write_text(FLEET)
    assert load_mission_file(path).items == []  # the file's own mission: none
    alpha, bravo = load_fleet_missions(path)
    assert (alpha.name, alpha.vehicle, bravo.name, bravo.vehicle, bravo.speed_m_s) == (
        "alpha",
        "x500",
        "bravo",
        "quad250",
        6,
    )
    waypoint = next(i for i in bravo.items if i.command == MavCmd.NAV_WAYPOINT)
    north, east, _ = LocalNedFrame(bravo.home).ned_from_geodetic(waypoint.x_lat_deg, waypoint.y_lon_deg, 488.0)
    assert (north, east) == pytest.approx((40.0, 0.0), abs=1e-6)  # about the world's home, not bravo's


def test_a_vehicles_bad_item_names_the_line_and_the_vehicle(tmp_path: Path) -> None:
    path = tmp_path / "pair.yaml"
    path.write_text(FLEET.replace("waypoint: {north_m: 40, east_m: 0, alt_m: 15}", "waypiont: {north_m: 40}"))
    with pytest.raises(MissionFileError) as err:
        load_fleet_missions(path)
    assert str(err.value).startswith(f"{path}:15: vehicles[1] mission item 1"), str(err.value)
    with pytest.raises(InputFileError, match="vehicles\\[1\\] mission item 1"):
        check_autopilot_inputs(mission=path)
