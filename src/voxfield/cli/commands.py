"""The commands ``voxfield`` offers, in the order its help lists them, with the module that
defines each and the one-line summary the listing shows.

The entry point imports only the module of the command it runs: the others appear in the
listing by name and summary alone. ``voxfield --help`` and the light commands then start
without loading Numba, SciPy and the kernels, which every module of a rendering command
pulls in. This module imports nothing of the library for that reason.
"""

from __future__ import annotations

import argparse
from typing import NamedTuple


class Command(NamedTuple):
    module: str  #: in ``voxfield.cli``; one module may define several commands
    summary: str


COMMANDS: dict[str, Command] = {
    "render": Command("cmd_render", "render a scene to PNG or EXR"),
    "info": Command("cmd_scenes", "build a scene's octree and print its structure"),
    "build": Command("cmd_scenes", "build a scene's octree and save it (.npz)"),
    "scenes": Command("cmd_scenes", "list built-in scenes and terrain recipes"),
    "errors": Command("cmd_errors", "error tables: build, inspect, picture one mask"),
    "calibrate": Command("cmd_calibrate",
                         "solve for the error threshold meeting a ray budget or PSNR"),
    "sweep": Command("cmd_sweep",
                     "decay × threshold grid of ray counts and quality (EA Table 5.1)"),
    "compare": Command("cmd_compare",
                       "reference vs adaptive vs error-aware: cost and quality tables"),
    "study": Command("cmd_study", "resumable studies of both theses' chapters (thresholds, "
                     "resolution, lighting, curves, probes, ...)"),
    "light": Command("cmd_light",
                     "bake sun and sky lighting for times of day into colour channels"),
    "shadows": Command("cmd_shadows",
                       "shadow-ray LOD test: reference vs distance-LOD vs error-aware"),
    "bake": Command("cmd_probes", "bake a grid of light probes (radiance, distance, normals)"),
    "probes": Command("cmd_probes", "inspect a baked probe set"),
    "probe-render": Command("cmd_probe_render", "render a camera view from a baked probe set"),
    "report": Command("cmd_report", "rebuild a study folder's report.html"),
}

QUIET_HELP = "no progress bars or summaries (notes still print)"


def add_quiet(p: argparse.ArgumentParser) -> None:
    """``--quiet`` on a sub-command (the main parser's own --quiet still works before it)."""
    p.add_argument("--quiet", action="store_true", default=argparse.SUPPRESS, help=QUIET_HELP)


def add_command(subparsers, name: str, **settings):
    """``subparsers.add_parser(name)`` with the summary ``COMMANDS`` lists for it, so the
    listing reads the same whether or not the command's module was imported."""
    return subparsers.add_parser(name, help=COMMANDS[name].summary, **settings)


def command_modules(command: str | None) -> list[str]:
    """The modules a parser for ``command`` imports, in listing order: all of them for None
    (the whole parser), ``command``'s own for a known name, none for any other."""
    if command is None:
        return list(dict.fromkeys(c.module for c in COMMANDS.values()))
    return [COMMANDS[command].module] if command in COMMANDS else []


def chosen_command(argv: list[str]) -> str | None:
    """The command a command line names: the first argument that is not an option (the
    main parser's own, ``--quiet`` and ``--help``, take no value), "" when there is none,
    and None (parse with every command loaded) after an end-of-options ``--``."""
    for token in argv:
        if token == "--":
            return None
        if not token.startswith("-"):
            return token
    return ""
