"""The README's Python example runs as written (the data path aside), and each of its
``voxfield`` command lines is one the command line accepts: a user's first copy and paste
must not end in a traceback or a usage error."""

from __future__ import annotations

import re
import shlex
from pathlib import Path

import pytest

from voxfield.cli.main import build_parser, chosen_command, join_negative_values

README = Path(__file__).resolve().parents[1] / "README.md"
BLOCKS = re.findall(r"```python\n(.*?)```", README.read_text(encoding="utf-8"), re.S)


def test_the_readme_has_a_python_example():
    assert BLOCKS


def test_the_python_example_runs(shared_data, capsys):
    for code in BLOCKS:
        code = code.replace('"../shared/data/', f'"{shared_data.as_posix()}/')
        exec(compile(code, str(README), "exec"), {"__name__": "readme_example"})
    printed = capsys.readouterr().out.split()
    # print(ref.total_rays, ref.total_steps, lod.finest_lod.max()): 4×4 rays a pixel.
    assert int(printed[0]) == 512 * 512 * 16 and int(printed[1]) > 0


def _shell_command_lines() -> list[list[str]]:
    """Every ``voxfield`` command in the README's shell blocks, continuations joined and
    trailing comments dropped, as argv."""
    lines = []
    for block in re.findall(r"```sh\n(.*?)```", README.read_text(encoding="utf-8"), re.S):
        for line in block.replace("\\\n", " ").splitlines():
            words = shlex.split(line, comments=True)
            if words and words[0] == "voxfield":
                lines.append(words[1:])
    return lines


def _inline_command_lines() -> list[list[str]]:
    """The README's inline ``voxfield COMMAND ARGUMENTS`` examples written out in full (a
    command's name alone, or a line with a "…" or a placeholder in capitals, stands for a
    family and is left out)."""
    lines = []
    for text in re.findall(r"`(voxfield [a-z][^`]*)`", README.read_text(encoding="utf-8")):
        words = shlex.split(text.replace("\n", " "))[1:]
        names_only = all(re.fullmatch(r"[a-z][a-z-]*", word) for word in words)
        if (not names_only and "…" not in text and words not in lines
                and not re.search(r"\b[A-Z]{4,}\b", text)):
            lines.append(words)
    return lines


def test_the_readme_shows_commands():
    assert len(_shell_command_lines()) >= 20 and len(_inline_command_lines()) >= 5


@pytest.mark.parametrize("argv", _shell_command_lines() + _inline_command_lines(),
                         ids=" ".join)
def test_each_readme_command_parses(argv):
    """A renamed or removed option breaks the README's copy-and-paste unseen otherwise."""
    argv = join_negative_values(argv)
    args = build_parser(chosen_command(argv)).parse_args(argv)
    assert args.command == argv[0]
