"""``python -m tools.gcs``: the ground-station script (``tools.gcs.cli``)."""

import sys

from tools.gcs.cli import main

sys.exit(main())
