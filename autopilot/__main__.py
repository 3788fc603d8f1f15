"""``python -m autopilot``: same as ``quadsitl autopilot`` (see :mod:`autopilot.cli`)."""

from __future__ import annotations

import sys

from autopilot.cli import main

if __name__ == "__main__":
    sys.exit(main())
