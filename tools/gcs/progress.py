"""The ground-station script's progress bars (``tools.gcs fly``: one per vehicle).

Each bar counts mission items reached and shows a state column; :func:`flight_state_text` and
:func:`sim_time_text` are the vehicle's mode, arming and sim time as the bars print them.
"""

from __future__ import annotations

from collections.abc import Sequence

from mavlink_bridge.gcs_client.client import VehicleStatus


def flight_state_text(status: VehicleStatus) -> str:
    """The flight mode and arming state, padded to fixed columns (``AUTO_MISSION  ARMED   ``)."""
    return f"{status.mode_name:<13} {'ARMED' if status.armed else 'disarmed':<8}"


def sim_time_text(status: VehicleStatus) -> str:
    """The vehicle's sim time as ``t=`` shows it (``   12.3 s``; ``   ?`` before the first report)."""
    return f"{status.sim_time_s:7.1f} s" if status.sim_time_s is not None else "   ?"


class MissionBars:
    """Rich progress bars of mission items reached, one per ``(name, total items)`` row, with a state column;
    a no-op when disabled. ``label`` is the first column's rich format (``{task.description}`` is the name)."""

    def __init__(self, label: str, rows: Sequence[tuple[str, int]], enabled: bool) -> None:
        self._bar = None
        self._tasks: list[int] = []
        if enabled:
            from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

            self._bar = Progress(
                TextColumn(label),
                BarColumn(),
                MofNCompleteColumn(),
                TextColumn("{task.fields[state]}"),
                TimeElapsedColumn(),
                transient=False,
            )
            self._tasks = [self._bar.add_task(name, total=max(total, 1), state="") for name, total in rows]

    def __enter__(self) -> MissionBars:
        if self._bar is not None:
            self._bar.start()
        return self

    def __exit__(self, *exc: object) -> None:
        if self._bar is not None:
            self._bar.stop()

    def show(self, index: int, reached: int, state: str) -> None:
        """Row ``index`` has ``reached`` items and the state text ``state``."""
        if self._bar is not None:
            self._bar.update(self._tasks[index], completed=reached, state=state)
