"""MANUAL_CONTROL (a joystick on the GCS link: QGroundControl's virtual joystick, MAVSDK ``ManualControl``).

Axes are int16 in [-1000, 1000]: ``x`` pitch stick (forward +), ``y`` roll stick (right +), ``r`` yaw stick
(clockwise +), ``z`` throttle in [0, 1000] (PX4 and MAVSDK: 500 = centre). INT16_MAX marks an axis as
unused (centred). Values outside the range are clamped. A message for another system never gets here: the
GCS server drops it with the others not for this vehicle. The decoded :class:`ManualInput` goes to
``vehicle.set_manual_input`` (POSCTL flies it; see ``autopilot.flight_tasks.position_control``).
"""

from __future__ import annotations

from dataclasses import dataclass

from pymavlink.dialects.v20 import common as mavlink2

from mavlink_bridge.contract.vehicle_api import ManualInput

_UNUSED_AXIS = 0x7FFF
_FULL_SCALE = 1000.0


@dataclass(slots=True)
class ManualControlStats:
    received: int = 0
    used: int = 0
    refused: int = 0  # by the vehicle


def _axis(raw: int) -> float:
    """A signed stick axis in [-1, 1] (an unused axis is centred)."""
    if raw == _UNUSED_AXIS:
        return 0.0
    return max(-1.0, min(1.0, raw / _FULL_SCALE))


def manual_input_from_msg(msg: mavlink2.MAVLink_message) -> ManualInput:
    """The normalized sticks of a MANUAL_CONTROL message."""
    z = int(msg.z)
    throttle = 0.5 if z == _UNUSED_AXIS else max(0.0, min(1.0, z / _FULL_SCALE))
    return ManualInput(_axis(int(msg.x)), _axis(int(msg.y)), throttle, _axis(int(msg.r)))


class ManualControlProtocol:
    """Hands MANUAL_CONTROL to ``vehicle.set_manual_input``."""

    HANDLED = frozenset({"MANUAL_CONTROL"})

    def __init__(self, vehicle: object) -> None:
        self._vehicle = vehicle
        self.stats = ManualControlStats()

    def handle(self, msg: mavlink2.MAVLink_message) -> None:
        self.stats.received += 1
        if self._vehicle.set_manual_input(manual_input_from_msg(msg)):  # type: ignore[attr-defined]
            self.stats.used += 1
        else:
            self.stats.refused += 1
