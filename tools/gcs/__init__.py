"""The ground-station script (``python -m tools.gcs``), by job: ``cli`` (options, entry point), ``link`` (one
socket to one vehicle or a fleet), ``commands`` (one request each), ``fly`` (fly a mission or a fleet world),
``summary`` (what a flight found) and ``progress`` (the bars)."""

from tools.gcs.summary import failsafe_reason

__all__ = ["failsafe_reason"]
