"""The processes of ``quadsitl up``: start the simulator and every autopilot, watch them, stop them all.

One rule for one vehicle and many: the run ends when the simulator exits, when every autopilot has exited, or on
SIGINT/SIGTERM (forwarded to every child); then every child still running is stopped (autopilots first, so the
simulator sums up last). An autopilot exiting while others still fly is reported and leaves them flying; with one
vehicle its autopilot is every autopilot, so either process ending stops the other.

Exit status (:func:`run_status`): the non-zero status of the process whose exit ended the run (the simulator, or
the last autopilot), else the simulator's non-zero status (3 autopilot lost, 4 vehicle ended the run), else that
of an autopilot stopped with the run; 0 when all ended cleanly. Killed by signal N: 128 + N, as a shell says.
"""

from __future__ import annotations

import contextlib
import os
import signal
import subprocess
import time
from collections.abc import Sequence
from dataclasses import dataclass
from types import FrameType

#: How long a child gets to exit after SIGTERM before it is killed (wall s).
STOP_TIMEOUT_S = 15.0
#: How often the children are polled (wall s).
POLL_S = 0.05


@dataclass(frozen=True, slots=True)
class RunOutcome:
    """How each child ended: exit statuses, who ended the run, which autopilots exited while others flew on."""

    sim_rc: int
    autopilot_rcs: tuple[int, ...]
    ended_by: int | None  # the index of the autopilot whose exit ended the run; -1: the simulator; None: a signal
    left_early: frozenset[int]  # autopilots that exited while others flew on


def stop_process(proc: subprocess.Popen[bytes], timeout_s: float = STOP_TIMEOUT_S, *, signalled: bool = False) -> int:
    """SIGTERM (a clean stop: summaries are written), wait up to ``timeout_s``, then SIGKILL; the exit status.

    ``signalled``: the process was already sent its stop signal; only wait (a second SIGTERM could hit it
    after it restored the default handler during its own shutdown and kill it mid-summary).
    """
    if proc.poll() is None:
        if not signalled:
            proc.send_signal(signal.SIGTERM)
        try:
            proc.wait(timeout=timeout_s)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
    return int(proc.returncode)


def stop_group(proc: subprocess.Popen[bytes], grace_s: float) -> None:
    """Stop a process started in its own session and everything in its group: SIGTERM (summaries get written),
    ``grace_s`` to exit, then SIGKILL of whatever is left."""
    with contextlib.suppress(ProcessLookupError):
        os.killpg(proc.pid, signal.SIGTERM)
    with contextlib.suppress(subprocess.TimeoutExpired):
        proc.wait(timeout=grace_s)
    with contextlib.suppress(ProcessLookupError):
        os.killpg(proc.pid, signal.SIGKILL)
    proc.wait()


def supervise(sim_cmd: list[str], autopilot_cmds: Sequence[list[str]], names: Sequence[str]) -> RunOutcome:
    """Run the simulator and the autopilots (``names``: each one's, for the line saying it left) by the rule above."""
    stop = {"signal": 0}

    def _on_signal(signum: int, _frame: FrameType | None) -> None:
        stop["signal"] = signum

    previous = {sig: signal.signal(sig, _on_signal) for sig in (signal.SIGINT, signal.SIGTERM)}
    env = dict(os.environ, PYTHONUNBUFFERED="1")
    sim = subprocess.Popen(sim_cmd, env=env)
    autopilots = [subprocess.Popen(cmd, env=env) for cmd in autopilot_cmds]
    left: set[int] = set()
    ended_by: int | None = None
    try:
        while stop["signal"] == 0:
            if sim.poll() is not None:
                ended_by = -1
                break
            gone = [i for i, proc in enumerate(autopilots) if proc.poll() is not None]
            if len(gone) == len(autopilots):
                ended_by = min(set(gone) - left, default=gone[-1])
                break
            for i in sorted(set(gone) - left):
                left.add(i)
                rc = autopilots[i].returncode
                print(f"quadsitl up: {names[i]}'s autopilot exited {rc}; the others fly on", flush=True)
            time.sleep(POLL_S)
        signalled = stop["signal"] != 0
        if signalled:
            for proc in (*autopilots, sim):
                if proc.poll() is None:
                    proc.send_signal(stop["signal"])
        for proc in autopilots:
            stop_process(proc, signalled=signalled)
        stop_process(sim, signalled=signalled)
    finally:
        for proc in (*autopilots, sim):
            if proc.poll() is None:
                proc.kill()
                proc.wait()
        for sig, handler in previous.items():
            signal.signal(sig, handler)
    return RunOutcome(sim.returncode, tuple(p.returncode for p in autopilots), ended_by, frozenset(left))


def run_status(outcome: RunOutcome) -> int:
    """The exit status of ``quadsitl up`` for ``outcome`` (see the module's docstring)."""
    if outcome.ended_by == -1:
        first = outcome.sim_rc
    elif outcome.ended_by is not None:
        first = outcome.autopilot_rcs[outcome.ended_by]
    else:
        first = 0
    stopped = [rc for i, rc in enumerate(outcome.autopilot_rcs) if i not in outcome.left_early and rc != 0]
    rc = first or outcome.sim_rc or (stopped[0] if stopped else 0)
    return 128 - rc if rc < 0 else rc
