"""``tools.run``'s process handling (tools.run.processes.fly) with stand-in children: the flight (``quadsitl up``)
stops when the ground station's summary appears, not when its process exits, and an old summary stops nothing."""

from __future__ import annotations

import sys
import time
from pathlib import Path

from tools.run.processes import fly

# Stands in for `quadsitl up`: runs until SIGTERM, then writes when it stopped (a clean exit, as up's is).
UP = """
import signal, sys, time
def stop(*_):
    open(sys.argv[1], "w").write(repr(time.monotonic()))
    sys.exit(0)
signal.signal(signal.SIGTERM, stop)
while True:
    time.sleep(0.05)
"""
# Stands in for the ground station: writes its summary after a short flight, then is slow to exit.
GCS = """
import sys, time
time.sleep(float(sys.argv[2]))
open(sys.argv[1], "w").write("{}")
time.sleep(float(sys.argv[3]))
open(sys.argv[4], "w").write(repr(time.monotonic()))
"""


def _fly(tmp_path: Path, flight_s: float, exit_s: float) -> tuple[float, float, int | None, int | None]:
    summary, up_stopped, gcs_exited = tmp_path / "gcs_summary.json", tmp_path / "up_at", tmp_path / "gcs_at"
    up_cmd = [sys.executable, "-c", UP, str(up_stopped)]
    gcs_cmd = [sys.executable, "-c", GCS, str(summary), str(flight_s), str(exit_s), str(gcs_exited)]
    outcome = fly(up_cmd, gcs_cmd, tmp_path, wall_limit_s=60.0, gcs_summary=summary)
    assert not (outcome.timed_out or outcome.up_died_first or outcome.interrupted)
    return float(up_stopped.read_text()), float(gcs_exited.read_text()), outcome.gcs_rc, outcome.up_rc


def test_the_flight_stops_when_the_ground_station_writes_its_summary_not_when_it_exits(tmp_path: Path) -> None:
    up_at, gcs_at, gcs_rc, up_rc = _fly(tmp_path, flight_s=1.0, exit_s=3.0)
    assert (gcs_rc, up_rc) == (0, 0)  # both exit codes kept
    assert gcs_at - up_at > 2.0, (up_at, gcs_at)  # up stopped while the ground station was still exiting


def test_a_summary_left_by_an_earlier_run_does_not_stop_the_flight(tmp_path: Path) -> None:
    (tmp_path / "gcs_summary.json").write_text('{"ok": true}')  # from a run before, in the same --out-dir
    t0 = time.monotonic()
    up_at, _, gcs_rc, _ = _fly(tmp_path, flight_s=1.5, exit_s=0.0)
    assert gcs_rc == 0 and up_at - t0 > 1.4, up_at - t0  # stopped after this run's summary, not at once
