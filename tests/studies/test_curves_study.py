"""The curves study: each renderer's knob traces a curve with the published trends, the
deltas compare them, files are written, and a second run recomputes nothing."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from voxfield.cli.main import main
from voxfield.errors import VoxfieldError
from voxfield.metrics import flip_available
from voxfield.render import Camera
from voxfield.scene.builtin import pillars
from voxfield.studies.curves_study import (
    ORACLE_FRACTIONS,
    ORACLE_SIDES,
    curves_figure,
    run_curves_study,
)
from voxfield.svo import build_octree

KNOBS = {"thresholds": (0.4, 0.05, 0.15), "decays": (0.0, 0.2),
         "normalisations": (0.001, 0.03, 0.8), "lods": (2, 1, 0)}


@pytest.fixture(scope="module")
def octree():
    return build_octree(pillars(64))


def cameras():
    perspective = Camera.look_at((70, 60, 90), (32, 10, 32), fov_deg=50, width=24)
    orthographic = Camera.orthographic((32, 80, 32), (0, -1, 0), (0, 0, -1), view_height=64.0,
                                       width=24)
    return {"persp": perspective, "ortho": orthographic}


def test_curves_follow_their_knobs_and_resume(octree, tmp_path):
    report = run_curves_study(octree, cameras(), tmp_path, scene_name="pillars", **KNOBS)
    assert set(report["cameras"]) == {"persp", "ortho"}
    assert report["cameras"]["ortho"]["kind"] == "orthographic"
    for cam in report["cameras"].values():
        curves = cam["curves"]
        assert set(curves) == {"EA d=0", "EA d=0.2", "EA context d=0.2", "EA+colour d=0.2",
                               "EA+colour→LOD 0 d=0.2", "hybrid d=0.2", "A", "LOD", "oracle"}
        # The oracle's 4×4 refinements are the reference's own pixels: refining more of the
        # worst pixels only lowers the error, and refining all of them leaves none.
        exact = [p for p in curves["oracle"]["points"] if p["side"] == 4]
        assert [p["fraction"] for p in exact] == sorted(p["fraction"] for p in exact)
        psnr = [math.inf if p["psnr"] is None else p["psnr"] for p in exact]
        assert psnr == sorted(psnr)
        assert exact[-1]["fraction"] == 1.0 and exact[-1]["psnr"] is None
        # Its choice is the ranking the selection scores measure against: precision 1.
        for p in curves["oracle"]["points"]:
            assert p["selection_precision"] in (None, 1.0)
        for p in (p for curve in curves.values() for p in curve["points"]):
            assert 0.0 <= p["refined_share"] <= 1.0
            for key in ("selection_precision", "error_covered"):
                assert p[key] is None or 0.0 <= p[key] <= 1.0
        # The hybrid refines at least where EA does: never fewer rays at any threshold.
        for ea_point, hybrid_point in zip(curves["EA d=0.2"]["points"],
                                          curves["hybrid d=0.2"]["points"], strict=True):
            assert hybrid_point["rays"] >= ea_point["rays"]
        # The context-aware error only drops errors: never more rays.
        for ea_point, context_point in zip(curves["EA d=0.2"]["points"],
                                           curves["EA context d=0.2"]["points"], strict=True):
            assert context_point["rays"] <= ea_point["rays"]
        # And the colour term only adds error: never fewer rays either.
        for ea_point, colour_point in zip(curves["EA d=0.2"]["points"],
                                          curves["EA+colour d=0.2"]["points"], strict=True):
            assert colour_point["rays"] >= ea_point["rays"]
        ea = sorted(curves["EA d=0"]["points"], key=lambda p: p["threshold"])
        assert [p["rays"] for p in ea] == sorted((p["rays"] for p in ea), reverse=True)
        a = sorted(curves["A"]["points"], key=lambda p: p["variance_normalisation"])
        assert [p["rays"] for p in a] == sorted((p["rays"] for p in a), reverse=True)
        lod = sorted(curves["LOD"]["points"], key=lambda p: p["lod"])
        assert all(p["rays"] == 24 * 24 for p in lod)  # one ray a pixel at every level
        assert [p["steps"] for p in lod] == sorted((p["steps"] for p in lod), reverse=True)
        assert len(cam["deltas"]) == 14  # six EA-family curves and the oracle, against A, LOD
        for d in cam["deltas"]:
            assert d["bd_psnr_steps"] is None or np.isfinite(d["bd_psnr_steps"])
            assert d["bd_psnr_steps"] is not None or d["note"]
    for name in ("results.json", "results.md", "curves.png"):
        assert (tmp_path / name).is_file()
    assert "Bjøntegaard deltas" in (tmp_path / "results.md").read_text()
    if flip_available():  # a dev install has FLIP: every point has it, plotted and tabled
        points = [p for cam in report["cameras"].values() for curve in cam["curves"].values()
                  for p in curve["points"]]
        assert all(0.0 <= p["flip"] < 1.0 for p in points)
        assert any(p["flip"] > 0.0 for p in points)
        assert len(curves_figure(report).axes) == 2 * 4  # per camera: a FLIP-per-step panel
        assert "| FLIP |" in (tmp_path / "results.md").read_text()
    items = sorted((tmp_path / "items").glob("*.json"))
    assert len(items) == 2 * (1 + 6 * 3 + 3 + 3 + len(ORACLE_FRACTIONS) * len(ORACLE_SIDES))
    stamps = {p.name: p.stat().st_mtime_ns for p in items}
    again = run_curves_study(octree, cameras(), tmp_path, scene_name="pillars", **KNOBS)
    assert {p.name: p.stat().st_mtime_ns for p in items} == stamps
    assert again["cameras"] == json.loads(json.dumps(report["cameras"]))


def test_curves_from_the_command_line(tmp_path, capsys):
    out = tmp_path / "curves"
    code = main(["--quiet", "study", "curves", "builtin:pillars", "--size", "16",
                 "--thresholds", "0.1,0.4", "--decays", "0.2", "--normalisations", "0.01,0.3",
                 "--lods", "1,0", "--out", str(out)])
    assert code == 0
    report = json.loads((out / "results.json").read_text())
    assert set(report["cameras"]) == {"top", "ortho-top"}


def test_thresholds_past_both_ends_give_the_curve_s_ends(tmp_path):
    """As in ``study thresholds``, ``sweep`` and ``render``: a negative threshold refines
    every ray down to the voxels (the 4×4 reference's image: 1 + 4 + 16 rays a pixel) and
    inf none (one ray a pixel); the curves study refused them, alone among the commands."""
    out = tmp_path / "curves"
    code = main(["--quiet", "study", "curves", "builtin:pillars", "--size", "16",
                 "--cameras", "top", "--thresholds", "-1,inf", "--decays", "0.2",
                 "--normalisations", "0.01,0.3", "--lods", "1,0", "--out", str(out)])
    assert code == 0
    report = json.loads((out / "results.json").read_text())  # strict JSON
    finest, coarsest = report["cameras"]["top"]["curves"]["EA d=0.2"]["points"]
    assert finest["threshold"] == -1 and coarsest["threshold"] is None  # inf, as JSON has it
    assert finest["rays_per_pixel"] == 21 and finest["rmse"] == 0.0
    assert coarsest["rays_per_pixel"] == 1 and coarsest["refined_share"] == 0.0


@pytest.mark.parametrize("bad", [["--thresholds", "nan,0.1"], ["--decays", "-1"],
                                 ["--cameras", "nowhere"], ["--normalisations", "0,1"],
                                 ["--normalisations", "0"]])
def test_bad_curve_values_are_one_line_and_exit_2(bad, tmp_path, capsys):
    try:
        code = main(["--quiet", "study", "curves", "builtin:pillars", "--size", "16",
                     "--out", str(tmp_path / "c"), *bad])
    except SystemExit as refused:  # the parser's own refusal
        code = refused.code
    assert code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and not (tmp_path / "c").exists()
    if bad[0] == "--normalisations":  # (a variance normalisation of 0 was refused late, or
        # hidden behind "each curve needs at least two knob values")
        assert err[0] == "voxfield: error: --normalisations must be finite and positive"


def test_a_lod_list_that_is_not_numbers_is_an_argument_error(tmp_path):
    with pytest.raises(SystemExit) as exit_info:
        main(["--quiet", "study", "curves", "builtin:pillars", "--lods", "2,x"])
    assert exit_info.value.code == 2


def test_curves_on_a_cluster_equal_the_loop(octree, tmp_path, dask_client):
    """Every point as a Dask task (scattered octree and reference): the same curves and
    deltas as the plain loop, point for point."""
    knobs = {"thresholds": (0.4, 0.1), "decays": (0.2,), "normalisations": (0.01, 0.5),
             "lods": (1, 0)}
    view = {"persp": cameras()["persp"]}
    loop = run_curves_study(octree, view, tmp_path / "loop", **knobs)
    cluster = run_curves_study(octree, view, tmp_path / "cluster", scheduler=dask_client,
                               **knobs)
    assert cluster["cameras"] == loop["cameras"]


def test_lods_past_the_octree_are_named_when_left_out(tmp_path):
    """--lods 9,1 on a depth-2 octree: LOD 9 was dropped from the curve without a word, and
    the one level left was refused as if the user had given one value."""
    import types

    shallow = types.SimpleNamespace(depth=2, name="s")
    with pytest.warns(UserWarning, match=r"LOD 9, 5 left out .* levels run 0\.\.2"), \
            pytest.raises(VoxfieldError, match="at least two"):
        run_curves_study(shallow, {"top": None}, tmp_path / "c", lods=(9, 5, 1))
    assert not (tmp_path / "c").exists()
