"""``python -m voxfield.cli``."""

import sys

from voxfield.cli.main import main

sys.exit(main())
