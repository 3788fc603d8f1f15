"""A short mission and campaign files for the campaign tests (takeoff to 5 m, 10 m hop, land: ~20 s sim)."""

from __future__ import annotations

from pathlib import Path

from sitl_procs import fence_world_yaml

HOP = fence_world_yaml(
    "hop",
    speed_m_s=5.0,
    mission=["takeoff: {alt_m: 5}", "waypoint: {north_m: 10, east_m: 0, alt_m: 5, accept_radius_m: 1.0}", "land: {}"],
    fence=["inclusion_circle: {north_m: 0, east_m: 0, radius_m: 100}"],
    world=["wind: {north_m_s: 0.5, east_m_s: 0.0, down_m_s: 0.0, gust_m_s: 0.2}", "payload_kg: 0.0"],
)

#: Seed 3: case 0 draws the motor failure (a GROUND_IMPACT: a failing case), cases 1-3 none, 4 and 5 the failure.
CAMPAIGN = """\
name: hop-test
base: hop.yaml
cases: {cases}
seed: 3
mode: {mode}
sim_time_s: 25
deadline_s: {deadline_s}
vary:
  world.wind.north_m_s: {{uniform: [-2, 2]}}
  failures: {{choice: [[], [{{at_s: 12, inject: motor_off, motor: 2}}]]}}
pass_if: {{landed: true, collisions: 0, items_missed: 0}}
"""


def write_campaign(folder: Path, *, cases: int = 4, mode: str = "inproc", deadline_s: float = 300.0) -> Path:
    """``folder/hop.yaml`` and ``folder/campaign.yaml``; the campaign file's path."""
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "hop.yaml").write_text(HOP)
    path = folder / f"campaign_{mode}.yaml"
    path.write_text(CAMPAIGN.format(cases=cases, mode=mode, deadline_s=deadline_s))
    return path
