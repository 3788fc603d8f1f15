"""The ground-station script: ``python -m tools.gcs [options] COMMAND ...``.

Commands: ``status``, ``upload FILE [--fence-only]``, ``download OUT [--vehicle NAME]``, ``clear``, ``arm``,
``disarm``, ``start``, ``mode NAME``, ``takeoff ALT_M``, ``land``, ``rtl``,
``fly FILE --summary PATH [--timeout-s S] [--stagger-s S]`` (a fleet world: every vehicle, ``tools.gcs_fleet``),
``param get NAME``, ``param set NAME VALUE``,
``param list``. Mission files: YAML v1, QGC WPL 110 (``.waypoints``/``.txt``), ``.plan``.
Exit code 0 only when the request succeeded; errors are one line on stderr, with the vehicle's own reason
for a refusal (its STATUSTEXT, else what the COMMAND_ACK result means). What it is waiting for (a vehicle,
a GPS fix, arming) goes to stderr as it happens.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import math
import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass
from pathlib import Path

from autopilot.mission.files import MissionFileError, load_fleet_missions, load_mission_file, save_mission_file
from autopilot.mission.plan import MissionPlan
from mavlink_bridge.contract.about import version_text
from mavlink_bridge.contract.frames import GeoPoint
from mavlink_bridge.contract.status_texts import is_bypassed, is_failsafe
from mavlink_bridge.contract.vehicle_api import (
    CommandResult,
    FlightMode,
    LandedState,
    MissionResult,
    MissionType,
    StatusText,
)
from mavlink_bridge.gcs_client.client import CommandFailedError, GcsClient, GcsError, MissionUploadError, VehicleStatus
from mavlink_bridge.wire.link import LinkUrlError, resolve_url
from mavlink_bridge.wire.signing import SigningKeyError, signing_key_from_text
from tools.gcs_progress import MissionBars, flight_state_text, sim_time_text

DEFAULT_CONNECT = "udpin:127.0.0.1:14550"
MISSION_STATE_COMPLETE = 5
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


class GcsScriptError(Exception):
    """A request that did not succeed; the message is the one line printed on stderr."""


def say(text: str) -> None:
    """Progress for the person at the terminal (stderr: stdout holds only the result)."""
    print(f"gcs: {text}", file=sys.stderr, flush=True)


@dataclass(frozen=True, slots=True)
class FlySummary:
    """What ``fly --summary`` writes (SPEC §12)."""

    ok: bool
    items_total: int
    items_reached: int
    sim_time_s: float | None
    wall_time_s: float
    landed: bool
    disarmed: bool
    reason: str
    items_bypassed: int = 0  # waypoints the vehicle flew around instead of reaching ("Bypassed item N: ...")

    def to_json(self) -> str:
        return json.dumps(asdict(self), indent=2) + "\n"


def connect_url(url: str | None, instance: int) -> str:
    """The link to use: ``url`` exactly as typed, else the default GCS port shifted by ``instance`` (like
    ``quadsitl --instance N``, which shifts default ports only)."""
    return resolve_url(url, DEFAULT_CONNECT, instance)


# ---- commands ----------------------------------------------------------------------------------------------
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


def arm_when_ready(client: GcsClient, timeout_s: float) -> None:
    """Arm, retrying while the vehicle refuses (estimator or GPS not ready yet) until ``timeout_s``."""
    deadline = time.monotonic() + timeout_s
    said = False
    while True:
        try:
            client.arm()
            say("armed")
            return
        except CommandFailedError as exc:
            if exc.result not in (CommandResult.DENIED, CommandResult.TEMPORARILY_REJECTED, CommandResult.FAILED):
                raise
            if time.monotonic() >= deadline:
                raise GcsScriptError(f"arming refused for {timeout_s:g} s: {exc}") from exc
            if not said:
                say(f"waiting until the vehicle accepts arming (it says: {exc.text})")
                said = True
            client.pump(0.5)


def upload_when_ready(client: GcsClient, plan: MissionPlan, timeout_s: float) -> None:
    """Wait for a 3D GPS fix, then upload mission + fence, retrying while the vehicle is not ready yet."""
    deadline = time.monotonic() + timeout_s
    if client.telemetry().gps_fix_type < 3:
        say("waiting for the vehicle's 3D GPS fix")
    try:
        client.wait_until(lambda s: s.gps_fix_type >= 3, timeout_s)
    except GcsError as exc:
        raise GcsScriptError(f"no 3D GPS fix reported within {timeout_s:g} s") from exc
    say(f"uploading {len(plan.items)} mission items and {len(plan.fence)} fence items")
    while True:
        try:
            client.upload_mission(plan.fence, MissionType.FENCE)  # first: the mission is checked against it
            client.upload_mission(plan.items, MissionType.MISSION)
            return
        except MissionUploadError as exc:
            transient = exc.result in (MissionResult.ERROR, MissionResult.DENIED)
            if not transient or time.monotonic() >= deadline:
                raise
            client.pump(0.5)


def mission_done(status: VehicleStatus, total: int) -> bool:
    return status.mission_state == MISSION_STATE_COMPLETE or (total > 0 and total - 1 in status.items_reached)


def fly(client: GcsClient, plan: MissionPlan, timeout_s: float, progress: bool = True) -> FlySummary:
    """Upload mission + fence, arm, start, and wait until the mission is done, landed and disarmed."""
    t0 = time.monotonic()
    total = len(plan.items)
    text_serial = client.statustext_serial
    upload_when_ready(client, plan, min(60.0, timeout_s))
    client.forget_reached_items()
    arm_when_ready(client, min(60.0, timeout_s))
    try:
        client.start_mission()
    except CommandFailedError:
        client.set_mode(FlightMode.AUTO_MISSION)
    deadline = t0 + timeout_s
    reason = ""
    seen_armed = False  # armed in telemetry at least once (a fast sim may finish before we look)
    with MissionBars("[bold]mission", [("mission", total)], enabled=progress) as bars:
        while True:
            client.pump(0.1)
            status = client.telemetry()
            _show(bars, status)
            seen_armed = seen_armed or status.armed
            landed_disarmed = not status.armed and status.landed_state is LandedState.ON_GROUND
            if landed_disarmed and mission_done(status, total):
                break
            if landed_disarmed and seen_armed:
                client.pump(0.5)  # late MISSION_ITEM_REACHED / MISSION_CURRENT
                status = client.telemetry()
                _show(bars, status)
                if not mission_done(status, total):
                    reason = "the vehicle landed and disarmed before the mission was complete"
                break
            if time.monotonic() >= deadline:
                reason = f"not landed and disarmed after {timeout_s:g} s"
                break
    texts = [t.text for t in status.statustexts if t.severity <= 3]
    if reason and texts:
        reason += f" (last error: {texts[-1]})"
    reason = reason or failsafe_reason(client.statustexts_since(text_serial))
    bypassed = sum(is_bypassed(t.text) for t in client.statustexts_since(text_serial))
    landed = status.landed_state is LandedState.ON_GROUND
    ok = not reason and landed and not status.armed and mission_done(status, total)
    return FlySummary(
        ok=ok,
        items_total=total,
        items_reached=len(status.items_reached),
        sim_time_s=status.sim_time_s,
        wall_time_s=round(time.monotonic() - t0, 3),
        landed=landed,
        disarmed=not status.armed,
        reason=reason,
        items_bypassed=bypassed,
    )


def failsafe_reason(texts: Sequence[StatusText]) -> str:
    """A mission during which a failsafe fired (a geofence breach too, even when GF_ACTION only warns) failed:
    the first such STATUSTEXT is the reason; empty when none fired."""
    for text in texts:
        if is_failsafe(text.text):
            return f"failsafe during the mission: {text.text}"
    return ""


def _show(bars: MissionBars, status: VehicleStatus) -> None:
    state = f"{flight_state_text(status)} {status.landed_state.name} t={sim_time_text(status)}"
    bars.show(0, len(status.items_reached), state)


def cmd_fly(client: GcsClient, args: argparse.Namespace) -> str:
    t0 = time.monotonic()
    plan: MissionPlan | None = None
    with contextlib.suppress(GcsError):  # the flight's own sim time counts from here (SYSTEM_TIME comes at 1 Hz)
        client.wait_until(lambda s: s.sim_time_s is not None, min(3.0, args.timeout_s))
    start_sim_s = client.telemetry().sim_time_s
    try:
        plan = load_mission_file(args.file)
        summary = fly(client, plan, args.timeout_s, progress=not args.no_progress)  # a failsafe fails it
    except (GcsScriptError, GcsError, MissionFileError) as exc:
        status = client.telemetry()
        summary = FlySummary(
            ok=False,
            items_total=len(plan.items) if plan is not None else 0,
            items_reached=len(status.items_reached),
            sim_time_s=status.sim_time_s,
            wall_time_s=round(time.monotonic() - t0, 3),
            landed=status.landed_state is LandedState.ON_GROUND,
            disarmed=not status.armed,
            reason=str(exc),
        )
    if args.summary:
        Path(args.summary).parent.mkdir(parents=True, exist_ok=True)
        Path(args.summary).write_text(summary.to_json())
    if not summary.ok:
        raise GcsScriptError(f"mission failed: {summary.reason or 'not complete'}")
    flown = ""
    if summary.sim_time_s is not None and start_sim_s is not None:  # from this flight's start, not the sim's
        flown = f", {summary.sim_time_s - start_sim_s:.1f} s sim time in {summary.wall_time_s:.1f} s wall"
    bypassed = f", {summary.items_bypassed} bypassed" if summary.items_bypassed else ""
    return f"mission complete: {summary.items_reached}/{summary.items_total} items{bypassed}{flown}"


# ---- entry point -------------------------------------------------------------------------------------------
def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="python -m tools.gcs",
        description="The ground-station script: upload, fly and inspect missions over MAVLink.",
        epilog="Example: python -m tools.gcs fly missions/delivery.yaml --summary fly.json",
    )
    parser.add_argument("--version", action="version", version=version_text("tools.gcs"))
    parser.add_argument(
        "--connect", default=None, help=f"link URL, used as typed (default {DEFAULT_CONNECT}, shifted by --instance)"
    )
    parser.add_argument("--instance", type=int, default=0, help="the quadsitl --instance N to talk to (port + N)")
    parser.add_argument("--signing-key", default=None, help="MAVLink 2 signing key: 64 hex digits or a passphrase")
    parser.add_argument("--wait-s", type=float, default=60.0, help="how long to wait for the vehicle's heartbeat")
    parser.add_argument("--timeout-step-s", type=float, default=5.0, help="timeout of one protocol exchange")
    parser.add_argument("--system", type=int, default=1, help="target system id")
    sub = parser.add_subparsers(dest="command", required=True)
    sub.add_parser("status", help="what the vehicle reports: mode, position, GPS, battery, mission").set_defaults(
        run=cmd_status
    )
    p = sub.add_parser("upload", help="upload a mission file (mission + fence)")
    p.add_argument("file", help="mission file: .yaml, .plan or .waypoints")
    p.add_argument("--fence-only", action="store_true", help="upload only the fence")
    p.set_defaults(run=cmd_upload)
    p = sub.add_parser("download", help="download mission + fence to a file (format by extension)")
    p.add_argument("out", help="file to write: .yaml, .plan or .waypoints")
    p.add_argument(
        "--vehicle",
        default=None,
        metavar="NAME",
        help="vehicle to write in the file, e.g. delivery650 (MAVLink does not carry it: none written by default)",
    )
    p.set_defaults(run=cmd_download)
    sub.add_parser("clear", help="clear mission and fence").set_defaults(run=cmd_clear)
    for name, run in (("arm", cmd_arm), ("disarm", cmd_disarm)):
        p = sub.add_parser(name, help=f"{name} the motors")
        p.add_argument("--force", action="store_true", help="bypass the vehicle's checks (21196)")
        p.set_defaults(run=run)
    sub.add_parser("start", help="start the mission").set_defaults(
        run=cmd_simple(lambda c: c.start_mission(), "mission started")
    )
    p = sub.add_parser("mode", help=f"set the flight mode ({', '.join(sorted(MODE_NAMES))})")
    p.add_argument("name", help="mode name")
    p.set_defaults(run=cmd_mode)
    p = sub.add_parser("takeoff", help="take off to ALT_M above home")
    p.add_argument("alt_m", type=float, help="metres above home")
    p.set_defaults(run=cmd_takeoff)
    sub.add_parser("land", help="land where it is").set_defaults(run=cmd_simple(lambda c: c.land(), "landing"))
    sub.add_parser("rtl", help="return to launch").set_defaults(
        run=cmd_simple(lambda c: c.rtl(), "returning to launch")
    )
    p = sub.add_parser("fly", help="upload, arm, start and wait until landed and disarmed")
    p.add_argument("file", help="mission file: .yaml, .plan or .waypoints")
    p.add_argument("--summary", default=None, help="write the JSON summary here")
    p.add_argument("--timeout-s", type=float, default=600.0, help="wall-clock limit")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.add_argument(
        "--stagger-s", type=float, default=0.0, help="fleet world: sim seconds between two vehicles' take-offs"
    )
    p.add_argument(
        "--stall-s", type=float, default=120.0, help="fleet world: sim seconds without progress that fail a vehicle"
    )
    p.set_defaults(run=cmd_fly)
    p = sub.add_parser("param", help="get, set or list parameters")
    psub = p.add_subparsers(dest="param_cmd", required=True)
    psub.add_parser("get", help="read one parameter").add_argument("name", help="parameter name, e.g. CA_RSAFE_M")
    ps = psub.add_parser("set", help="set one parameter (the vehicle checks its range)")
    ps.add_argument("name", help="parameter name, e.g. CA_RSAFE_M")
    ps.add_argument("value", type=float, help="new value")
    psub.add_parser("list", help="every parameter and its value")
    p.set_defaults(run=cmd_param)
    return parser


def _fleet_plans(args: argparse.Namespace) -> list[MissionPlan]:
    """The per-vehicle plans when ``fly``'s file is a fleet world (``vehicles:``), else ``[]``."""
    if args.stagger_s < 0.0 or not math.isfinite(args.stagger_s):
        raise GcsScriptError(f"--stagger-s must be a finite number >= 0, got {args.stagger_s:g}")
    return load_fleet_missions(args.file)


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        key = signing_key_from_text(args.signing_key) if args.signing_key else None
        url = connect_url(args.connect, args.instance)
        if args.command == "fly" and (fleet := _fleet_plans(args)):
            from tools import gcs as importable  # run as a script, this module is __main__, not tools.gcs
            from tools.gcs_fleet import cmd_fly_fleet  # a fleet world: every vehicle over the one GCS port

            try:
                print(cmd_fly_fleet(url, fleet, args))
            except importable.GcsScriptError as exc:  # the fleet module raises tools.gcs's own class
                raise GcsScriptError(str(exc)) from exc
            return 0
        with GcsClient(url, target_system=args.system, signing_key=key, timeout_s=args.timeout_step_s) as client:
            try:
                client.wait_heartbeat(min(args.wait_s, 1.0))
            except GcsError:
                say(f"waiting for a vehicle on {url} (up to {args.wait_s:g} s; is quadsitl up running?)")
                try:
                    client.wait_heartbeat(max(args.wait_s - 1.0, 0.0))
                except GcsError as exc:
                    raise GcsScriptError(
                        f"no vehicle heard on {url} within {args.wait_s:g} s; fix: start one (quadsitl up), "
                        "or pass the --instance N or --connect URL it runs with"
                    ) from exc
            message = args.run(client, args)
    except (GcsScriptError, GcsError, MissionFileError, LinkUrlError, SigningKeyError, OSError) as exc:
        print(f"gcs: error: {exc}", file=sys.stderr)
        return 1
    print(message)
    return 0


if __name__ == "__main__":
    sys.exit(main())
