"""Shared pytest fixtures: free loopback ports and the repository root on sys.path (for tools/)."""

from __future__ import annotations

import os
import socket
import sys
from pathlib import Path

import pytest

REPO_ROOT = Path(__file__).resolve().parent.parent
if str(REPO_ROOT) not in sys.path:
    sys.path.insert(0, str(REPO_ROOT))


def free_udp_port() -> int:
    """A UDP port on 127.0.0.1 that is free right now."""
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


@pytest.fixture
def udp_port() -> int:
    return free_udp_port()


@pytest.fixture
def repo_root() -> Path:
    return REPO_ROOT


def pytest_configure(config: pytest.Config) -> None:
    """Under pytest-xdist (``make test``: two workers), each worker and every process its tests start (simulator,
    autopilots, ground station, Dask workers) run on one CPU of their own, worker k on the k-th allowed CPU.

    A lockstep flight is a ping-pong: one of its processes works while the other waits. On one CPU the hand-off is
    a local context switch; spread over two it is a cross-CPU wake-up, which a virtual machine makes expensive, and
    two flights side by side then keep taking each other's CPU. Measured on the 2-core VM (docs/testing.md):
    test_sitl_failures.py and test_sitl_routing.py on two workers, 74.8-78.2 s pinned against 81.7-86.0 s not.
    The lockstep makes a flight the same on any CPU; a plain ``pytest`` run (no workers) is not pinned."""
    worker = os.environ.get("PYTEST_XDIST_WORKER", "")
    if not worker.startswith("gw") or not hasattr(os, "sched_setaffinity"):
        return
    cpus = sorted(os.sched_getaffinity(0))
    if len(cpus) >= 2:
        os.sched_setaffinity(0, {cpus[int(worker.removeprefix("gw")) % len(cpus)]})
