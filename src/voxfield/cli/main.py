"""The ``voxfield`` entry point: the main parser, one sub-command group per ``cmd_*`` module,
of which a command line loads only the one it runs (``commands``).

Bad input prints one line, ``voxfield: error: ...``, and exits with status 2.
"""

from __future__ import annotations

import argparse
import importlib
import re
import signal
import sys
import warnings

import voxfield
from voxfield.cli.commands import COMMANDS, QUIET_HELP, chosen_command, command_modules
from voxfield.cli.exits import (
    EXIT_INTERRUPTED,
    EXIT_USAGE,
    interrupted,
    report_failures,
    stdout_failed,
    stopping_on_termination,
)
from voxfield.progress import compile_notice

__all__ = ["EXIT_INTERRUPTED", "EXIT_USAGE", "build_parser", "main"]


class CommandLineParser(argparse.ArgumentParser):
    """argparse with the command line's one-line errors: a mistyped option gets the same
    single ``voxfield: error: …`` line (and status 2) as any other bad input, naming the
    command's ``--help`` instead of printing its usage block. Sub-commands inherit it.

    Options are never abbreviated: argparse took ``--size 32`` for ``--sizes 32`` in ``study
    resolution``, which then measured one size of the four asked for, without a word."""

    def __init__(self, *args, **kwargs) -> None:
        kwargs.setdefault("allow_abbrev", False)
        super().__init__(*args, **kwargs)

    def error(self, message: str):
        self.exit(2, f"voxfield: error: {message} (see `{self.prog} --help`)\n")

    def _print_message(self, message: str, file=None) -> None:
        """argparse drops a failed write: ``--help > /dev/full`` wrote nothing and exited 0.
        Help and usage that cannot reach standard output end in one line and status 2."""
        if not message:
            return
        file = file or sys.stderr
        try:
            file.write(message)
            file.flush()
        except AttributeError:  # no stream at all (pythonw, some daemons): as argparse does
            pass
        except OSError as exc:
            if file is sys.stdout:
                sys.exit(stdout_failed("voxfield", exc))


def build_parser(command: str | None = None) -> argparse.ArgumentParser:
    """The whole parser (``command`` None), or the one a command line needs: ``command``'s
    module registers its arguments, and every other command is listed by name and summary
    only, its module (and all that imports) unloaded. An empty or unknown ``command`` loads
    none: the listing, and argparse's "invalid choice", read the same as the whole parser's."""
    parser = CommandLineParser(
        prog="voxfield",
        description="Sparse voxel octrees with error-aware LOD, light probes and ray queries.",
    )
    parser.add_argument("--quiet", action="store_true", help=QUIET_HELP)
    parser.add_argument("--version", action="version",
                        version=f"%(prog)s {voxfield.__version__}")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    loaded = {module: importlib.import_module(f"voxfield.cli.{module}")
              for module in command_modules(command)}
    for name, (module, summary) in COMMANDS.items():
        if module in loaded:
            # A module registers all its commands at its first one's place in the listing.
            loaded.pop(module).register(sub)
        elif name not in sub.choices:
            sub.add_parser(name, help=summary)
    return parser


def _note_warning(message, category, filename, lineno, file=None, line=None) -> None:
    """Library warnings (an unreadable texture, a missing model) as one plain line each,
    without Python's source-line echo."""
    print(f"voxfield: note: {message}", file=sys.stderr)


#: A value that starts like a negative number: ``-10,20,30``, ``-1x2x2``, ``-.5``, ``-inf``.
_NEGATIVE_VALUE = re.compile(r"^-(\.?\d|inf(inity)?\b)", re.IGNORECASE)


def join_negative_values(argv: list[str]) -> list[str]:
    """``--opt -1,2,3`` as ``--opt=-1,2,3``: argparse takes a token that starts with ``-``
    and is not a plain number for an option, so coordinates and lists with a leading minus
    would otherwise fail as "expected one argument" before their own check could speak."""
    out: list[str] = []
    i = 0
    while i < len(argv):
        token = argv[i]
        if (token.startswith("--") and "=" not in token and i + 1 < len(argv)
                and _NEGATIVE_VALUE.match(argv[i + 1])):
            out.append(f"{token}={argv[i + 1]}")
            i += 2
            continue
        out.append(token)
        i += 1
    return out


def program() -> None:
    """The ``voxfield`` program: ``main``'s status as the process's. Once the command has
    finished, Ctrl-C is ignored: in the tenths of a second the interpreter then takes to shut
    down, it killed the process without a word and with status 130, over a command whose
    outputs were all written. SIGTERM still ends an exit that hangs."""
    status = main()
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    sys.exit(status)


def main(argv: list[str] | None = None) -> int:
    """The command line's status: ``report_failures`` speaks for the command; Ctrl-C while
    the parser loads the command's modules (numpy, Numba: a second or so) is one line too."""
    with stopping_on_termination():
        try:
            return _main(argv)
        except KeyboardInterrupt as exc:
            return interrupted("voxfield", exc)


def _main(argv: list[str] | None) -> int:
    warnings.showwarning = _note_warning
    argv = join_negative_values(sys.argv[1:] if argv is None else list(argv))
    parser = build_parser(chosen_command(argv))
    if not argv:  # `voxfield` alone: what it can do, not an error about a missing command
        parser.print_help()
        return 0
    for token in argv:
        # argparse drops a value of "--" (its end-of-options marker) and hands the option an
        # empty list, which no option's type check sees.
        if token.startswith("--") and token.endswith("=--"):
            parser.error(f"argument {token[:-3]}: expected a value, got '--'")
    args = parser.parse_args(argv)
    if getattr(args, "out", None) == "":
        # An empty --out (an unset shell variable) fell back to the default path unseen.
        parser.error("argument --out: expected a path, got an empty one")
    args.quiet = getattr(args, "quiet", False)

    def run() -> int:
        with compile_notice(enabled=not args.quiet and sys.stderr.isatty()):
            return args.func(args)

    return report_failures("voxfield", run)
