"""Fly OFFBOARD on velocity setpoints with MAVSDK-Python 4.x (native cmavsdk binding) against any PX4-compatible
vehicle.

Runs in an interpreter where ``mavsdk>=4`` is importable; imports nothing from quadsitl. Steps: connect, wait
for the home and global position health flags, ``Offboard.set_velocity_ned`` (climb), ``Offboard.start``,
``Action.arm``; then, each phase ended by what telemetry shows (so the session works at any sim speed):
climb to 8 m; ``set_velocity_ned`` 2 m/s north until 15 m north of the start; ``set_velocity_body`` 1 m/s
forward turning at 30 deg/s until the heading has turned 80 deg; ``set_velocity_ned`` 1 m/s down until the
vehicle is on the ground and disarmed. MAVSDK re-sends the latest setpoint at 20 Hz on its own.

Usage: ``python mavsdk_offboard_velocity.py --connect udpin://127.0.0.1:PORT --result result.json
[--timeout-s S]``. ``result.json`` holds the steps and a telemetry sample per phase (``samples``: phase,
north/east/down m, NED velocity m/s, heading deg); exit code 0 only when every phase completed.
"""

from __future__ import annotations

import sys
from typing import Any

from mavsdk.plugins.action import Action, ActionError
from mavsdk.plugins.offboard import Offboard, OffboardError, VelocityBodyYawspeed, VelocityNedYaw
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

CLIMB_TO_M = 8.0
CRUISE_NORTH_M = 15.0
TURN_DEG = 80.0


def fly(connect_url: str, result: dict[str, Any], deadline: float) -> None:
    """The whole client session (see module docstring); raises StepFailedError on the first failed step."""
    steps, samples = result["steps"], result["samples"]
    with connected(connect_url, deadline) as (mavsdk, system):
        result["mavsdk_version"] = mavsdk.version()
        telemetry, action, offboard = Telemetry(system), Action(system), Offboard(system)
        wait_position_ok(telemetry, deadline)
        steps.append("ready")
        try:
            offboard.set_velocity_ned(VelocityNedYaw(0.0, 0.0, -1.5, 0.0))  # PX4: a setpoint before start
            offboard.start()
            steps.append("offboard_started")
            action.arm()
            steps.append("armed")
        except (OffboardError, ActionError) as exc:
            raise StepFailedError(f"{exc.origin} -> {exc.result.name}") from None

        wait_for("the climb", lambda: -telemetry.position_velocity_ned().position.down_m > CLIMB_TO_M, deadline)
        samples.append(telemetry_sample(telemetry, "climb"))
        start_north = telemetry.position_velocity_ned().position.north_m
        offboard.set_velocity_ned(VelocityNedYaw(2.0, 0.0, 0.0, 0.0))
        wait_for(
            "the cruise north",
            lambda: telemetry.position_velocity_ned().position.north_m - start_north > CRUISE_NORTH_M,
            deadline,
        )
        samples.append(telemetry_sample(telemetry, "cruise"))
        heading0 = telemetry.heading().heading_deg
        offboard.set_velocity_body(VelocityBodyYawspeed(1.0, 0.0, 0.0, 30.0))

        def turned() -> bool:
            return (telemetry.heading().heading_deg - heading0) % 360.0 > TURN_DEG

        wait_for("the turn", turned, deadline)
        samples.append(telemetry_sample(telemetry, "turn"))
        offboard.set_velocity_ned(VelocityNedYaw(0.0, 0.0, 1.0, telemetry.heading().heading_deg))
        wait_for("landed and disarmed", lambda: landed_and_disarmed(telemetry), deadline)
        samples.append(telemetry_sample(telemetry, "landed"))
        steps.append("landed")


def main(argv: list[str] | None = None) -> int:
    return run_phased_session(__doc__.split("\n", 1)[0], fly, argv)


if __name__ == "__main__":
    sys.exit(main())
