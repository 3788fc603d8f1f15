"""Search objectives: a margin computed from a results row, negative when the case failed (SPEC §14).

A named objective fixes the column and its sense; ``{column: C, min: T}`` (the column must stay at or above T)
and ``{column: C, max: T}`` (at or below T) are the general form::

    objective: clearance                    # min_clearance_m - 0.5 m
    objective: {name: clearance, floor_m: 1.0}
    objective: {name: separation}           # traffic_min_sep_m - 10 m (the UAV separation volume)
    objective: {name: tracking, bound_m: 2} # 2 m - tracking_pos_max_m
    objective: {column: max_tilt_deg, max: 35}

A flight that crashed (it ended before its planned sim time: ``end_reason`` not ``COMPLETED``) is a failure
whatever its column says: its margin is at most ``-CRASH_MARGIN``. A row with no verdict (``error``, ``timeout``,
or the column not measured: NaN) has no margin (NaN): the search treats it as no finding.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

from mavlink_bridge.contract.source_lines import did_you_mean
from sim.fleet import UAV_VOLUME_HOR_M

#: A crashed flight's margin is at most minus this (a crash is a failure, whatever the column says).
CRASH_MARGIN = 1.0
#: name -> (column, sense, option key, default threshold); sense "min": the column must stay >= the threshold.
NAMED: dict[str, tuple[str, str, str, float]] = {
    "clearance": ("min_clearance_m", "min", "floor_m", 0.5),
    "separation": ("traffic_min_sep_m", "min", "volume_m", UAV_VOLUME_HOR_M),
    "tracking": ("tracking_pos_max_m", "max", "bound_m", 2.0),
}
#: Columns the general form may name (a number per row).
COLUMNS = (
    "min_clearance_m",
    "tracking_pos_rms_m",
    "tracking_pos_max_m",
    "tracking_att_rms_deg",
    "max_tilt_deg",
    "energy_used_frac",
    "fence_breaches",
    "collisions",
    "items_missed",
    "failsafes",
    "traffic_min_sep_m",
    "traffic_min_dist_m",
    "traffic_min_manned_m",
    "traffic_contacts",
    "traffic_nmac",
    "traffic_volume_entries",
    "traffic_completion",
)


class ObjectiveError(ValueError):
    """A bad ``objective:``; the message is ``key: what; fix: how`` (the caller prefixes FILE:LINE)."""


@dataclass(frozen=True)
class Objective:
    """margin = value - threshold (sense ``min``) or threshold - value (sense ``max``)."""

    name: str
    column: str
    sense: str
    threshold: float

    @property
    def text(self) -> str:
        """How the margin is computed, in one line."""
        if self.sense == "min":
            return f"{self.column} - {self.threshold:g}"
        return f"{self.threshold:g} - {self.column}"

    def margin(self, row: Mapping[str, Any]) -> float:
        """The row's margin (NaN: no verdict; negative: the case failed)."""
        if row.get("status") in ("error", "timeout"):
            return math.nan
        value = row.get(self.column)
        if isinstance(value, bool):
            value = float(value)
        value = float(value) if isinstance(value, int | float) else math.nan
        margin = value - self.threshold if self.sense == "min" else self.threshold - value
        if str(row.get("end_reason", "COMPLETED")) not in ("COMPLETED", ""):
            return min(margin, -CRASH_MARGIN) if math.isfinite(margin) else -CRASH_MARGIN
        return margin


def parse_objective(raw: Any, fail: Callable[[tuple[str, ...], str, str], Exception]) -> Objective:
    """The objective of ``search.objective`` (``fail(node, message, fix)`` builds the FILE:LINE error)."""
    node = ("search", "objective")
    fix = f"one of {', '.join(NAMED)}, or {{column: C, min: T}} / {{column: C, max: T}}"
    if isinstance(raw, str):
        raw = {"name": raw}
    if not isinstance(raw, dict):
        raise fail(node, f"expected a name or a mapping, got {raw!r}", fix)
    if "name" in raw:
        name = raw["name"]
        if name not in NAMED:
            raise fail((*node, "name"), f"unknown objective {name!r}", did_you_mean(name, NAMED) + f" ({fix})")
        column, sense, option, default = NAMED[name]
        for key in raw:
            if key not in ("name", option):
                raise fail((*node, str(key)), "unknown key", f"the {name} objective takes only '{option}'")
        threshold = raw.get(option, default)
        if not _is_num(threshold):
            raise fail((*node, option), f"expected a number, got {threshold!r}", f"{option}: {default:g}")
        return Objective(name, column, sense, float(threshold))
    column = raw.get("column")
    if column not in COLUMNS:
        raise fail((*node, "column"), f"unknown column {column!r}", did_you_mean(column, COLUMNS))
    senses = [k for k in ("min", "max") if k in raw]
    extra = [k for k in raw if k not in ("column", "min", "max")]
    if extra:
        raise fail((*node, str(extra[0])), "unknown key", "keys: column and one of min / max")
    if len(senses) != 1 or not _is_num(raw[senses[0]]):
        raise fail(node, f"expected exactly one numeric min or max, got {raw!r}", f"{{column: {column}, min: 0.5}}")
    return Objective(f"{column} {senses[0]} {raw[senses[0]]:g}", column, senses[0], float(raw[senses[0]]))


def _is_num(value: Any) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool) and math.isfinite(value)
