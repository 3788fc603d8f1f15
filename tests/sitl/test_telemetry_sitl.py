"""A short real flight (sim + autopilot processes, --rerun save:PATH): the recording equals the autopilot's own log."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from sitl_procs import logs, read_json, start_autopilot, start_sim, stop

from autopilot.telemetry import entities as ent
from autopilot.telemetry.recording_reader import read_recording

pytestmark = [pytest.mark.sitl, pytest.mark.slow]

SCRIPT = """\
- {at_s: 2.0, cmd: arm}
- {at_s: 2.5, cmd: takeoff, alt_m: 8}
- {at_s: 5.5, cmd: goto, north_m: 6, east_m: 3, alt_m: 8}
"""
DURATION_S = 8.5  # the EKF is healthy 1.5 s after start: the script arms at 2 s


def test_recording_of_a_real_flight_matches_the_autopilot_summary(tmp_path: Path, udp_port: int) -> None:
    script = tmp_path / "flight.yaml"
    script.write_text(SCRIPT)
    rrd = tmp_path / "flight.rrd"
    sim = start_sim(tmp_path, udp_port, "--duration-s", str(DURATION_S))
    ap = start_autopilot(tmp_path, udp_port, None, "--script", str(script), "--rerun", f"save:{rrd}")
    try:
        sim.wait(timeout=240)
    finally:
        stop(ap)
        stop(sim)
    summary_path = tmp_path / "autopilot_summary.json"
    assert summary_path.is_file() and rrd.is_file(), logs(tmp_path)
    summary = read_json(summary_path)
    r = read_recording(rrd)

    pos = r.scalars(ent.POS_NED)
    assert len(pos.t_us) == summary["frames"]  # one row per lockstep step
    assert np.all(np.diff(pos.t_us) == 4000)  # 250 Hz, strictly increasing sim time
    assert pos.t_us[-1] * 1e-6 == pytest.approx(summary["sim_time_s"], abs=1e-6)

    flying = ~np.isnan(r.scalars(ent.ATT_ERR).values[:, 0])  # the controller block, every step (NaN while idle)
    assert flying.sum() == summary["flying_steps"]
    err = np.linalg.norm(r.scalars(ent.POS_ERR_NED).values[flying], axis=1)
    assert np.sqrt(np.mean(err**2)) == pytest.approx(summary["tracking_pos_err_rms_m"], rel=1e-9)
    assert err.max() == pytest.approx(summary["tracking_pos_err_max_m"], rel=1e-9)
    att = np.radians(r.scalars(ent.ATT_ERR).values[flying, :2])
    att_rms_deg = np.degrees(np.sqrt(np.mean(np.sum(att**2, axis=1))))
    assert att_rms_deg == pytest.approx(summary["tracking_att_err_rms_deg"], rel=1e-9)

    texts = r.text_log()
    for change in summary["mode_history"]:  # every mode change is in the log within one step
        hits = [t for t, _, text in texts if change["mode"].lower() in text.lower()]
        assert any(abs(t * 1e-6 - change["t_s"]) <= 0.0041 for t in hits), (change, texts)
    assert r.blueprints >= 1
    tr = r.translations()
    assert len(tr.t_us) == pytest.approx(summary["sim_time_s"] * 25.0, abs=2)
    idx = np.searchsorted(pos.t_us, tr.t_us)
    np.testing.assert_allclose(tr.values, pos.values[idx], atol=1e-4)  # pose and series agree
