"""Ground-station client library: missions, commands, parameters and telemetry as typed calls (SPEC §8).

Callers never see a MAVLink message. Every protocol step has a retry interval and a
bounded number of retries; failures are typed exceptions carrying the vehicle's
MAVLink result and the reason it gave in STATUSTEXT. Single-threaded: every blocking
call pumps the link, keeps :meth:`GcsClient.telemetry` current and sends the GCS
HEARTBEAT at 1 Hz.
"""

from __future__ import annotations

from mavlink_bridge.gcs_client.commands import REASON_WAIT_S, RESULT_MEANING, GcsCommands
from mavlink_bridge.gcs_client.errors import (
    CommandFailedError,
    GcsError,
    GcsTimeoutError,
    MissionDownloadError,
    MissionUploadError,
    ParamNotFoundError,
    ParamRefused,
    ParamRefusedError,
)
from mavlink_bridge.gcs_client.missions import GcsMissions
from mavlink_bridge.gcs_client.params import GcsParams
from mavlink_bridge.gcs_client.session import MAV_COMP_ID_MISSIONPLANNER
from mavlink_bridge.gcs_client.telemetry import VehicleStatus

__all__ = [
    "MAV_COMP_ID_MISSIONPLANNER",
    "REASON_WAIT_S",
    "RESULT_MEANING",
    "CommandFailedError",
    "GcsClient",
    "GcsError",
    "GcsTimeoutError",
    "MissionDownloadError",
    "MissionUploadError",
    "ParamNotFoundError",
    "ParamRefused",
    "ParamRefusedError",
    "VehicleStatus",
]


class GcsClient(GcsMissions, GcsParams, GcsCommands):
    """A ground station on one link (``udpin:`` waits for the vehicle to talk, ``udpout:`` talks first).

    Missions (:class:`GcsMissions`), commands (:class:`GcsCommands`) and parameters (:class:`GcsParams`)
    over one :class:`~mavlink_bridge.gcs_client.session.GcsSession`.
    """
