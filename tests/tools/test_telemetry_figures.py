"""tools.rrd_figures: a recording becomes the paper-style PNGs and a CSV equal to the logged series."""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
import pytest

from autopilot.telemetry import make_listener
from tools.benchmarks.telemetry import synthetic_records
from tools.rrd_figures import FIGURES, main

N_STEPS = 500


@pytest.fixture(scope="module")
def recording(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, np.ndarray]:
    path = tmp_path_factory.mktemp("fig") / "flight.rrd"
    telemetry = make_listener(f"save:{path}")
    assert telemetry is not None
    pos = []
    for record in synthetic_records(N_STEPS):
        pos.append(record.state.pos_ned_m)
        telemetry.on_step(record)
    telemetry.on_route([(0, 0, 0), (20, 0, -5), (20, 20, -5)])
    telemetry.close()
    return path, np.asarray(pos)


def test_figures_and_csv(recording: tuple[Path, np.ndarray], tmp_path: Path) -> None:
    path, pos = recording
    assert main([str(path), "--out", str(tmp_path)]) == 0
    for name in FIGURES:
        data = (tmp_path / name).read_bytes()
        assert data[:8] == b"\x89PNG\r\n\x1a\n" and len(data) > 5000, name
    with (tmp_path / "series.csv").open() as f:
        rows = list(csv.reader(f))
    header, body = rows[0], np.asarray(rows[1:], dtype=float)
    assert len(body) == N_STEPS
    assert header[:4] == ["t_s", "position/pos_ned_m/north", "position/pos_ned_m/east", "position/pos_ned_m/down"]
    np.testing.assert_array_equal(body[:, 1:4], pos)
    assert np.all(np.diff(body[:, 0]) > 0)
    assert "gains/attitude/kp/k_p yaw" in header and "motors/motor_cmd/m0 front-right" in header
    kp_yaw = body[:, header.index("gains/attitude/kp/k_p yaw")]
    assert np.isfinite(kp_yaw[-1]) and np.count_nonzero(np.diff(kp_yaw[-50:])) <= 10  # 50 Hz, held between samples


def test_unreadable_recording_exits_2(tmp_path: Path) -> None:
    assert main([str(tmp_path / "nope.rrd"), "--out", str(tmp_path)]) == 2
