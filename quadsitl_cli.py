"""The ``quadsitl`` console script: dispatches to the simulator, the autopilot or both.

``sim`` and ``autopilot`` never import each other, so this dispatcher imports
the chosen side only by name: ``quadsitl sim`` runs ``sim.cli``, ``quadsitl autopilot``
runs ``autopilot.cli`` and ``quadsitl up`` runs ``autopilot.launcher``, which starts them as separate processes
(one autopilot per vehicle of a fleet world); ``quadsitl campaign`` runs ``tools.campaign.cli`` (many flights on
Dask).
"""

from __future__ import annotations

import importlib
import sys

from mavlink_bridge.contract.about import version_text

_COMMANDS = {
    "sim": ("sim.cli", "run the lockstep simulator (UDP server)"),
    "autopilot": ("autopilot.cli", "run the autopilot (client of the simulator, GCS and API links)"),
    "up": (
        "autopilot.launcher",
        "start the simulator and the autopilot (one per vehicle of a fleet world); Ctrl-C stops all",
    ),
    "campaign": ("tools.campaign.cli", "fly many seeded flights on Dask; report, replay, failure search, estimate"),
}


def _usage() -> str:
    lines = ["usage: quadsitl {sim,autopilot,up,campaign} [options]   (quadsitl CMD --help for options)", ""]
    lines += [f"  {name:<10} {help_text}" for name, (_, help_text) in _COMMANDS.items()]
    lines += ["", "  --version  print the version", "", "Start here: quadsitl up --world missions/delivery.yaml"]
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    args = sys.argv[1:] if argv is None else argv
    if not args or args[0] in ("-h", "--help"):
        print(_usage())
        return 0 if args else 2
    if args[0] == "--version":
        print(version_text("quadsitl"))
        return 0
    name, rest = args[0], args[1:]
    if name not in _COMMANDS:
        print(f"quadsitl: unknown command {name!r}\n\n{_usage()}", file=sys.stderr)
        return 2
    module = importlib.import_module(_COMMANDS[name][0])
    return int(module.main(rest) or 0)


if __name__ == "__main__":
    sys.exit(main())
