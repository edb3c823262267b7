"""``voxfield bake`` and ``voxfield probes show``: options, a tiny end-to-end bake, the PNG."""

from __future__ import annotations

import argparse

import numpy as np
import pytest
from PIL import Image

from voxfield import cli
from voxfield.probes.cli_probes import add_probe_parsers
from voxfield.probes.storage import open_probe_set


@pytest.fixture
def run(monkeypatch):
    """``voxfield.cli.main`` with the probe commands registered (whether or not the main
    parser already registers them)."""
    build = cli.build_parser

    def with_probes():
        parser = build()
        sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
        if "bake" not in sub.choices:
            add_probe_parsers(sub)
        return parser

    monkeypatch.setattr(cli, "build_parser", with_probes)
    return cli.main


def test_bake_options_parse(run):
    parser = cli.build_parser()
    args = parser.parse_args(["bake", "builtin:cornell", "--grid", "4x2x4", "--resolution",
                              "16", "--renderer", "lod", "--lod", "cone", "--scheduler",
                              "tcp://10.0.0.1:8786", "--out", "x", "--fresh", "--relocate"])
    assert (args.grid, args.resolution, args.renderer, args.lod) == ("4x2x4", 16, "lod", None)
    assert args.scheduler == "tcp://10.0.0.1:8786" and args.fresh and args.relocate
    defaults = parser.parse_args(["bake", "builtin:cornell", "--grid", "2x2x2"])
    assert defaults.scheduler == "threads" and defaults.out is None
    args = parser.parse_args(["probes", "show", "folder", "--out", "a.png", "--no-scene"])
    assert (args.folder, args.out, args.no_scene) == ("folder", "a.png", True)


def test_bad_arguments_exit_2(run, tmp_path, capsys):
    with pytest.raises(SystemExit) as exc:
        run(["bake", "builtin:cornell"])  # --grid is required
    assert exc.value.code == 2
    code = run(["bake", "builtin:cornell", "--grid", "2x1x1", "--resolution", "7",
                "--out", str(tmp_path / "p"), "--quiet"])
    assert code == 2 and "resolution must be an even integer" in capsys.readouterr().err
    code = run(["probes", "show", str(tmp_path / "nothing"), "--quiet"])
    assert code == 2 and "no such probe-set folder" in capsys.readouterr().err


def test_bake_and_show_end_to_end(run, tmp_path, capsys):
    out = tmp_path / "cornell"
    argv = ["bake", "builtin:cornell", "--grid", "2x1x1", "--resolution", "8",
            "--renderer", "lod", "--lod", "0", "--scheduler", "serial", "--out", str(out)]
    assert run(argv) == 0
    text = capsys.readouterr().out
    assert "2 of 2 probes, 8² texels, lod" in text and "per texel: 1.000 rays" in text
    probes = open_probe_set(out)
    assert probes.count == 2 and np.isfinite(probes.distance).any()

    assert run(argv) == 0  # a re-run resumes: nothing left to bake
    assert "this run baked 0 and reused 2" in capsys.readouterr().out

    png = tmp_path / "show.png"
    assert run(["probes", "show", str(out), "--out", str(png), "--size", "64"]) == 0
    with Image.open(png) as image:
        assert image.format == "PNG" and image.size[0] > 500
    assert run(["probes", "show", str(out), "--no-scene", "--quiet"]) == 0
    assert (out / "show.png").is_file()
