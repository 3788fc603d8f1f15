"""Campaigns on a real Dask cluster (``dask scheduler`` + ``dask worker`` processes on 127.0.0.1) and through
faults: Ctrl-C then ``--resume`` on a LocalCluster (the reference rows), the same rows from a real cluster, a worker
killed mid-campaign."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pyarrow.parquet as pq
import pytest
from campaign_files import write_campaign
from dask_cluster import REPO_ROOT, dask_cluster

from tools.campaign.cli import main

pytestmark = [pytest.mark.slow]

#: What must be identical between two runs of the same case: its inputs, its outcome and its flight.
SAME = (
    *("case_id", "sim_seed", "vary.world.wind.north_m_s", "failures", "vehicle", "world_yaml", "params_yaml"),
    *("script_yaml", "status", "reason", "end_reason", "items_reached", "landed", "tracking_pos_rms_m", "truth_hash"),
)


def _rows(out: Path) -> list[dict]:
    return pq.read_table(out / "results.parquet").to_pylist()


def _same(a: list[dict], b: list[dict]) -> None:
    assert [r["case_id"] for r in a] == [r["case_id"] for r in b]
    for ra, rb in zip(a, b, strict=True):
        for key in SAME:
            assert ra[key] == rb[key], (ra["case_id"], key)


def _cli(*args: str) -> subprocess.Popen[bytes]:
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(filter(None, [str(REPO_ROOT), os.environ.get("PYTHONPATH")])))
    cmd = [sys.executable, "-m", "quadsitl_cli", "campaign", *args, "--no-progress"]
    # SIGINT at its default, so Python turns it into KeyboardInterrupt: a test run started in the background of a
    # shell without job control (nohup, `cmd &` in a script) inherits it ignored, and the Ctrl-C would be lost
    return subprocess.Popen(cmd, cwd=REPO_ROOT, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))  # fmt: skip


def _wait_for(path: Path, proc: subprocess.Popen[bytes], timeout_s: float = 180.0) -> None:
    deadline = time.monotonic() + timeout_s
    while not path.exists():
        assert proc.poll() is None, proc.stdout.read().decode() if proc.stdout else ""
        assert time.monotonic() < deadline, f"{path} never appeared"
        time.sleep(0.1)


#: Cases of the inproc campaign (each about 0.5 s of wall): every worker of the two-worker runs flies some, and the
#: Ctrl-C (sent once the third case has started) lands while most are still to fly.
CASES = 6


@pytest.fixture(scope="module")
def resumed(tmp_path_factory: pytest.TempPathFactory) -> tuple[list[dict], list[dict]]:
    """The reference rows: an inproc campaign on the embedded LocalCluster, stopped by Ctrl-C as its flights begin,
    then resumed; (the rows written before the Ctrl-C, every row after the resume)."""
    folder = tmp_path_factory.mktemp("resumed")
    path = write_campaign(folder, cases=CASES)
    out = folder / "out"
    proc = _cli(str(path), "--out", str(out), "--workers", "1")
    # a worker writes a case's folder as it starts flying it (one worker: in order): with case 2 started, case 0's row
    # has reached the client (its result was sent a whole flight ago; waiting for case 1's folder only, a slow
    # machine's Ctrl-C could beat case 0's result to the client and leave nothing written), and cases 2-5 are left
    _wait_for(out / "cases" / "case-000002", proc)
    proc.send_signal(signal.SIGINT)
    output, _ = proc.communicate(timeout=120)
    assert proc.returncode == 130, output.decode()
    assert "--resume" in output.decode()
    first = _rows(out)  # what was done is written: the table, the report
    assert 1 <= len(first) < CASES and (out / "report.md").is_file()
    assert main([str(path), "--out", str(out), "--workers", "2", "--no-progress"]) == 2  # refused: use --resume
    assert main([str(path), "--out", str(out), "--resume", "--workers", "2", "--no-progress"]) == 1
    return first, _rows(out)


def test_ctrl_c_then_resume_flies_every_case_exactly_once(resumed: tuple[list[dict], list[dict]]) -> None:
    first, rows = resumed
    assert [r["case_id"] for r in rows] == list(range(CASES))
    done_before = {r["case_id"]: r for r in first}
    for r in rows:
        if r["case_id"] in done_before:  # not re-flown: the very same row
            assert json.dumps(r, sort_keys=True) == json.dumps(done_before[r["case_id"]], sort_keys=True)  # NaN too


def test_dask_scheduler_and_workers_give_the_local_cluster_rows(
    tmp_path: Path, resumed: tuple[list[dict], list[dict]]
) -> None:
    """An uninterrupted run on a real cluster: the same rows as the interrupted and resumed LocalCluster run."""
    with dask_cluster(tmp_path / "cluster", n_workers=2) as cluster:
        out = tmp_path / "out"
        rc = main(
            [str(write_campaign(tmp_path, cases=CASES)), "--out", str(out), "--scheduler", cluster.address,
             "--no-progress"]
        )  # fmt: skip
    assert rc == 1
    rows = _rows(out)
    _same(rows, resumed[1])
    assert len({r["worker"] for r in rows}) == 2  # both dask workers flew cases


@pytest.mark.sitl
def test_a_worker_killed_mid_campaign_costs_only_its_running_case(
    tmp_path: Path, resumed: tuple[list[dict], list[dict]]
) -> None:
    path = write_campaign(tmp_path, cases=2, mode="sitl")
    out = tmp_path / "out"
    with dask_cluster(tmp_path / "cluster", n_workers=2) as cluster:
        proc = _cli(str(path), "--out", str(out), "--scheduler", cluster.address)
        _wait_for(out / "cases" / "case-000001" / "autopilot.log", proc)  # both flights are in the air
        time.sleep(1.0)
        cluster.kill_worker(0)
        output, _ = proc.communicate(timeout=300)
    assert proc.returncode == 1, output.decode()
    rows = _rows(out)
    assert [r["case_id"] for r in rows] == [0, 1]  # every case exactly once
    assert all(r["status"] in ("ok", "fail") for r in rows), [r["reason"] for r in rows]
    for r, ref in zip(rows, resumed[1][:2], strict=True):  # the re-flown case is the same flight (sitl = inproc)
        assert (r["truth_hash"], r["status"]) == (ref["truth_hash"], ref["status"])
    assert len({r["worker"] for r in rows}) >= 1
