"""Every command and action of ``voxfield``: its ``--help``, and one small run that writes
what the command promises. The commands are read from the parser itself, so a command added
without a run here fails ``test_every_command_has_a_run``."""

from __future__ import annotations

import argparse
import base64
import json

import pytest
from PIL import Image

from voxfield.cli import build_parser, main


def _leaves(parser: argparse.ArgumentParser, prefix=()) -> list[tuple[str, ...]]:
    """Every runnable command path, e.g. ("render",), ("errors", "show")."""
    subs = [a for a in parser._actions if isinstance(a, argparse._SubParsersAction)]
    if not subs:
        return [prefix]
    found = []
    for name, child in subs[0].choices.items():
        found += _leaves(child, (*prefix, name))
    return found


LEAVES = _leaves(build_parser())


def _report(folder, page_name: str = "report.html") -> bool:
    """The folder's HTML report, with the tables of its results and any figures embedded."""
    page = folder / page_name
    if not page.is_file():
        return False
    html = page.read_text(encoding="utf-8")
    return "<table>" in html and all(base64.b64encode(png.read_bytes()).decode() in html
                                     for png in folder.glob("*.png"))


def _png(path) -> tuple[int, int]:
    with Image.open(path) as image:
        return image.size


#: One small run per command: (arguments with {out} for a fresh output path, check of what
#: was written). Commands that read a probe set get one baked by the ``probes`` fixture.
RUNS = {
    ("render",): (["builtin:sphere", "--size", "16", "--renderer", "error-aware",
                   "--threshold", "0.1", "--out", "{out}.png"],
                  lambda out: _png(f"{out}.png") == (16, 16)),
    ("info",): (["builtin:menger", "--json"], None),
    ("build",): (["builtin:menger", "--out", "{out}.npz"],
                 lambda out: (out.parent / f"{out.name}.npz").is_file()),
    ("scenes",): ([], None),
    ("errors", "build"): (["--directions", "16", "--resolution", "16", "--oct-resolution", "8",
                           "--out", "{out}.npz"],
                          lambda out: (out.parent / f"{out.name}.npz").is_file()),
    ("errors", "build-lighting"): (["--resolution", "4", "--oct-resolution", "4",
                                    "--out", "{out}.npz"],
                                   lambda out: (out.parent / f"{out.name}.npz").is_file()),
    ("errors", "info"): ([], None),
    ("errors", "show"): (["0x0f", "--out", "{out}.png"], lambda out: _png(f"{out}.png")[0] > 0),
    ("calibrate",): (["builtin:pillars", "--target-rays", "400", "--size", "16",
                      "--iterations", "3", "--out", "{out}.json"],
                     lambda out: "threshold" in json.loads((out.parent / f"{out.name}.json")
                                                           .read_text())),
    ("sweep",): (["builtin:pillars", "--size", "16", "--decays", "0.2", "--thresholds", "0.1",
                  "--out", "{out}"], lambda out: _report(out)),
    ("compare",): (["builtin:pillars", "--size", "16", "--out", "{out}"], _report),
    ("study", "thresholds"): (["builtin:pillars", "--size", "16", "--thresholds", "0.1,0.2",
                               "--out", "{out}"], _report),
    ("study", "resolution"): (["builtin:pillars", "--sizes", "16", "--out", "{out}"], _report),
    ("study", "lighting"): (["builtin:pillars", "--size", "16", "--times", "noon",
                             "--out", "{out}"], _report),
    ("study", "curves"): (["builtin:pillars", "--size", "16", "--thresholds", "0.1,0.4",
                           "--decays", "0.2", "--normalisations", "0.01,0.3", "--lods", "1,0",
                           "--cameras", "top", "--out", "{out}"],
                          lambda out: (out / "curves.png").is_file() and _report(out)),
    ("study", "normalisation"): (["builtin:pillars", "builtin:menger", "--size", "16",
                                  "--out", "{out}"],
                                 _report),
    ("study", "probe-resolution"): (["builtin:cornell", "--resolutions", "8", "--out", "{out}"],
                                    _report),
    ("study", "probes"): (["builtin:cornell", "--resolutions", "8,16", "--probe-counts", "1x1x1",
                           "--count-resolution", "8", "--marchers", "dda", "--orderings",
                           "fixed", "--repeats", "1", "--size", "12", "--out", "{out}"],
                          _report),
    ("light",): (["builtin:pillars", "--times", "noon", "--sky-rays", "0", "--no-preview",
                  "--out", "{out}.npz"],
                 lambda out: (out.parent / f"{out.name}.json").is_file()),
    ("shadows",): (["--size", "12", "--light-samples", "2", "--reference-samples", "4",
                    "--floor-samples", "2", "--out", "{out}"], _report),
    ("bake",): (["builtin:cornell", "--grid", "1x1x1", "--resolution", "8", "--renderer", "lod",
                 "--out", "{out}"], lambda out: (out / "probes.json").is_file()),
    ("probes", "show"): (["{probes}", "--size", "32", "--out", "{out}.png"],
                         lambda out: _png(f"{out}.png")[0] > 0
                         and _report(out.parent, f"{out.name}.html")),
    ("probes", "export-cubes"): (["{probes}", "--size", "4", "--out", "{out}"],
                                 lambda out: len(list(out.glob("*.exr"))) == 6 * 4),
    ("probe-render",): (["{probes}", "--size", "16", "--camera", "room", "--out", "{out}.png"],
                        lambda out: _png(f"{out}.png") == (16, 16)),
    ("report",): (["{probes}/../study"], None),  # rebuilding is checked in test_html_report
}


@pytest.fixture(scope="module")
def probes(tmp_path_factory):
    folder = tmp_path_factory.mktemp("probes") / "set"
    assert main(["--quiet", "bake", "builtin:cornell", "--grid", "2x1x2", "--resolution", "8",
                 "--renderer", "lod", "--out", str(folder)]) == 0
    # A study folder beside it, for ``voxfield report``.
    assert main(["--quiet", "compare", "builtin:pillars", "--size", "8",
                 "--out", str(folder.parent / "study")]) == 0
    return folder


def test_every_command_has_a_run():
    assert sorted(LEAVES) == sorted(RUNS)


@pytest.mark.parametrize("path", [(), *sorted({leaf[:k] for leaf in LEAVES
                                               for k in range(1, len(leaf) + 1)})],
                         ids=lambda p: " ".join(p) or "voxfield")
def test_every_command_has_help(path, capsys):
    with pytest.raises(SystemExit) as exc:
        main([*path, "--help"])
    assert exc.value.code == 0
    assert "usage: voxfield" in capsys.readouterr().out


@pytest.mark.parametrize("path", sorted(RUNS), ids=" ".join)
def test_every_command_runs(path, tmp_path, probes, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)  # anything written by default lands here
    argv, check = RUNS[path]
    out = tmp_path / "result"
    argv = [a.replace("{out}", str(out)).replace("{probes}", str(probes)) for a in argv]
    assert main(["--quiet", *path, *argv]) == 0, capsys.readouterr().err
    if check is not None:
        assert check(out)
