"""``voxfield study probe-resolution``: the probe bakers' table from the command line."""

from __future__ import annotations

import json

from voxfield.cli import main


def test_probe_resolution_study_writes_its_tables(tmp_path):
    out = tmp_path / "study"
    code = main(["study", "probe-resolution", "builtin:cornell", "--resolutions", "8,16",
                 "--grid", "1x1x1", "--out", str(out), "--quiet"])
    assert code == 0
    report = json.loads((out / "results.json").read_text())
    rows = {(r["resolution"], r["baker"]): r for r in report["rows"]}
    assert set(rows) == {(r, b) for r in (8, 16)
                         for b in ("reference", "lod", "adaptive", "error-aware")}
    # The cheap bakers cast fewer rays than the 16-per-texel reference.
    for resolution in (8, 16):
        reference = rows[(resolution, "reference")]
        assert all(rows[(resolution, b)]["rays"] < reference["rays"]
                   for b in ("lod", "adaptive", "error-aware"))
    assert "Table 5.29" in (out / "results.md").read_text()


def test_bad_grid_is_a_clear_error(tmp_path, capsys):
    code = main(["study", "probe-resolution", "builtin:cornell", "--grid", "2xx",
                 "--out", str(tmp_path), "--quiet"])
    assert code == 2
    assert "voxfield: error:" in capsys.readouterr().err
