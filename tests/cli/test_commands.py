"""The command table: a command line loads only its own command's module, and the parser it
gets reads and lists every command exactly as the whole parser does."""

from __future__ import annotations

import argparse
import ast
import subprocess
import sys

import pytest

from voxfield.cli.commands import COMMANDS, chosen_command
from voxfield.cli.main import build_parser

WHOLE = build_parser()


def _commands(parser: argparse.ArgumentParser) -> dict[str, argparse.ArgumentParser]:
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return dict(sub.choices)


def _help_of(parser: argparse.ArgumentParser) -> str:
    """A parser's help and, recursively, every action's under it."""
    nested = [_help_of(child) for child in _commands(parser).values()] \
        if any(isinstance(a, argparse._SubParsersAction) for a in parser._actions) else []
    return "\n".join([parser.format_help(), *nested])


def test_the_table_lists_the_commands_the_modules_register_in_their_order():
    whole = _commands(WHOLE)
    assert list(whole) == list(COMMANDS)
    listing = WHOLE.format_help()
    for name, (_, summary) in COMMANDS.items():
        assert " ".join(summary.split()[:3]) in " ".join(listing.split())
        assert whole[name].prog == f"voxfield {name}"


@pytest.mark.parametrize("name", list(COMMANDS))
def test_a_command_lines_parser_reads_its_command_as_the_whole_parser_does(name):
    lazy = build_parser(name)
    assert lazy.format_help() == WHOLE.format_help()
    assert _help_of(_commands(lazy)[name]) == _help_of(_commands(WHOLE)[name])


@pytest.mark.parametrize("argv", [[], ["--help"], ["rendr"], ["--quiet", "probes", "show"]])
def test_the_named_command_is_the_first_argument_that_is_not_an_option(argv):
    named = chosen_command(argv)
    assert named == next((t for t in argv if not t.startswith("-")), "")
    assert build_parser(named).format_help() == WHOLE.format_help()


def test_an_end_of_options_marker_loads_every_command():
    assert chosen_command(["--", "render"]) is None
    assert list(_commands(build_parser(None))) == list(COMMANDS)


def _loaded_after(argv: list[str], modules: tuple[str, ...]) -> list[bool]:
    """Which of ``modules`` a fresh interpreter has imported after ``voxfield ARGV``."""
    script = ("import sys\nfrom voxfield.cli.main import main\n"
              f"try:\n    main({argv!r})\nexcept SystemExit:\n    pass\n"
              f"print([m in sys.modules for m in {modules!r}])")
    proc = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                          timeout=120, check=True)
    return ast.literal_eval(proc.stdout.strip().splitlines()[-1])


@pytest.mark.parametrize("argv", [["--help"], ["report", "--help"], ["nosuch"]])
def test_listing_and_light_commands_load_no_kernels(argv):
    """Numba and SciPy (0.2 s and more to import) stay unloaded until a command needs them."""
    assert _loaded_after(argv, ("numba", "scipy", "voxfield.kernels")) == [False] * 3


def test_a_rendering_command_loads_its_kernels_and_no_terrain_filters():
    """SciPy's filters wait for the adaptive renderer or a terrain to need them."""
    assert _loaded_after(["render", "--help"], ("voxfield.kernels", "scipy.ndimage",
                                                "scipy.sparse")) == [True, False, False]


def test_version_prints_the_package_s_own(capsys):
    """It said "the following arguments are required: COMMAND"."""
    import voxfield
    from voxfield.cli import main

    with pytest.raises(SystemExit) as exc:
        main(["--version"])
    assert exc.value.code == 0
    assert capsys.readouterr().out == f"voxfield {voxfield.__version__}\n"


@pytest.mark.parametrize("argv", [
    ["light", "builtin:sphere", "--out", ""],
    ["compare", "builtin:sphere", "--out="],
    ["render", "builtin:sphere", "--out", ""],
])
def test_an_empty_out_is_refused_by_the_parser(argv, tmp_path, monkeypatch, capsys):
    """An empty --out (an unset shell variable) wrote to the default path, ./out/..., without
    a word."""
    from voxfield.cli import main

    monkeypatch.chdir(tmp_path)
    with pytest.raises(SystemExit) as exc:
        main(argv)
    assert exc.value.code == 2
    assert "argument --out: expected a path, got an empty one" in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []
