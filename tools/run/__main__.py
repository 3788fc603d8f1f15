"""``python -m tools.run``: fly a mission or a fleet world end to end (``tools.run.cli``)."""

import sys

from tools.run.cli import main

sys.exit(main())
