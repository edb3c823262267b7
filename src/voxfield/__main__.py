"""``python -m voxfield``: the ``voxfield`` command, for an environment whose scripts are
not on the PATH."""

import sys

from voxfield.cli.main import main

sys.exit(main())
