"""The ``voxfield`` command line. The library never imports this package: it sits on top,
turns arguments into library calls and results into files and one-line summaries."""

from voxfield.cli.main import build_parser, main, program

__all__ = ["build_parser", "main", "program"]
