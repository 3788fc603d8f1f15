"""Lockstep determinism with the real autopilot: a scripted flight is bit-identical in sim time
through a lossy link (``--sim-loss 0.1``: 10 % of datagrams dropped each way) and at --speed 1 vs --speed max."""

from __future__ import annotations

from pathlib import Path

import pytest
from sitl_procs import Ports, logs, read_json, start_autopilot, start_sim, stop

pytestmark = [pytest.mark.sitl, pytest.mark.slow]

#: The EKF is healthy (aligned, GPS fused for 1 s) 1.5 s after start: the script arms at 2 s.
SCRIPT = """
- {at_s: 2.0, cmd: arm}
- {at_s: 2.1, cmd: takeoff, alt_m: 5}
- {at_s: 4.3, cmd: goto, north_m: 4, east_m: 2, alt_m: 6}
"""


def _start_pair(log_dir: Path, script: Path, duration_s: float, speed: str, *sim_extra: str):  # type: ignore[no-untyped-def]
    port = Ports.free().sim
    extra = ("--seed", "11", "--duration-s", str(duration_s), "--speed", speed, "--start-timeout-s", "120")
    extra += ("--autopilot-timeout-s", "30")  # a stall on a loaded machine must not end the run
    sim = start_sim(log_dir, port, *extra, *sim_extra)
    ap = start_autopilot(log_dir, port, None, "--script", str(script))
    return sim, ap


def _finish(log_dir: Path, sim, ap) -> tuple[str, str]:  # type: ignore[no-untyped-def]
    try:
        sim.wait(timeout=240)
    finally:
        stop(ap)
        sim_rc = stop(sim)
    assert sim_rc == 0, logs(log_dir)
    sim_summary = read_json(log_dir / "sim_summary.json")
    ap_summary = read_json(log_dir / "autopilot_summary.json")
    assert sim_summary["end_reason"] == "COMPLETED"
    assert ap_summary["flying_steps"] > 0  # it did fly
    return str(sim_summary["truth_sha256"]), str(ap_summary["truth_sha256"])


def test_lossy_link_gives_the_identical_flight(tmp_path: Path) -> None:
    """``quadsitl sim --sim-loss 0.1``: the sim's lossy relay drops 10 % of the datagrams each way."""
    script = tmp_path / "flight.yaml"
    script.write_text(SCRIPT)
    clean = _start_pair(tmp_path / "clean", script, 6.0, "max")
    lossy = _start_pair(tmp_path / "lossy", script, 6.0, "max", "--sim-loss", "0.1")
    try:
        clean_hashes = _finish(tmp_path / "clean", *clean)
        lossy_hashes = _finish(tmp_path / "lossy", *lossy)
    finally:
        for proc in (*clean, *lossy):
            stop(proc)
    assert lossy_hashes == clean_hashes
    sim_summary = read_json(tmp_path / "lossy" / "sim_summary.json")
    assert sim_summary["loss_dropped"] > 50  # the link really lost datagrams
    assert sim_summary["resends"] > 0


def test_speed_1_and_speed_max_give_the_identical_flight(tmp_path: Path) -> None:
    script = tmp_path / "flight.yaml"
    script.write_text(SCRIPT)
    paced = _start_pair(tmp_path / "paced", script, 3.0, "1")
    fast = _start_pair(tmp_path / "fast", script, 3.0, "max")
    try:
        paced_hashes = _finish(tmp_path / "paced", *paced)
        fast_hashes = _finish(tmp_path / "fast", *fast)
    finally:
        for proc in (*paced, *fast):
            stop(proc)
    assert paced_hashes == fast_hashes
    paced_summary = read_json(tmp_path / "paced" / "sim_summary.json")
    assert float(paced_summary["real_time_factor"]) <= 1.05  # really paced to real time  # type: ignore[arg-type]
