"""The one in-process flight flies what the two it replaced flew: fixed truth digests of a single-vehicle campaign
case (the old ``inproc_flight`` over ``VehicleSim``) and of a fleet world (the old ``fleet_inproc`` over
``FleetRun``), recorded from the code before they were merged (commit 51a0bc0). The single-vehicle case's digest
is also what its ``mode: sitl`` flight gives (``test_campaign_local``: sitl = inproc bit for bit). The fleet world's
digests were re-pinned when the receivers stopped reporting truth (UTM relay of the vehicles' own reports, a noisy
ADS-B link), and again when the reactive layer began to fly (the two pads are 8 m apart, inside each other's
volume: the climb-outs are bounded); the same world and seed flown twice gives the same hashes. Case 1 was
re-pinned when a case began to end at landing (disarmed on the ground at 19.784 s instead of flying on to the
25 s ``sim_time_s``): the same flight, a hash over fewer steps."""

from __future__ import annotations

from pathlib import Path

import pytest
from campaign_files import write_campaign

from tools.campaign.cases import draw, materialise
from tools.campaign.inproc_flight import fly_world
from tools.campaign.runner import payload_for
from tools.campaign.spec import load_campaign
from tools.campaign.task import run_case

pytestmark = [pytest.mark.slow]

PAIR = """\
name: pair
home: {lat_deg: 47.3977, lon_deg: 8.5456, alt_m: 488}
world: {wind: {north_m_s: 1.0, gust_m_s: 0.5}}
vehicles:
  - name: alpha
    home: {north_m: 0, east_m: 0}
    mission: [{takeoff: {alt_m: 8}}, {waypoint: {north_m: 20, east_m: 10, alt_m: 8}}, {land: {}}]
  - name: bravo
    home: {north_m: 0, east_m: 8}
    mission: [{takeoff: {alt_m: 6}}, {waypoint: {north_m: 20, east_m: -2, alt_m: 6}}, {land: {}}]
traffic:
  - callsign: HELI1
    icao: 0xA1B2C3
    emitter: rotorcraft
    path: [{north_m: -100, east_m: 60, alt_m: 40}, {north_m: 1500, east_m: 60, alt_m: 40}]
    speed_m_s: 40
"""


@pytest.mark.parametrize(
    ("case_id", "end_reason", "sim_time_s", "digest"),
    [
        (0, "GROUND_IMPACT", 13.036, "ddc45d2dbf3f0617b8f4ffcc6d231ac14b70e14927b1524ebaae4eee4ee04667"),
        (1, "COMPLETED", 19.784, "91415613036cb771243fd89794d3d32bf7b2a11af4694b48f3f22a8036b6b870"),
    ],
)
def test_a_single_vehicle_case_keeps_its_digest(
    tmp_path: Path, case_id: int, end_reason: str, sim_time_s: float, digest: str
) -> None:
    spec = load_campaign(write_campaign(tmp_path / "campaign", cases=2))
    case = draw(spec, case_id)
    row = run_case(payload_for(spec, case, materialise(spec, case), tmp_path / "out"))
    assert (row["end_reason"], row["sim_time_s"], row["truth_hash"]) == (end_reason, sim_time_s, digest)


def test_a_fleet_world_keeps_its_per_vehicle_digests(tmp_path: Path) -> None:
    world = tmp_path / "pair.yaml"
    world.write_text(PAIR)
    out = fly_world(world, seed=9, stagger_s=2.0, sim_time_s=30.0)
    # both hold their take-off while the helicopter passes 60 m east at 40 m (the departure hold, 2026-12-02); the
    # climbs above the ground lock go through the altitude-change corridor (both land by 49 s of sim, 54 s before);
    # re-pinned 2026-12-03: while engaged with no track binding the layer flies its preference within the vehicle's
    # own limits and the fence, no longer the preference as it was (the pads 8 m apart: the climb-outs engage it);
    # and again when each vehicle's camera detections of the other became fixes of its track (8 m apart they see
    # each other: the tracks are fresher, and the other is no longer an obstacle to the planner); and again when a
    # take-off held on its pad began to wait at idle once settled on it (it had pushed against the ground near hover
    # thrust); and again when the plane inside a grown sphere began to ask to move apart along the line of centres
    # (it had let a fast pair fly on through each other: the pads 8 m apart start inside it); and again when a
    # departure hold began to end only after its column had been clear 2 s and the rules and column checks began to
    # read the reports' velocity, not the camera fixes' (alpha leaves its pad 2 s later and lands at 67 s)
    assert [v["truth_sha256"] for v in out["sim"]["vehicles"]] == [
        "aedfe6e8317e27354c90a6e884d2144beee23fd96bed2d99389d53c576b3bd1e",
        "8650929be6cfb5d83f52cdb247b370fab1163700108d32f5e5267ea1ce1eff6d",
    ]
    # each hears the other's own reports (1 Hz, 1 s late) and the helicopter's ADS-B (1 Hz, 0.6 s late, 95 %)
    assert [v["traffic_reports"] for v in out["sim"]["vehicles"]] == [56, 57]
