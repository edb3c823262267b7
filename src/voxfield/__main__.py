"""``python -m voxfield``: the ``voxfield`` command, for an environment whose scripts are
not on the PATH."""

from voxfield.cli.main import program

program()
