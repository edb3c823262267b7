"""`make demo` is a user's first command: every voxfield command line in its recipes must be
one the command line accepts (an option renamed elsewhere would otherwise break it unseen,
as the suite never runs make)."""

from __future__ import annotations

import re
import shlex
from pathlib import Path

import pytest

from voxfield.cli.main import build_parser, chosen_command

MAKEFILE = Path(__file__).resolve().parents[1] / "Makefile"


def _variables(text: str) -> dict[str, str]:
    return {name: value.strip() for name, value in
            re.findall(r"^([A-Z_]+)\s*:=\s*(.*?)$", text, re.M)}


def _demo_command_lines() -> list[list[str]]:
    """The Makefile's demo targets' ``voxfield`` invocations, variables expanded, as argv."""
    text = MAKEFILE.read_text(encoding="utf-8").replace("\\\n", " ")
    variables = _variables(text)
    targets = ["demo", *variables["DEMO_IMAGES"].split()]
    lines = []
    for target in targets:
        recipe = re.search(rf"^{re.escape(target)}:.*?\n((?:\t.*\n)+)", text, re.M)
        assert recipe, f"no recipe for {target}"
        for line in recipe.group(1).splitlines():
            line = re.sub(r"\$\((\w+)\)", lambda m: variables.get(m.group(1), m.group(0)),
                          line.strip().lstrip("@"))
            words = shlex.split(line)
            if words and words[0].endswith("/voxfield"):
                lines.append(words[1:])
    return lines


def test_the_demo_names_both_theses():
    commands = [argv[0] for argv in _demo_command_lines()]
    assert {"render", "errors", "bake", "probe-render"} <= set(commands)


@pytest.mark.parametrize("argv", _demo_command_lines(), ids=" ".join)
def test_each_demo_command_parses(argv):
    args = build_parser(chosen_command(argv)).parse_args(argv)
    assert args.command == argv[0]
