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


def test_a_baker_that_refined_nothing_is_named(tmp_path, capsys):
    """builtin:cornell's probes at the thesis's threshold from 64² on: the error-aware baker
    cast one ray a texel and its row read like the algorithm's cost; the study says so, in
    results.md and on stderr, and only where it happened."""
    for threshold, refines in (("1000", False), ("0.0001", True)):
        out = tmp_path / threshold
        assert main(["study", "probe-resolution", "builtin:cornell", "--resolutions", "8",
                     "--threshold", threshold, "--out", str(out), "--quiet"]) == 0
        report = json.loads((out / "results.json").read_text())
        (row,) = [r for r in report["rows"] if r["baker"] == "error-aware"]
        assert (row["rays_per_texel"] > 1.0) == refines
        err = capsys.readouterr().err
        assert ("refined no texel" in err) == (not refines)
        assert ("refined no texel" in (out / "results.md").read_text()) == (not refines)
