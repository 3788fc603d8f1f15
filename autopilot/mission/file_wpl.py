"""QGC WPL 110 (``.waypoints``/``.txt``): line 0 is home, item k is on line k + 1, DO_JUMP targets +1; no fence."""

from __future__ import annotations

from pathlib import Path

from autopilot.mission.file_common import MissionFileError, jump_shift, leading_speed
from autopilot.mission.plan import MissionPlan
from mavlink_bridge.contract.frames import GeoPoint
from mavlink_bridge.contract.mav_enums import MavFrame
from mavlink_bridge.contract.vehicle_api import MissionItem

WPL_HEADER = "QGC WPL 110"


def _fmt(v: float) -> str:
    return repr(float(v))


def write_wpl(plan: MissionPlan, path: Path, allow_drop_fence: bool) -> None:
    if plan.fence and not allow_drop_fence:
        raise MissionFileError(path, "QGC WPL 110 cannot hold fence items: save as .plan or .yaml instead")
    h = plan.home
    lines = [
        WPL_HEADER,
        "\t".join(["0", "1", "0", "16", "0", "0", "0", "0", _fmt(h.lat_deg), _fmt(h.lon_deg), _fmt(h.alt_amsl_m), "1"]),
    ]
    for item in plan.items:
        it = jump_shift(item, +1)
        cols = [str(item.seq + 1), "0", str(it.frame), str(it.command)]
        cols += [_fmt(v) for v in (it.param1, it.param2, it.param3, it.param4, it.x_lat_deg, it.y_lon_deg, it.z_alt_m)]
        cols.append("1" if it.autocontinue else "0")
        lines.append("\t".join(cols))
    path.write_text("\n".join(lines) + "\n")


def read_wpl(path: Path) -> MissionPlan:
    numbered = [(n, ln) for n, ln in enumerate(path.read_text().splitlines(), start=1) if ln.strip()]
    if not numbered or numbered[0][1].strip() != WPL_HEADER:
        line = numbered[0][0] if numbered else 1
        raise MissionFileError(path, f"first line must be '{WPL_HEADER}'", line=line, fix=f"write '{WPL_HEADER}' there")
    rows: list[tuple[int, list[str]]] = [(n, ln.split()) for n, ln in numbered[1:]]
    if not rows:
        raise MissionFileError(
            path, "no home line (line 0) after the header", line=numbered[0][0], fix="add the home position line"
        )
    values: list[tuple[int, int, int, list[float], bool]] = []
    columns = "INDEX CURRENT FRAME COMMAND P1 P2 P3 P4 LAT LON ALT AUTOCONTINUE"
    for idx, (line, cols) in enumerate(rows):
        if len(cols) != 12:
            raise MissionFileError(
                path,
                f"expected 12 columns, got {len(cols)}",
                section="line",
                item_index=idx,
                line=line,
                fix=f"write the tab-separated columns {columns}",
            )
        try:
            index, frame, command = int(cols[0]), int(cols[2]), int(cols[3])
            nums = [float(c) for c in cols[4:11]]
            auto = int(cols[11]) != 0
        except ValueError as exc:
            raise MissionFileError(
                path, f"not a number: {exc}", section="line", item_index=idx, line=line, fix=f"columns: {columns}"
            ) from None
        if index != idx:
            raise MissionFileError(
                path,
                f"index column is {index}, expected {idx}",
                section="line",
                item_index=idx,
                field="seq",
                line=line,
                fix=f"number the lines 0, 1, 2, ... (this one {idx})",
            )
        values.append((index, frame, command, nums, auto))
    _, home_frame, _, home_nums, _ = values[0]
    if home_frame not in (MavFrame.GLOBAL, MavFrame.GLOBAL_INT):
        raise MissionFileError(
            path,
            "home (line 0) must be in frame 0 (GLOBAL, altitude AMSL)",
            section="line",
            item_index=0,
            field="frame",
        )
    home = GeoPoint(home_nums[4], home_nums[5], home_nums[6])
    items = []
    for index, frame, command, n, auto in values[1:]:
        item = MissionItem(index - 1, command, frame, n[0], n[1], n[2], n[3], n[4], n[5], n[6], auto)
        items.append(jump_shift(item, -1))
    return MissionPlan(path.stem, home, items, [], leading_speed(items))
