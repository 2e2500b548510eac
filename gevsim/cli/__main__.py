"""``python -m gevsim.cli``."""

import sys

from gevsim.cli import main

sys.exit(main())
