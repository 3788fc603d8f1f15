"""`tools.gcs fly` tells the truth (issue 13): a failsafe during the mission (a geofence breach that only warns
too) fails the flight with that reason; waypoints the vehicle flew around are counted as bypassed."""

from __future__ import annotations

import json
import threading
import time

from test_gcs_script import vehicle_link  # noqa: F401  (the fixture)

from mavlink_bridge.contract.vehicle_api import Severity
from tools.gcs import cli as gcs


def _say_when_armed(harness, texts: list[tuple[Severity, str]]) -> threading.Thread:  # type: ignore[no-untyped-def]
    """Send ``texts`` from the vehicle once it is armed (as the autopilot does in flight)."""

    def run() -> None:
        deadline = time.monotonic() + 20.0
        while not harness.vehicle.armed and time.monotonic() < deadline:
            time.sleep(0.005)
        with harness.locked():
            for severity, text in texts:
                harness.server.statustext(severity, text)

    thread = threading.Thread(target=run, daemon=True)
    thread.start()
    return thread


def test_a_geofence_breach_that_only_warns_fails_the_flight(vehicle_link, tmp_path, capsys) -> None:  # noqa: F811
    harness, connect, mission = vehicle_link
    with harness.locked():
        harness.vehicle.item_period_us = 400_000  # a flight long enough for the text to arrive during it
    breach = "Failsafe: geofence breach: outside the uploaded geofence"
    thread = _say_when_armed(harness, [(Severity.WARNING, breach)])
    summary_path = tmp_path / "s.json"
    rc = gcs.main([*connect, "fly", str(mission), "--summary", str(summary_path), "--no-progress", "--timeout-s", "30"])
    thread.join(5.0)
    summary = json.loads(summary_path.read_text())
    assert rc != 0 and summary["ok"] is False
    assert summary["reason"] == f"failsafe during the mission: {breach}"
    assert breach in capsys.readouterr().err


def test_bypassed_waypoints_are_counted_and_the_flight_still_succeeds(vehicle_link, tmp_path, capsys) -> None:  # noqa: F811
    harness, connect, mission = vehicle_link
    with harness.locked():
        harness.vehicle.item_period_us = 400_000
    thread = _say_when_armed(harness, [(Severity.WARNING, "Bypassed item 2: a detour rejoined the route past it")])
    summary_path = tmp_path / "s.json"
    rc = gcs.main([*connect, "fly", str(mission), "--summary", str(summary_path), "--no-progress", "--timeout-s", "30"])
    thread.join(5.0)
    summary = json.loads(summary_path.read_text())
    assert rc == 0 and summary["ok"] is True and summary["items_bypassed"] == 1
    assert "1 bypassed" in capsys.readouterr().out
