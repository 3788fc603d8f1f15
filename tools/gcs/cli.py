"""The ground-station script: ``python -m tools.gcs [options] COMMAND ...``.

Commands: ``status``, ``upload FILE [--fence-only]``, ``download OUT [--vehicle NAME]``, ``clear``, ``arm``,
``disarm``, ``start``, ``mode NAME``, ``takeoff ALT_M``, ``land``, ``rtl`` (``tools.gcs.commands``),
``fly FILE --summary PATH [--timeout-s S] [--stagger-s S] [--stall-s S]`` (one vehicle, or every vehicle of a fleet
world: ``tools.gcs.fly``), ``param get NAME``, ``param set NAME VALUE``, ``param list``. Mission files: YAML v1,
QGC WPL 110 (``.waypoints``/``.txt``), ``.plan``.
Exit code 0 only when the request succeeded; errors are one line on stderr, with the vehicle's own reason
for a refusal (its STATUSTEXT, else what the COMMAND_ACK result means). What it is waiting for (a vehicle,
a GPS fix, arming) goes to stderr as it happens.
"""

from __future__ import annotations

import argparse
import sys

from autopilot.mission.files import MissionFileError
from mavlink_bridge.contract.about import version_text
from mavlink_bridge.gcs_client.client import GcsError
from mavlink_bridge.wire.link import LinkUrlError
from mavlink_bridge.wire.signing import SigningKeyError, signing_key_from_text
from tools.gcs.commands import (
    MODE_NAMES,
    cmd_arm,
    cmd_clear,
    cmd_disarm,
    cmd_download,
    cmd_land,
    cmd_mode,
    cmd_param,
    cmd_rtl,
    cmd_start,
    cmd_status,
    cmd_takeoff,
    cmd_upload,
)
from tools.gcs.fly import cmd_fly
from tools.gcs.link import DEFAULT_CONNECT, GcsScriptError, connect_url, vehicle_clients


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
    parser.add_argument("--wait-s", type=float, default=60.0, help="how long to wait to hear the vehicle(s)")
    parser.add_argument("--timeout-step-s", type=float, default=5.0, help="timeout of one protocol exchange")
    parser.add_argument(
        "--system", type=int, default=1, help="target system id (fly with a fleet world: the first vehicle's)"
    )
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
    sub.add_parser("start", help="start the mission").set_defaults(run=cmd_start)
    p = sub.add_parser("mode", help=f"set the flight mode ({', '.join(sorted(MODE_NAMES))})")
    p.add_argument("name", help="mode name")
    p.set_defaults(run=cmd_mode)
    p = sub.add_parser("takeoff", help="take off to ALT_M above home")
    p.add_argument("alt_m", type=float, help="metres above home")
    p.set_defaults(run=cmd_takeoff)
    sub.add_parser("land", help="land where it is").set_defaults(run=cmd_land)
    sub.add_parser("rtl", help="return to launch").set_defaults(run=cmd_rtl)
    p = sub.add_parser("fly", help="upload, arm, start and wait until landed and disarmed (every vehicle of a fleet)")
    p.add_argument("file", help="mission file (.yaml, .plan or .waypoints) or fleet world (vehicles:)")
    p.add_argument("--summary", default=None, help="write the JSON summary here")
    p.add_argument("--timeout-s", type=float, default=600.0, help="wall-clock limit")
    p.add_argument("--no-progress", action="store_true", help="no progress bars")
    p.add_argument(
        "--stagger-s", type=float, default=0.0, help="fleet world: sim seconds between two vehicles' take-offs"
    )
    p.add_argument(
        "--stall-s",
        type=float,
        default=None,
        help="sim seconds without mission progress that fail a vehicle, a minute if it is not moving either "
        "(default: 300 for a fleet world, off for one vehicle)",
    )
    p = sub.add_parser("param", help="get, set or list parameters")
    psub = p.add_subparsers(dest="param_cmd", required=True)
    psub.add_parser("get", help="read one parameter").add_argument("name", help="parameter name, e.g. CA_RSAFE_M")
    ps = psub.add_parser("set", help="set one parameter (the vehicle checks its range)")
    ps.add_argument("name", help="parameter name, e.g. CA_RSAFE_M")
    ps.add_argument("value", type=float, help="new value")
    psub.add_parser("list", help="every parameter and its value")
    p.set_defaults(run=cmd_param)
    return parser


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        key = signing_key_from_text(args.signing_key) if args.signing_key else None
        url = connect_url(args.connect, args.instance)
        if args.command == "fly":
            message = cmd_fly(args, url, key)
        else:
            with vehicle_clients(
                url, [args.system], signing_key=key, step_timeout_s=args.timeout_step_s, wait_s=args.wait_s
            ) as (_, (client,)):
                message = args.run(client, args)
    except (GcsScriptError, GcsError, MissionFileError, LinkUrlError, SigningKeyError, OSError) as exc:
        print(f"gcs: error: {exc}", file=sys.stderr)
        return 1
    print(message)
    return 0
