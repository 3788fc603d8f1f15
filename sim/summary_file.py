"""``sim_summary.json``: the file every simulator run writes (SPEC §12), for one vehicle or a fleet."""

from __future__ import annotations

import json
from dataclasses import asdict
from pathlib import Path

SUMMARY_FILE = "sim_summary.json"


class SummaryFile:
    """Mixin of the frozen summary dataclasses: their JSON text and ``log_dir/sim_summary.json``."""

    __slots__ = ()

    def to_json(self) -> str:
        """Pretty JSON, one key per line."""
        return json.dumps(asdict(self), indent=2) + "\n"  # type: ignore[call-overload]

    def write(self, log_dir: Path) -> Path:
        """Write ``log_dir/sim_summary.json`` (creating the directory)."""
        log_dir.mkdir(parents=True, exist_ok=True)
        path = log_dir / SUMMARY_FILE
        path.write_text(self.to_json())
        return path
