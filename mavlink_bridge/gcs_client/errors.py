"""The typed errors of the ground-station client: timeouts, refused missions, commands and parameters."""

from __future__ import annotations

from pymavlink.dialects.v20 import common as mavlink2

from mavlink_bridge.contract.vehicle_api import CommandResult, MissionResult

M = mavlink2


class GcsError(Exception):
    """Base of every error the client raises."""


class GcsTimeoutError(GcsError, TimeoutError):
    """The vehicle did not answer within the retries, or a wait condition did not come true in time."""


class MissionUploadError(GcsError):
    """The vehicle refused or did not complete an upload; its previous mission is still in force."""

    def __init__(self, result: MissionResult, text: str) -> None:
        super().__init__(f"mission upload failed ({result.name}): {text}")
        self.result = result
        self.text = text


class MissionDownloadError(GcsError):
    """A download was refused or did not complete."""


class CommandFailedError(GcsError):
    """A command was acked with something other than ACCEPTED; ``text`` is the vehicle's reason."""

    def __init__(self, command: int, result: CommandResult, text: str = "") -> None:
        name = M.enums["MAV_CMD"][command].name if command in M.enums["MAV_CMD"] else str(command)
        super().__init__(f"{name} -> {result.name}" + (f": {text}" if text else ""))
        self.command = command
        self.result = result
        self.text = text


class ParamNotFoundError(GcsError):
    """The vehicle has no parameter of that name."""


class ParamRefusedError(GcsError):
    """A PARAM_SET was refused; ``value_in_force`` is what the vehicle kept."""

    def __init__(self, name: str, requested: float, value_in_force: float, reason: str) -> None:
        said = reason
        for prefix in (f"{name} refused: ", f"{name}: "):  # the vehicle's text names the parameter too: once is enough
            said = said.removeprefix(prefix)
        super().__init__(f"{name} = {requested:g} refused (still {value_in_force:g}): {said}")
        self.name = name
        self.requested = requested
        self.value_in_force = value_in_force
        self.reason = reason


#: The name the brief uses for a refused PARAM_SET.
ParamRefused = ParamRefusedError
