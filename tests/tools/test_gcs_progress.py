"""The ground-station progress text ``tools.gcs fly`` shows (tools/gcs/progress.py)."""

from __future__ import annotations

import dataclasses

import pytest

from mavlink_bridge.gcs_client.telemetry import TelemetryState
from tools.gcs.progress import MissionBars, flight_state_text, sim_time_text


def test_state_and_sim_time_text_keep_fixed_columns() -> None:
    status = dataclasses.replace(TelemetryState(1).status(), mode_name="AUTO_MISSION", armed=True, sim_time_s=12.34)
    assert flight_state_text(status) == "AUTO_MISSION  ARMED   "
    assert sim_time_text(status) == "   12.3 s"
    unknown = dataclasses.replace(status, armed=False, sim_time_s=None)
    assert flight_state_text(unknown) == "AUTO_MISSION  disarmed"
    assert sim_time_text(unknown) == "   ?"


def test_mission_bars_show_each_row_and_do_nothing_when_disabled(capsys: pytest.CaptureFixture[str]) -> None:
    with MissionBars("[bold]{task.description:<10}", [("alpha", 3), ("beta", 0)], enabled=False) as bars:
        bars.show(1, 5, "ignored")  # no bar, no error
    assert capsys.readouterr().out == ""
    with MissionBars("[bold]{task.description:<10}", [("alpha", 3), ("beta", 0)], enabled=True) as bars:
        bars.show(0, 2, "done t=    1.0 s")
    text = capsys.readouterr().out
    assert "alpha" in text and "2/3" in text and "done t=    1.0 s" in text
    assert "beta" in text and "0/1" in text
