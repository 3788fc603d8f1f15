"""Fly POSCTL on joystick input with MAVSDK-Python 4.x (``ManualControl``) against any PX4-compatible vehicle.

Runs in an interpreter where ``mavsdk>=4`` is importable; imports nothing from quadsitl. MAVSDK sends one
MANUAL_CONTROL per ``set_manual_control_input`` call, so the session streams the sticks every 20 ms as a GCS
joystick does. Steps: connect, wait for position health, ``Action.arm``, centred sticks, then
``start_position_control``; then, each phase ended by what telemetry shows (so it works at any sim speed):
full throttle to 6 m; half forward stick until 12 m ahead; sticks centred until the vehicle has stopped,
and a second later still; throttle down until landed and disarmed.

Usage: ``python mavsdk_manual_control.py --connect udpin://127.0.0.1:PORT --result result.json [--timeout-s S]``.
``result.json`` holds the steps and a telemetry sample per phase (``samples``: phase, north/east/down m, NED
velocity m/s, heading deg); exit code 0 only when every phase completed.
"""

from __future__ import annotations

import math
import sys
import time
from typing import Any

from mavsdk.plugins.action import Action, ActionError
from mavsdk.plugins.manual_control import ManualControl, ManualControlError
from mavsdk.plugins.telemetry import Telemetry
from mavsdk_session import (
    StepFailedError,
    connected,
    landed_and_disarmed,
    run_phased_session,
    telemetry_sample,
    wait_for,
    wait_position_ok,
)

SEND_PERIOD_S = 0.02
CLIMB_TO_M = 6.0
AHEAD_M = 12.0


def _hold_sticks(
    manual: ManualControl, sticks: tuple[float, float, float, float], until: Any, what: str, deadline: float
) -> None:
    """Send ``sticks`` (x forward, y right, z throttle 0..1 with 0.5 centre, r yaw) every SEND_PERIOD_S until
    ``until()`` holds."""

    def sent_and_done() -> bool:
        manual.set_manual_control_input(*sticks)
        return bool(until())

    wait_for(what, sent_and_done, deadline)


def fly(connect_url: str, result: dict[str, Any], deadline: float) -> None:
    """The whole client session (see module docstring); raises StepFailedError on the first failed step."""
    steps, samples = result["steps"], result["samples"]
    with connected(connect_url, deadline) as (mavsdk, system):
        result["mavsdk_version"] = mavsdk.version()
        telemetry, action, manual = Telemetry(system), Action(system), ManualControl(system)
        wait_position_ok(telemetry, deadline)
        steps.append("ready")
        centred = (0.0, 0.0, 0.5, 0.0)
        try:
            action.arm()
            steps.append("armed")
            for _ in range(10):  # MAVSDK wants input flowing before it switches to position control
                manual.set_manual_control_input(*centred)
                time.sleep(SEND_PERIOD_S)
            manual.start_position_control()
            steps.append("position_control")
        except (ActionError, ManualControlError) as exc:
            raise StepFailedError(f"{exc.origin} -> {exc.result.name}") from None

        def down_m() -> float:
            return telemetry.position_velocity_ned().position.down_m

        _hold_sticks(manual, (0.0, 0.0, 1.0, 0.0), lambda: -down_m() > CLIMB_TO_M, "the climb", deadline)
        samples.append(telemetry_sample(telemetry, "climb"))
        start = telemetry.position_velocity_ned().position

        def ahead_m() -> float:
            p = telemetry.position_velocity_ned().position
            return math.hypot(p.north_m - start.north_m, p.east_m - start.east_m)

        _hold_sticks(manual, (0.55, 0.0, 0.5, 0.0), lambda: ahead_m() > AHEAD_M, "the flight ahead", deadline)
        samples.append(telemetry_sample(telemetry, "forward"))

        def stopped() -> bool:
            v = telemetry.position_velocity_ned().velocity
            return math.hypot(v.north_m_s, v.east_m_s) < 0.1 and abs(v.down_m_s) < 0.1

        _hold_sticks(manual, centred, stopped, "the stop", deadline)
        samples.append(telemetry_sample(telemetry, "stopped"))
        later = time.monotonic() + 1.0
        _hold_sticks(manual, centred, lambda: time.monotonic() > later, "a second of holding", deadline)
        samples.append(telemetry_sample(telemetry, "held"))
        down_stick = (0.0, 0.0, 0.0, 0.0)
        _hold_sticks(manual, down_stick, lambda: landed_and_disarmed(telemetry), "landed and disarmed", deadline)
        samples.append(telemetry_sample(telemetry, "landed"))
        steps.append("landed")


def main(argv: list[str] | None = None) -> int:
    return run_phased_session(__doc__.split("\n", 1)[0], fly, argv)


if __name__ == "__main__":
    sys.exit(main())
