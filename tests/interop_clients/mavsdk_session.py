"""What the MAVSDK driver scripts share: errors, waiting, connecting, readiness and their common options.

Imported by the drivers as a sibling module (their folder is first on ``sys.path`` when run as scripts), in an
interpreter where ``mavsdk>=4`` is importable; imports nothing from quadsitl.
"""

from __future__ import annotations

import argparse
import json
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from mavsdk import ComponentType, Configuration, Mavsdk
from mavsdk.plugins.telemetry import LandedState, Telemetry

POLL_S = 0.02


class StepFailedError(Exception):
    """A step of the session did not succeed; the message says which and why."""


def wait_for(what: str, predicate: Any, deadline: float) -> None:
    """Poll ``predicate`` until it holds; StepFailedError after ``deadline`` (monotonic)."""
    while not predicate():
        if time.monotonic() > deadline:
            raise StepFailedError(f"timed out waiting for {what}")
        time.sleep(POLL_S)


@contextmanager
def connected(connect_url: str, deadline: float) -> Iterator[tuple[Mavsdk, Any]]:
    """A ground-station MAVSDK instance and the first autopilot it discovers on ``connect_url``; the instance
    is destroyed on the way out (its native threads would otherwise outlive the session)."""
    mavsdk = Mavsdk(Configuration.create_with_component_type(ComponentType.GROUND_STATION))
    try:
        result = mavsdk.add_any_connection(connect_url)
        if result.name != "SUCCESS":
            raise StepFailedError(f"add_any_connection({connect_url}) -> {result.name}")
        system = mavsdk.first_autopilot(max(1.0, deadline - time.monotonic()))
        if system is None:
            raise StepFailedError("no autopilot discovered")
        yield mavsdk, system
    finally:
        mavsdk.destroy()


def wait_position_ok(telemetry: Telemetry, deadline: float) -> None:
    """Until the home and global position health flags are set (what arming and missions need)."""

    def position_ok() -> bool:
        health = telemetry.health()
        return bool(health.is_home_position_ok and health.is_global_position_ok)

    wait_for("home and global position health", position_ok, deadline)


def landed_and_disarmed(telemetry: Telemetry) -> bool:
    """On the ground with the motors disarmed (the end of every flight)."""
    return telemetry.landed_state() == LandedState.ON_GROUND and not telemetry.armed()


def session_parser(description: str) -> argparse.ArgumentParser:
    """``--connect``, ``--result`` and ``--timeout-s``: the options every driver takes."""
    parser = argparse.ArgumentParser(description=description)
    parser.add_argument("--connect", required=True, help="MAVSDK connection URL, e.g. udpin://127.0.0.1:14540")
    parser.add_argument("--result", required=True, type=Path, help="where the JSON observations go")
    parser.add_argument("--timeout-s", type=float, default=80.0, help="wall-clock limit of the whole session")
    return parser


def telemetry_sample(telemetry: Telemetry, phase: str) -> dict[str, Any]:
    """Where the vehicle is and goes now: phase, north/east/down m, NED velocity m/s, heading deg."""
    pv = telemetry.position_velocity_ned()
    p, v = pv.position, pv.velocity
    return {
        "phase": phase,
        "north_m": p.north_m,
        "east_m": p.east_m,
        "down_m": p.down_m,
        "vel_ned_m_s": [v.north_m_s, v.east_m_s, v.down_m_s],
        "heading_deg": telemetry.heading().heading_deg,
    }


def run_phased_session(
    description: str, fly: Callable[[str, dict[str, Any], float], None], argv: list[str] | None
) -> int:
    """``main`` of a driver whose ``fly(connect_url, result, deadline)`` fills ``result["steps"]`` and
    ``result["samples"]``: the result JSON is written whatever happens; exit code 0 only when ``fly`` returned."""
    args = session_parser(description).parse_args(argv)
    result: dict[str, Any] = {"mavsdk_version": "", "steps": [], "samples": [], "ok": False, "error": ""}
    try:
        fly(args.connect, result, time.monotonic() + args.timeout_s)
        result["ok"] = True
    except StepFailedError as exc:
        result["error"] = str(exc)
    finally:
        args.result.write_text(json.dumps(result, indent=1) + "\n")
    return 0 if result["ok"] else 1
