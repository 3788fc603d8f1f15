"""Fly a raw mission with MAVSDK-Python 4.x (native cmavsdk binding) against any PX4-compatible vehicle.

Runs in an interpreter where ``mavsdk>=4`` is importable; imports nothing from quadsitl, so it
exercises the vehicle exactly as a third-party application would. Steps: connect, wait for the
home and global position health flags, download every parameter and set one float (``Param``),
``MissionRaw.upload_mission`` of the items, download them back, ``Action.arm``,
``MissionRaw.start_mission``, then wait until mission progress reaches the last item and the
vehicle is on the ground and disarmed.

Usage: ``python mavsdk_fly_mission.py --connect udpin://127.0.0.1:PORT --items items.json
--result result.json --set-param NAME VALUE [--timeout-s S]``. ``items.json`` is a list of MISSION_ITEM_INT
field dicts (``seq frame command current autocontinue param1..4 x y z mission_type``, x/y in degE7).
``result.json`` records every observation (see ``Recorder``); exit code 0 only when the
mission completed with the vehicle landed and disarmed, 1 on a failed step, 2 on bad usage.
"""

from __future__ import annotations

import json
import sys
import threading
import time
from pathlib import Path
from typing import Any

from mavsdk.plugins.action import Action, ActionError
from mavsdk.plugins.mission_raw import MissionItem, MissionRaw, MissionRawError
from mavsdk.plugins.param import Param, ParamError
from mavsdk.plugins.telemetry import Telemetry
from mavsdk_session import StepFailedError, connected, landed_and_disarmed, session_parser, wait_for, wait_position_ok

_ITEM_FIELDS = (
    "seq",
    "frame",
    "command",
    "current",
    "autocontinue",
    "param1",
    "param2",
    "param3",
    "param4",
    "x",
    "y",
    "z",
    "mission_type",
)


class Recorder:
    """Observations shared with MAVSDK's callback threads; written to the result file at the end."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self.data: dict[str, Any] = {
            "mavsdk_version": "",
            "steps": [],
            "progress": [],
            "flight_modes": [],
            "status_texts": [],
            "ok": False,
            "error": "",
        }

    def step(self, step_name: str, /, **fields: Any) -> None:
        with self._lock:
            self.data["steps"].append({"step": step_name, "wall_s": round(time.monotonic(), 3), **fields})
        print(json.dumps({"step": step_name, **fields}), flush=True)

    def append_if_new(self, key: str, value: Any) -> None:
        with self._lock:
            seq = self.data[key]
            if not seq or seq[-1] != value:
                seq.append(value)

    def last(self, key: str) -> Any:
        with self._lock:
            seq = self.data[key]
            return seq[-1] if seq else None

    def write(self, path: Path) -> None:
        with self._lock:
            path.write_text(json.dumps(self.data, indent=1) + "\n")


def _item_dict(item: MissionItem) -> dict[str, Any]:
    return {name: getattr(item, name) for name in _ITEM_FIELDS}


def check_params(param: Param, set_name: str, set_value: float, rec: Recorder) -> None:
    """Download every parameter, then set one float and read it back (PARAM_SET -> PARAM_VALUE)."""
    try:
        everything = param.get_all_params()
        before = param.get_param_float(set_name)
        param.set_param_float(set_name, set_value)
        after = param.get_param_float(set_name)
    except ParamError as exc:
        raise StepFailedError(f"param {exc.origin} -> {exc.result.name}") from None
    rec.step(
        "params",
        float_count=len(everything.float_params),
        int_count=len(everything.int_params),
        custom_count=len(everything.custom_params),
        name=set_name,
        before=before,
        after=after,
    )


def fly(
    connect_url: str, items: list[MissionItem], set_param: tuple[str, float], rec: Recorder, deadline: float
) -> None:
    """The whole client session (see module docstring); raises StepFailedError on the first failed step."""
    with connected(connect_url, deadline) as (mavsdk, system):
        rec.data["mavsdk_version"] = mavsdk.version()
        rec.step(
            "discovered",
            system_id=system.get_system_id(),
            autopilot=system.autopilot_type().name,
            vehicle=system.vehicle_type().name,
        )
        telemetry, action, mission = Telemetry(system), Action(system), MissionRaw(system)
        telemetry.subscribe_flight_mode(lambda mode, _ud: rec.append_if_new("flight_modes", mode.name))
        telemetry.subscribe_status_text(lambda st, _ud: rec.append_if_new("status_texts", st.text))
        mission.subscribe_mission_progress(lambda p, _ud: rec.append_if_new("progress", [int(p.current), int(p.total)]))
        wait_position_ok(telemetry, deadline)
        # the subscription reports changes only: record the mode on the ground (HOLD) explicitly
        rec.append_if_new("flight_modes", telemetry.flight_mode().name)
        health = telemetry.health()
        rec.step("health", armable=bool(health.is_armable), local_position_ok=bool(health.is_local_position_ok))
        check_params(Param(system), *set_param, rec)

        try:
            mission.upload_mission(items)
        except MissionRawError as exc:
            raise StepFailedError(f"upload_mission -> {exc.result.name}") from None
        rec.step("uploaded", count=len(items))
        try:
            downloaded = mission.download_mission()
        except MissionRawError as exc:
            raise StepFailedError(f"download_mission -> {exc.result.name}") from None
        rec.data["downloaded"] = [_item_dict(it) for it in downloaded]
        rec.step("downloaded", count=len(downloaded))

        try:
            action.arm()
        except ActionError as exc:
            raise StepFailedError(f"arm -> {exc.result.name}") from None
        rec.step("armed")
        try:
            mission.start_mission()
        except MissionRawError as exc:
            raise StepFailedError(f"start_mission -> {exc.result.name}") from None
        rec.step("started")

        total = len(items)
        wait_for("mission progress to reach the last item", lambda: rec.last("progress") == [total, total], deadline)
        rec.step("mission_finished", progress=rec.last("progress"))
        wait_for("landed and disarmed", lambda: landed_and_disarmed(telemetry), deadline)
        position = telemetry.position()
        rec.step(
            "landed",
            lat_deg=position.latitude_deg,
            lon_deg=position.longitude_deg,
            rel_alt_m=position.relative_altitude_m,
        )


def main(argv: list[str] | None = None) -> int:
    parser = session_parser(__doc__.split("\n", 1)[0])
    parser.add_argument("--items", required=True, type=Path, help="JSON list of MISSION_ITEM_INT field dicts")
    parser.add_argument("--set-param", required=True, nargs=2, metavar=("NAME", "VALUE"), help="a float to set")
    args = parser.parse_args(argv)
    try:
        raw = json.loads(args.items.read_text())
        items = [MissionItem(**{name: entry[name] for name in _ITEM_FIELDS}) for entry in raw]
    except (OSError, ValueError, KeyError, TypeError) as exc:
        print(f"mavsdk_fly_mission: bad --items: {exc}", file=sys.stderr)
        return 2
    rec = Recorder()
    try:
        set_param = (args.set_param[0], float(args.set_param[1]))
        fly(args.connect, items, set_param, rec, time.monotonic() + args.timeout_s)
        rec.data["ok"] = True
    except StepFailedError as exc:
        rec.data["error"] = str(exc)
    finally:
        rec.write(args.result)
    return 0 if rec.data["ok"] else 1


if __name__ == "__main__":
    sys.exit(main())
