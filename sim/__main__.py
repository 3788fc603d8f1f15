"""``python -m sim``: the lockstep simulator process (same as ``quadsitl sim``)."""

import sys

from sim.cli import main

sys.exit(main())
