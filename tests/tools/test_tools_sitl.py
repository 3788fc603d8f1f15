"""``tools.sitl``, the launcher CI suites use: a flight through it, its summaries, and a failed process reported."""

from __future__ import annotations

from pathlib import Path

import pytest

from tools.sitl import SitlError, sitl_run

pytestmark = [pytest.mark.sitl, pytest.mark.slow]


def test_a_flight_through_the_public_launcher_and_its_summaries(tmp_path: Path) -> None:
    with sitl_run(tmp_path, vehicle="x500", seed=2) as run, run.gcs_client() as gcs:
        gcs.wait_until(lambda s: s.home is not None and s.gps_fix_type >= 3, 120.0)
        gcs.arm()
        gcs.takeoff(5.0)
        gcs.wait_until(lambda s: (s.alt_rel_m or 0.0) > 4.5, 120.0)
        gcs.land()
        gcs.wait_until(lambda s: not s.armed, 120.0)
    assert run.api_url is None and run.gcs_url.startswith("udpin:127.0.0.1:")
    assert run.sim_summary["end_reason"] == "STOPPED" and run.sim_summary["collisions"] == 0
    assert run.autopilot_summary["landed"] and run.autopilot_summary["disarmed"]
    assert (tmp_path / "sim.log").is_file() and (tmp_path / "autopilot.log").is_file()


def test_a_process_that_fails_is_reported_with_its_log(tmp_path: Path) -> None:
    missing = tmp_path / "no_such_params.yaml"
    with (
        pytest.raises(SitlError, match=r"autopilot exited [1-9]") as err,
        sitl_run(tmp_path, vehicle="x500", autopilot_args=("--params", str(missing))) as run,
    ):
        run.autopilot.wait(timeout=120)  # it refuses the missing parameter file and exits on its own
    assert "--- autopilot.log" in str(err.value) and "no_such_params" in str(err.value)
