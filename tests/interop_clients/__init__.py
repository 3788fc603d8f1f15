"""Third-party MAVLink clients for the interoperability tests (issue 5): where they are, how to run them.

The clients are dev dependencies, installed by ``make test`` (MAVSDK pinned in pyproject's ``dev`` extra, MAVProxy
without its GUI dependencies from ``requirements.txt`` here); a test whose client is missing fails with
:data:`MISSING_CLIENT`. ``QUADSITL_INTEROP_PYTHON`` may name another interpreter that
has them (e.g. ``/tmp/interop/bin/python``, whose ``bin/`` also holds ``mavproxy.py``); it is tried first, then the
interpreter running pytest and then ``PATH``. The driver scripts in this
package import nothing from quadsitl: they use the vehicle exactly as an outside application would.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

INTEROP_PYTHON_ENV = "QUADSITL_INTEROP_PYTHON"
CLIENTS_DIR = Path(__file__).resolve().parent
MAVSDK_DRIVER = CLIENTS_DIR / "mavsdk_fly_mission.py"
MAVSDK_OFFBOARD_DRIVER = CLIENTS_DIR / "mavsdk_offboard_velocity.py"
MAVSDK_MANUAL_DRIVER = CLIENTS_DIR / "mavsdk_manual_control.py"
_PROBE_TIMEOUT_S = 60.0
#: Why an interop test fails when its client is missing (they are dev dependencies: never skipped).
MISSING_CLIENT = (
    "{client} not found in this interpreter, $QUADSITL_INTEROP_PYTHON or PATH: it is a dev dependency of quadsitl; "
    "install it with `make test`, or `pip install -e '.[dev]'` and "
    "`pip install --no-deps -r tests/interop_clients/requirements.txt`"
)
_MAVSDK4_PROBE = "import mavsdk, sys; sys.exit(0 if int(mavsdk.__version__.split('.')[0]) >= 4 else 1)"


def candidate_pythons() -> list[str]:
    """Interpreters to look for clients in: ``$QUADSITL_INTEROP_PYTHON`` first, then this one."""
    named = os.environ.get(INTEROP_PYTHON_ENV)
    return [p for p in (named, sys.executable) if p]


def _runs_ok(args: list[str]) -> bool:
    try:
        done = subprocess.run(args, capture_output=True, timeout=_PROBE_TIMEOUT_S, check=False)
    except (OSError, subprocess.TimeoutExpired):
        return False
    return done.returncode == 0


def mavsdk4_python() -> str | None:
    """The first candidate interpreter that imports ``mavsdk`` 4.x (the native binding), or None."""
    return next((p for p in candidate_pythons() if _runs_ok([p, "-c", _MAVSDK4_PROBE])), None)


def mavproxy_script() -> str | None:
    """``mavproxy.py`` next to a candidate interpreter or on ``PATH``, if it runs (``--version``); else None."""
    found = [str(Path(p).parent / "mavproxy.py") for p in candidate_pythons()]
    on_path = shutil.which("mavproxy.py")
    if on_path:
        found.append(on_path)
    return next((s for s in found if Path(s).is_file() and _runs_ok([s, "--version"])), None)
