"""The Dask task of a campaign: fly one case from its materialised files, return its results row.

:func:`run_case` is what every worker runs (a top-level function of one :class:`CasePayload`). The payload
carries the case's file texts, so a worker needs quadsitl installed but none of the campaign's input files.
A case is a world of one vehicle or a fleet (its world lists ``vehicles:``); either is flown by the same path:
``sitl`` starts the one supervisor (``tools.campaign.sitl_flight``) in a new session and kills its whole process
group at the deadline (the row's status is then ``timeout``: Dask has no deadline per task); ``inproc`` flies it
in this process (``inproc_flight``, one vehicle or a fleet), checking the wall clock every simulated second. One
:func:`row` is built from the flight record, with the traffic columns when the case is a fleet. Nothing here
raises for a bad flight: a crash, a refused input or a dead process is an ``error`` row with its reason.
"""

from __future__ import annotations

import functools
import json
import math
import os
import socket
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from autopilot.launch_processes import stop_group
from mavlink_bridge.contract.status_texts import is_failsafe, is_geofence_breach
from tools.campaign.cases import Case, CaseFiles, write_case_files
from tools.campaign.fleet_record import traffic_columns
from tools.campaign.spec import PassRule

STATUSES = ("ok", "fail", "timeout", "error")
#: Wall seconds between SIGTERM and SIGKILL of a case's process group at its deadline.
KILL_GRACE_S = 3.0


@dataclass(frozen=True)
class CasePayload:
    """Everything a worker needs to fly one case and judge it."""

    campaign: str
    root_seed: int
    mode: str
    estimator: str
    sim_time_s: float
    deadline_s: float
    pass_if: tuple[PassRule, ...]
    case: Case
    files: CaseFiles
    case_dir: str
    rerun: str | None = None  # replay: autopilot --rerun save:PATH


#: What a flight and its judging depend on (paths in the repository): ``tools.benchmarks.encounters`` counts a row as
#: a flight of the code at HEAD only when its commit has these as HEAD has them.
FLIGHT_CODE = ("autopilot", "sim", "mavlink_bridge", "tools/encounters.py", "tools/campaign/cases.py",
               "tools/campaign/inproc_flight.py", "tools/campaign/fleet_record.py", "tools/gcs/summary.py",
               "missions/params")  # fmt: skip


@functools.cache
def versions() -> str:
    """The versions a row was flown with (numpy's streams and numba's kernels are tied to them), with the git
    commit of the code when it runs from a checkout (``+dirty`` when the flight code, ``FLIGHT_CODE``, has
    uncommitted changes: no commit holds what flew)."""
    import importlib.metadata as md

    root = Path(__file__).resolve().parent.parent.parent
    try:
        head = subprocess.run(["git", "-C", str(root), "rev-parse", "--short", "HEAD"], capture_output=True, text=True,
                              timeout=10, check=False).stdout.strip()  # fmt: skip
        changed = subprocess.run(["git", "-C", str(root), "status", "--porcelain", "--", *FLIGHT_CODE],
                                 capture_output=True, text=True, timeout=10, check=False).stdout.strip()  # fmt: skip
        head += "+dirty" if head and changed else ""
    except (OSError, subprocess.TimeoutExpired):
        head = ""

    out = []
    for name in ("quadsitl", "numpy", "numba", "scipy", "pymavlink"):
        try:
            out.append(f"{name} {md.version(name)}")
        except md.PackageNotFoundError:
            out.append(f"{name} -")
    return ", ".join([*out, f"python {sys.version.split()[0]}", *([f"git {head}"] if head else [])])


def run_case(payload: CasePayload) -> dict[str, Any]:
    """Fly the case and return its row (see :func:`row`); never raises for a failed flight."""
    t0 = time.monotonic()
    try:
        case_dir = write_case(payload)
        fleet = payload.files.fleet
        if payload.mode == "sitl":
            flight = _fly_sitl(case_dir, payload.deadline_s, payload.rerun)
        elif fleet:
            from tools.campaign import inproc_flight

            flight = inproc_flight.fly(case_dir, payload.deadline_s, payload.rerun, stagger_s=payload.case.stagger_s)
        else:
            from tools.campaign import inproc_flight

            flight = inproc_flight.fly(case_dir, payload.deadline_s, payload.rerun)
    except Exception as exc:  # a refused input or a crash in-process: an error row, the campaign goes on
        flight = {"error": f"{type(exc).__name__}: {exc}", "sim": {}, "autopilot": {}, "texts": []}
    return row(payload, flight, time.monotonic() - t0)


def write_case(payload: CasePayload) -> Path:
    """The case's folder with everything its flight reads: the case files and ``case.json``."""
    case_dir = Path(payload.case_dir)
    write_case_files(payload.files, case_dir)
    case_json = {
        "case_id": payload.case.case_id,
        "vehicle": payload.case.vehicle,
        "sim_seed": payload.case.sim_seed,
        "sim_time_s": payload.sim_time_s,
        "estimator": payload.estimator,
        "fleet": payload.files.fleet,
        "stagger_s": payload.case.stagger_s,
        "deadline_s": payload.deadline_s,
    }
    (case_dir / "case.json").write_text(json.dumps(case_json, indent=1) + "\n")
    return case_dir


def _fly_sitl(case_dir: Path, deadline_s: float, rerun: str | None) -> dict[str, Any]:
    """The supervisor in its own process group, killed as a group at the deadline."""
    from tools.campaign.sitl_flight import FLIGHT_FILE, REPO_ROOT

    (case_dir / FLIGHT_FILE).unlink(missing_ok=True)
    cmd = [sys.executable, "-m", "tools.campaign.sitl_flight", str(case_dir), "--parent-pid", str(os.getpid())]
    if rerun:
        cmd += ["--rerun", rerun]
    env = dict(
        os.environ,
        PYTHONHASHSEED="0",
        PYTHONPATH=os.pathsep.join(filter(None, [str(REPO_ROOT), os.environ.get("PYTHONPATH")])),
    )
    with open(case_dir / "supervisor.log", "wb") as log:
        proc = subprocess.Popen(cmd, cwd=REPO_ROOT, env=env, stdout=log, stderr=log, start_new_session=True)
    try:
        proc.wait(timeout=deadline_s)
    except subprocess.TimeoutExpired:
        kill_group(proc)
        return {"error": "", "timed_out": True, "sim": {}, "autopilot": {}, "texts": [], "pgid": proc.pid}
    finally:
        if proc.poll() is None:  # interrupted (KeyboardInterrupt in a local run): leave nothing behind
            kill_group(proc)
    try:
        flight = json.loads((case_dir / FLIGHT_FILE).read_text())
    except (OSError, ValueError):
        tail = (case_dir / "supervisor.log").read_text(errors="replace").strip().splitlines()[-3:]
        flight = {"error": f"the flight supervisor exited {proc.returncode}: {' | '.join(tail)}"}
    flight["pgid"] = proc.pid
    return flight


def kill_group(proc: subprocess.Popen[bytes]) -> None:
    """The case's process group stopped, with ``KILL_GRACE_S`` to write its summaries."""
    stop_group(proc, KILL_GRACE_S)


def _num(value: Any, default: float = math.nan) -> float:
    return float(value) if isinstance(value, int | float) and not isinstance(value, bool) else default


def row(payload: CasePayload, flight: dict[str, Any], wall_s: float) -> dict[str, Any]:
    """One results row: inputs, outcome and why, metrics, truth hash, versions (docs/campaigns.md lists them)."""
    sim, ap = flight.get("sim") or {}, flight.get("autopilot") or {}
    texts = [str(t) for t in flight.get("texts") or []]
    failsafes = [t for t in texts if is_failsafe(t)]
    total, reached = int(ap.get("items_total", 0)), int(ap.get("items_reached", 0))
    out: dict[str, Any] = {
        "case_id": payload.case.case_id,
        "campaign": payload.campaign,
        "root_seed": payload.root_seed,
        "sim_seed": payload.case.sim_seed,
        "mode": payload.mode,
        "estimator": payload.estimator,
        "sim_time_planned_s": payload.sim_time_s,
        "deadline_s": payload.deadline_s,
        "base": payload.case.base,
        "vehicle": payload.case.vehicle,
        "params": payload.case.params,
        "failures": payload.case.failures_json,
        **{f"vary.{key}": value for key, value in payload.case.overrides},
        "end_reason": str(sim.get("end_reason", "")),
        "items_total": total,
        "items_reached": reached,
        "items_bypassed": int(ap.get("items_bypassed", 0)),
        "items_missed": max(0, total - reached),
        "landed": bool(ap.get("landed", False)),
        "disarmed": bool(ap.get("disarmed", False)),
        "collisions": int(sim.get("collisions", 0)),
        "min_clearance_m": _num(sim.get("min_clearance_m")),
        "fence_breaches": int(ap.get("fence_breaches", sum(is_geofence_breach(t) for t in texts))),
        "tracking_pos_rms_m": _num(ap.get("tracking_pos_err_rms_m")),
        "tracking_pos_max_m": _num(ap.get("tracking_pos_err_max_m")),
        "tracking_att_rms_deg": _num(ap.get("tracking_att_err_rms_deg")),
        "max_tilt_deg": _num(sim.get("max_tilt_deg")),
        "energy_used_frac": 1.0 - _num(ap.get("battery_remaining")),
        "failsafes": len(failsafes),
        "failsafe_texts": "\n".join(failsafes),
        "sim_time_s": _num(sim.get("sim_time_s")),
        "flight_wall_s": _num(sim.get("wall_time_s")),
        "wall_time_s": wall_s,
        "truth_hash": str(sim.get("truth_sha256", "")),
        "worker": f"{socket.gethostname()}:{os.getpid()}",
        "versions": versions(),
        "world_yaml": payload.files.world_yaml,
        "params_yaml": payload.files.params_yaml,
        "script_yaml": payload.files.script_yaml,
    }
    if payload.files.fleet:
        out.update(traffic_columns(flight))
    out["status"], out["reason"] = _judge(payload, flight, out)
    out["passed"] = out["status"] == "ok"
    return out


def _judge(payload: CasePayload, flight: dict[str, Any], out: dict[str, Any]) -> tuple[str, str]:
    if flight.get("timed_out"):
        return "timeout", f"wall deadline {payload.deadline_s:g} s reached: the case's processes were killed"
    if flight.get("error"):
        return "error", str(flight["error"])[:2000]
    if not out["truth_hash"]:
        return "error", "the flight has no truth hash (no simulator summary)"
    failed = [why for rule in payload.pass_if if (why := rule.failure(out.get(rule.column))) is not None]
    if out["end_reason"] not in ("COMPLETED",):
        failed.insert(0, f"flight ended {out['end_reason']} at {out['sim_time_s']:.2f} s")
    return ("fail", "; ".join(failed)) if failed else ("ok", "")
