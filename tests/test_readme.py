"""The README's Python example runs as written (the data path aside): a user's first copy
and paste must not end in a traceback."""

from __future__ import annotations

import re
from pathlib import Path

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
