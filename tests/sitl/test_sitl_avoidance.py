"""Flights through obstacles (issue 6 "Must show", SPEC §7): the city block over loopback SITL (sim + autopilot
processes over UDP, the ground station flying it), the storm and Lissajous worlds in one process (the simulator's
and the autopilot's own modules and wire format, ``tools.campaign.inproc_flight``: the same truth as the lockstep,
``tests/tools/test_campaign_modes_agree.py``) at a quarter of the cost.

The autopilot knows only what the simulated stereo camera and ultrasonic range tell it. Each mission must
be flown to the end with zero collisions and a minimum clearance (sim ground truth) of at least
CA_RSAFE_M - CA_TRACK_TOL_M (over SITL the values read back from the autopilot), every item reached in order
(waypoints a detour bypassed or inside an obstacle are skipped and reported *bypassed*, never reached),
landed and disarmed.
"""

from __future__ import annotations

import subprocess
from pathlib import Path

import pytest
from conftest import REPO_ROOT
from sitl_procs import connect_gcs, landed_disarmed, logs, read_json, sitl_pair, upload_arm_start

from autopilot.mission.files import load_mission_file
from autopilot.mission.plan import MissionPlan
from autopilot.planner.param_decls import planner_param_specs
from mavlink_bridge.contract.status_texts import bypassed_seq, is_bypassed
from mavlink_bridge.gcs_client.client import GcsClient, VehicleStatus
from tools.campaign.inproc_flight import fly_world, vehicle_script

pytestmark = [pytest.mark.sitl, pytest.mark.slow]

MISSIONS = REPO_ROOT / "missions"
#: Sim seconds without a new MISSION_ITEM_REACHED after which a flight is declared stuck (the longest
#: item here, RTL from 130 m with a climb to MIS_RTL_ALT and the descent, takes about 60 s).
PROGRESS_TIMEOUT_SIM_S = 90.0


def _fly(client: GcsClient, plan: MissionPlan, sim: subprocess.Popen[bytes]) -> tuple[VehicleStatus, list[str]]:
    """Upload, arm, start; wait until landed and disarmed, stuck, or the sim ended the run. Final status + texts."""
    upload_arm_start(client, plan)
    serial = client.statustext_serial
    texts: list[str] = []
    seen_armed = False
    status = client.telemetry()
    t_progress = status.sim_time_s or 0.0
    reached = len(status.items_reached)
    while True:
        client.pump(0.1)
        status = client.telemetry()
        texts += [t.text for t in client.statustexts_since(serial)]
        serial = client.statustext_serial
        seen_armed = seen_armed or status.armed
        sim_s = status.sim_time_s or 0.0
        if seen_armed and landed_disarmed(status):
            client.pump(0.5)  # late MISSION_ITEM_REACHED
            return client.telemetry(), texts
        if len(status.items_reached) != reached:
            reached, t_progress = len(status.items_reached), sim_s
        if sim_s - t_progress > PROGRESS_TIMEOUT_SIM_S:
            return status, texts
        if sim.poll() is not None:  # e.g. a collision ends the run
            return status, texts


def _check(n: int, reached: list[int], texts: list[str], sim: dict, ap: dict, r_safe_m: float, tol_m: float) -> None:
    progress = f"reached {reached} of {n}, sim summary {sim}"
    assert sim["collisions"] == 0, progress
    clearance_m = sim["min_clearance_m"]
    assert isinstance(clearance_m, float) and clearance_m >= r_safe_m - tol_m, progress
    bypassed = {bypassed_seq(t) for t in texts if is_bypassed(t)}
    assert not bypassed & set(reached), progress  # never both
    assert sorted(set(reached) | bypassed) == list(range(n)), progress
    assert reached == sorted(reached), progress  # in order
    decisions = [t for t in texts if t.startswith("avoid: ")]
    assert decisions, texts  # the obstacles were in the way: the planner had to go around them
    assert ap["reached_seqs"] == reached and ap["bypassed_seqs"] == sorted(bypassed), ap
    assert ap["items_bypassed"] == len(bypassed) and ap["landed"] and ap["disarmed"]


def test_city_block_through_unknown_obstacles_over_sitl(tmp_path: Path) -> None:
    mission = MISSIONS / "city_block_delivery.yaml"
    plan = load_mission_file(mission)
    with sitl_pair(tmp_path, mission, seed=1) as s, connect_gcs(s.gcs_url) as client:
        r_safe_m, tol_m = client.get_param("CA_RSAFE_M"), client.get_param("CA_TRACK_TOL_M")
        status, texts = _fly(client, plan, s.sim)
    assert landed_disarmed(status), logs(tmp_path)
    sim, ap = read_json(tmp_path / "sim_summary.json"), read_json(tmp_path / "autopilot_summary.json")
    _check(len(plan.items), list(status.items_reached), texts, sim, ap, r_safe_m, tol_m)  # type: ignore[arg-type]


@pytest.mark.parametrize(
    "name",
    [
        pytest.param("storm_obstacles.yaml", id="storm"),  # waypoints 36 and 54 lie inside the spheres
        pytest.param("lissajous_obstacles.yaml", id="lissajous"),  # waypoints 14 and 38 lie inside the spheres
    ],
)
def test_mission_through_unknown_obstacles_in_process(name: str) -> None:
    mission = MISSIONS / name
    record = fly_world(mission, seed=1, script=vehicle_script(0, 10.0, 0.0), stall_s=None, end_when_landed=True,
                       sim_time_s=600.0)  # fmt: skip
    assert not record["error"] and not record["timed_out"], record["error"]
    defaults = {spec.name: spec.default for spec in planner_param_specs()}
    texts, ap = record["texts"], record["autopilot"]
    n = len(load_mission_file(mission).items)
    _check(n, list(ap["reached_seqs"]), texts, record["sim"], ap, defaults["CA_RSAFE_M"], defaults["CA_TRACK_TOL_M"])
