"""The ground-station script's simple commands, one request each to one vehicle: ``status``, ``upload``,
``download``, ``clear``, ``arm``, ``disarm``, ``start``, ``mode``, ``takeoff``, ``land``, ``rtl`` and ``param``.

Each takes the vehicle's client and the parsed arguments and returns the one-line (``status``, ``param list``:
one-screen) result; a refusal raises (the vehicle's reason in the message).
"""

from __future__ import annotations

import argparse
import contextlib
from collections.abc import Callable
from pathlib import Path

from autopilot.mission.files import load_mission_file, save_mission_file
from autopilot.mission.plan import MissionPlan
from mavlink_bridge.contract.frames import GeoPoint
from mavlink_bridge.contract.vehicle_api import FlightMode, MissionType
from mavlink_bridge.gcs_client.client import GcsClient, GcsError, VehicleStatus
from tools.gcs.link import GcsScriptError

MODE_NAMES: dict[str, FlightMode] = {
    "manual": FlightMode.MANUAL,
    "posctl": FlightMode.POSCTL,
    "position": FlightMode.POSCTL,
    "offboard": FlightMode.OFFBOARD,
    "hold": FlightMode.AUTO_LOITER,
    "loiter": FlightMode.AUTO_LOITER,
    "takeoff": FlightMode.AUTO_TAKEOFF,
    "mission": FlightMode.AUTO_MISSION,
    "rtl": FlightMode.AUTO_RTL,
    "land": FlightMode.AUTO_LAND,
}


def cmd_upload(client: GcsClient, args: argparse.Namespace) -> str:
    plan = load_mission_file(args.file)
    if not args.fence_only:
        client.upload_mission(plan.items, MissionType.MISSION)
    client.upload_mission(plan.fence, MissionType.FENCE)
    what = f"{len(plan.fence)} fence items" if args.fence_only else f"{len(plan.items)} items + {len(plan.fence)} fence"
    return f"uploaded {what} from {args.file}"


def cmd_download(client: GcsClient, args: argparse.Namespace) -> str:
    items = client.download_mission(MissionType.MISSION)
    fence = client.download_mission(MissionType.FENCE)
    status = _wait_for_home(client, client.timeout_s)
    home = status.home or GeoPoint(0.0, 0.0, 0.0)
    out = Path(args.out)
    wpl = out.suffix.lower() in (".waypoints", ".txt")
    plan = MissionPlan(name=out.stem, home=home, items=items, fence=fence, vehicle=args.vehicle or "")
    save_mission_file(plan, out, allow_drop_fence=wpl)
    note = f" (QGC WPL has no fence: {len(fence)} fence items not saved)" if wpl and fence else ""
    if not args.vehicle and not wpl:
        note += "; vehicle not written (MAVLink does not carry it): add --vehicle NAME to record it"
    return f"downloaded {len(items)} items + {0 if wpl else len(fence)} fence to {out}{note}"


def _wait_for_home(client: GcsClient, timeout_s: float) -> VehicleStatus:
    """The status once the vehicle has sent its home position (it sets home at its first GPS fix)."""
    try:
        return client.wait_until(lambda s: s.home is not None, timeout_s)
    except GcsError as exc:
        raise GcsScriptError(f"no home position from the vehicle within {timeout_s:g} s (no GPS fix yet?)") from exc


def cmd_status(client: GcsClient, args: argparse.Namespace) -> str:
    """One screen of what the vehicle reports: mode, arming, position, GPS, battery, mission, recent messages."""
    del args
    client.pump(1.5)  # a round of the 1-4 Hz streams
    s = client.telemetry()
    if s.home is None and s.gps_fix_type >= 3:
        with contextlib.suppress(GcsError):  # HOME_POSITION streams at 0.5 Hz: ask for it, as QGroundControl does
            client.request_home()
        s = client.telemetry()
    pos = "unknown" if s.pos_ned_m is None else "N {:.1f} m, E {:.1f} m, D {:.1f} m".format(*s.pos_ned_m)
    home = "not set (no GPS fix yet)" if s.home is None else f"{s.home.lat_deg:.6f}, {s.home.lon_deg:.6f}"
    if s.home is not None:
        home += f", {s.home.alt_amsl_m:.1f} m AMSL"
    battery = "unknown" if s.battery_remaining_pct is None else f"{s.battery_remaining_pct:.0f} %"
    sim = "unknown" if s.sim_time_s is None else f"{s.sim_time_s:.1f} s"
    mission_states = {0: "unknown", 1: "none", 2: "not started", 3: "active", 4: "paused", 5: "complete"}
    mission = f"{s.mission_count} items, current {s.mission_seq_current}, "
    mission += mission_states.get(s.mission_state, str(s.mission_state))
    lines = [
        f"mode        {s.mode_name} ({'ARMED' if s.armed else 'disarmed'}, {s.landed_state.name.lower()})",
        f"position    {pos} from home",
        f"home        {home}",
        f"gps         fix type {s.gps_fix_type}{' (3D)' if s.gps_fix_type >= 3 else ''}",
        f"battery     {battery}",
        f"mission     {mission}",
        f"sim time    {sim}",
    ]
    lines += [f"message     [{t.severity.name.lower()}] {t.text}" for t in s.statustexts[-5:]]
    return "\n".join(lines)


def cmd_clear(client: GcsClient, args: argparse.Namespace) -> str:
    del args
    client.clear_mission(MissionType.MISSION)
    client.clear_mission(MissionType.FENCE)
    return "cleared mission and fence"


def cmd_simple(action: Callable[[GcsClient], None], done: str) -> Callable[[GcsClient, argparse.Namespace], str]:
    def run(client: GcsClient, args: argparse.Namespace) -> str:
        del args
        action(client)
        return done

    return run


def cmd_arm(client: GcsClient, args: argparse.Namespace) -> str:
    client.arm(force=args.force)
    return "armed"


def cmd_disarm(client: GcsClient, args: argparse.Namespace) -> str:
    client.disarm(force=args.force)
    return "disarmed"


def cmd_mode(client: GcsClient, args: argparse.Namespace) -> str:
    mode = MODE_NAMES.get(args.name.lower())
    if mode is None:
        raise GcsScriptError(f"unknown mode {args.name!r}; choose one of {', '.join(sorted(MODE_NAMES))}")
    client.set_mode(mode)
    return f"mode {mode.name}"


def cmd_takeoff(client: GcsClient, args: argparse.Namespace) -> str:
    _wait_for_home(client, client.timeout_s)  # the takeoff altitude is sent above home
    client.takeoff(args.alt_m)
    return f"taking off to {args.alt_m:g} m"


def cmd_param(client: GcsClient, args: argparse.Namespace) -> str:
    if args.param_cmd == "get":
        return f"{args.name} = {client.get_param(args.name):g}"
    if args.param_cmd == "set":
        return f"{args.name} = {client.set_param(args.name, args.value):g}"
    return "\n".join(f"{name:<16} {value:g}" for name, value in client.list_params().items())


cmd_start = cmd_simple(lambda c: c.start_mission(), "mission started")
cmd_land = cmd_simple(lambda c: c.land(), "landing")
cmd_rtl = cmd_simple(lambda c: c.rtl(), "returning to launch")
