"""A real Dask cluster on 127.0.0.1 for the campaign tests: ``dask scheduler`` and ``dask worker`` processes,
as docs/campaigns.md tells a user to start them (free port, no dashboard, one thread per worker)."""

from __future__ import annotations

import contextlib
import os
import signal
import socket
import subprocess
import sys
import time
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

REPO_ROOT = Path(__file__).resolve().parent.parent
DASK = str(Path(sys.executable).parent / "dask")


def free_tcp_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


@dataclass
class Cluster:
    address: str
    scheduler: subprocess.Popen[bytes]
    workers: list[subprocess.Popen[bytes]]

    def kill_worker(self, index: int) -> None:
        """SIGKILL one ``dask worker`` (its nanny and worker process: the whole session)."""
        with contextlib.suppress(ProcessLookupError):
            os.killpg(self.workers[index].pid, signal.SIGKILL)
        self.workers[index].wait()


def _start(args: list[str], log: Path) -> subprocess.Popen[bytes]:
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(filter(None, [str(REPO_ROOT), os.environ.get("PYTHONPATH")])))
    with open(log, "ab") as out:
        return subprocess.Popen(args, cwd=log.parent, env=env, stdout=out, stderr=out, start_new_session=True)


@contextlib.contextmanager
def dask_cluster(log_dir: Path, n_workers: int = 2) -> Iterator[Cluster]:
    """``dask scheduler`` + ``n_workers`` x ``dask worker --nthreads 1`` on 127.0.0.1; all killed on exit."""
    from distributed import Client

    log_dir.mkdir(parents=True, exist_ok=True)
    port = free_tcp_port()
    address = f"tcp://127.0.0.1:{port}"
    no_dashboard = ["--no-dashboard", "--dashboard-address", "127.0.0.1:0"]
    scheduler_args = [DASK, "scheduler", "--host", "127.0.0.1", "--port", str(port), *no_dashboard]
    scheduler = _start(scheduler_args, log_dir / "scheduler.log")
    worker_args = [DASK, "worker", address, "--nthreads", "1", "--nworkers", "1", "--host", "127.0.0.1", *no_dashboard]
    workers = [_start([*worker_args, "--name", f"w{i}"], log_dir / f"worker{i}.log") for i in range(n_workers)]
    cluster = Cluster(address, scheduler, workers)
    try:
        deadline = time.monotonic() + 120.0
        with Client(address, timeout="60s") as client:
            client.wait_for_workers(n_workers, timeout=max(1.0, deadline - time.monotonic()))
        yield cluster
    finally:
        for proc in [*workers, scheduler]:
            with contextlib.suppress(ProcessLookupError):
                os.killpg(proc.pid, signal.SIGTERM)
        for proc in [*workers, scheduler]:
            try:
                proc.wait(timeout=10)
            except subprocess.TimeoutExpired:
                os.killpg(proc.pid, signal.SIGKILL)
                proc.wait()
