"""The probe study (probe thesis ch. 9) on a tiny Cornell box: files, resume, and the trends
the thesis predicts that already hold at 16² and 32² maps."""

from __future__ import annotations

import argparse
import copy
import json
import math

import numpy as np
import pytest

from voxfield.errors import VoxfieldError
from voxfield.lightfield.probe_render import LOST_NOTE_SHARE
from voxfield.render.camera import Camera, room_camera
from voxfield.render.ray_query import trace
from voxfield.scene.voxel_scene import VoxelScene
from voxfield.studies.probe_study import (
    grid_spec,
    parse_counts,
    run_probe_study,
    study_lost_note,
)
from voxfield.svo import build_octree
from voxfield.svo.open import open_octree

TINY = {"resolutions": (16, 32), "probe_counts": ((1, 1, 1), (2, 2, 2)), "timing_repeats": 1}


@pytest.fixture(scope="module")
def cornell():
    return open_octree("builtin:cornell")


@pytest.fixture(scope="module")
def camera(cornell):
    return room_camera(*cornell.voxel_bounds, size=24)


@pytest.fixture(scope="module")
def study(cornell, camera, tmp_path_factory):
    out = tmp_path_factory.mktemp("probe_study")
    report = run_probe_study(cornell, out, scene_name="builtin:cornell", camera=camera, **TINY)
    return out, report


def test_writes_every_file(study):
    out, report = study
    for name in ("results.json", "results.md", "fetches_vs_resolution.png", "probe_count.png",
                 "orderings.png", "contact_sheet.png"):
        assert (out / name).stat().st_size > 0, name
    saved = json.loads((out / "results.json").read_text())
    assert [q["method"] for q in saved["quality"]] == ["light-field", "environment",
                                                       "box-proxy"]
    text = (out / "results.md").read_text()
    for heading in ("## 1. Quality", "## 2. Texel fetches", "## 3. Failures",
                    "## 4. First-probe success", "## 5. Wall time"):
        assert heading in text


def test_a_view_no_probe_sees_is_said_to_measure_the_fallback(tmp_path):
    """A camera in a closed room the only probe cannot see into: every ray is lost, and the
    study says its light-field figures measure the fallback (in the report, the markdown
    and as a warning the command line prints as a note)."""
    n = 32
    x, y, z = np.meshgrid(np.arange(n), np.arange(n), np.arange(n), indexing="ij")
    solid = ((x == 0) | (x == n - 1) | (y == 0) | (y == n - 1) | (z == 0) | (z == n - 1)
             | (x == 22))  # the probe, at the box's centre, stands in the larger room
    coords = np.argwhere(solid)
    octree = build_octree(VoxelScene(coords, np.full((len(coords), 3), 0.6, np.float32)))
    camera = Camera.look_at((27.5, 16.0, 16.0), (22.0, 15.0, 17.0), fov_deg=70.0, width=16)
    with pytest.warns(UserWarning, match="100% of the light field's pixels that no probe "
                                         "proved empty were answered by no probe of the "
                                         "1x1x1 grid"):
        report = run_probe_study(octree, tmp_path / "closed", camera=camera,
                                 resolutions=(8, 16), probe_counts=((1, 1, 1),),
                                 marchers=("hierarchical",), orderings=("nearest",),
                                 timing_repeats=1, relocate_probes=False)
    assert len(report["notes"]) == 1
    assert "**Note:** 100% of the light field" in (tmp_path / "closed" / "results.md").read_text()


def test_a_view_the_probes_see_has_no_such_note(study):
    out, report = study
    row = next(q for q in report["quality"] if q["method"] == "light-field")
    assert row["failures"] / (1.0 - row["miss"]) < LOST_NOTE_SHARE and report["notes"] == []
    assert "**Note:**" not in (out / "results.md").read_text()


def test_resumes_without_recomputing(study, cornell, camera):
    out, first = study
    again = run_probe_study(cornell, out, scene_name="builtin:cornell", camera=camera, **TINY)
    assert again["items"]["computed"] == 0
    assert again["quality"] == first["quality"]
    assert again["resolution"] == first["resolution"]


def test_hierarchical_fetches_grow_slower_than_dda(study):
    _, report = study
    low, high = report["resolution"]
    growth = {m: high["marchers"][m]["fetches_per_pixel"] / low["marchers"][m]["fetches_per_pixel"]
              for m in ("dda", "hierarchical")}
    assert growth["hierarchical"] < growth["dda"]
    assert report["growth"]["hierarchical"]["exponent_r"] < report["growth"]["dda"]["exponent_r"]


def test_denser_grid_fails_less(study):
    _, report = study
    one, eight = report["probe_count"]
    for marcher in ("dda", "hierarchical"):
        assert eight["marchers"][marcher]["failures"] <= one["marchers"][marcher]["failures"]


def test_dda_and_hierarchical_give_the_same_answers(study):
    """The hierarchical trace skips texels, never changes the first event: same kinds."""
    _, report = study
    for row in report["resolution"]:
        dda, hier = row["marchers"]["dda"], row["marchers"]["hierarchical"]
        assert dda["failures"] == hier["failures"] and dda["hit"] == hier["hit"]


@pytest.mark.parametrize("bad", [
    {"resolutions": (32,)},
    {"resolutions": (2, 32)},
    {"marchers": ("bogus",)},
    {"orderings": ("signed-dot", "sideways")},
    {"probe_counts": ()},
    {"probe_counts": ((0, 1, 1),)},
    {"grid_counts": (1, 1)},
    {"timing_repeats": 0},
    {"camera": "top"},
])
def test_bad_input_is_a_voxfield_error(cornell, camera, tmp_path, bad):
    kwargs = {"camera": camera, **TINY, **bad}
    with pytest.raises(VoxfieldError):
        run_probe_study(cornell, tmp_path / "bad", **kwargs)


def test_parse_counts():
    assert parse_counts("4x1x4") == (4, 1, 4)
    assert parse_counts("3") == (3, 3, 3)
    with pytest.raises(VoxfieldError):
        parse_counts("4x4")


def test_grid_spec_names_each_grid_one_way():
    assert grid_spec((2, 2, 2)) == grid_spec("2x2x2") == grid_spec("2") == grid_spec(2) == "2x2x2"
    assert grid_spec("Surface: 4X3 @ 6.0") == "surface:4x3@6"
    for bad in ("surface:0x3@6", "surface:3x3@0", "surface:3x3@-2", "4x4", "cube"):
        with pytest.raises(VoxfieldError):
            grid_spec(bad)


def test_surface_layers_follow_a_terrain(tmp_path):
    """The probe-count section on layers over rolling ground: each probe stands its height
    above the ground below it, and both layers are measured."""
    x, z = np.meshgrid(np.arange(48), np.arange(48), indexing="ij")
    y = (14 + 5 * np.sin(x / 8.0) * np.cos(z / 6.0)).astype(np.int64)
    coords = np.stack([x.ravel(), y.ravel(), z.ravel()], axis=1)
    octree = build_octree(VoxelScene(coords, np.full((len(coords), 3), 0.5, np.float32)))
    camera = Camera.look_at((24.0, 40.0, 60.0), (24.0, 14.0, 24.0), fov_deg=60.0, width=16)
    report = run_probe_study(
        octree, tmp_path / "layers", camera=camera, grid_counts="surface:2x2@6",
        resolutions=(8, 16), probe_counts=("surface:2x2@6", "surface:3x3@8"),
        marchers=("hierarchical",), orderings=("nearest",), timing_repeats=1,
        relocate_probes=False)
    assert [row["grid"] for row in report["probe_count"]] == ["surface:2x2@6", "surface:3x3@8"]
    assert [row["probes"] for row in report["probe_count"]] == [4, 9]
    for spec, height in (("surface:2x2@6", 6.0), ("surface:3x3@8", 8.0)):
        positions = np.asarray(report["grids"][spec]["positions"])
        down = trace(octree, positions, np.tile([0.0, -1.0, 0.0], (len(positions), 1)), lod=0)
        assert down.hit.all()
        np.testing.assert_allclose(down.t, height, atol=1e-9)


def test_command_line_runs_the_study(tmp_path, capsys):
    from voxfield.cli import main

    out = tmp_path / "cli"
    code = main(["study", "probes", "builtin:cornell", "--resolutions", "8,16", "--probe-counts",
                 "1x1x1", "--marchers", "dda,hierarchical", "--orderings", "nearest",
                 "--repeats", "1", "--size", "16", "--epsilon-k", "4", "--out", str(out),
                 "--quiet"])
    assert code == 0
    # The default footprint epsilon reads no k: said, not silently dropped.
    assert ("the footprint epsilon takes no --epsilon-k (for adaptive/adaptive-text/angular)"
            in capsys.readouterr().err)
    report = json.loads((out / "results.json").read_text())
    cornell = open_octree("builtin:cornell")
    # The default view of a room is the thesis's, from among the probes inside its box.
    assert report["camera"] == room_camera(*cornell.voxel_bounds, size=16).params.tolist()
    assert [row["resolution"] for row in report["resolution"]] == [8, 16]
    assert {row["method"] for row in report["quality"]} >= {"light-field", "environment"}
    assert (out / "results.md").is_file()
    assert main(["study", "probes", "builtin:cornell", "--marchers", "teleport",
                 "--out", str(out), "--quiet"]) == 2
    assert "voxfield: error:" in capsys.readouterr().err


def test_a_grid_with_nothing_to_bake_is_refused_before_any_render(tmp_path, monkeypatch):
    """A counted grid over a slab, kept where it stands: every probe in the ground. The
    study baked zero-distance maps (its own rule spoke only when relocation disabled all),
    and refused, once it did, after the octree's reference render."""
    from voxfield.studies import probe_study

    x, z = np.meshgrid(np.arange(32), np.arange(32), indexing="ij")
    coords = np.stack([x.ravel(), np.zeros(x.size, np.int64), z.ravel()], axis=1)
    slab = build_octree(VoxelScene(coords, np.full((len(coords), 3), 0.5, np.float32)))
    camera = Camera.look_at((16.0, 30.0, 40.0), (16.0, 0.0, 16.0), fov_deg=60.0, width=8)

    def no_render(*args, **kwargs):
        raise AssertionError("rendered before the grid was checked")

    monkeypatch.setattr(probe_study, "render_lod", no_render)
    with pytest.raises(VoxfieldError, match="all 2 probes stand inside solid voxels"):
        run_probe_study(slab, tmp_path / "s", camera=camera, grid_counts="2x1x1",
                        resolutions=(8, 16), probe_counts=("2x1x1",), marchers=("hierarchical",),
                        orderings=("nearest",), timing_repeats=1, relocate_probes=False)


def test_a_psnr_equal_to_the_reference_reads_as_infinite_not_missing(study):
    """Every row of the study is measured against the octree, so a PSNR JSON stores as null
    is an image equal to it: ∞ in every table, as the other studies print it."""
    from voxfield.json_output import to_json
    from voxfield.studies.probe_study import results_markdown

    _, report = study
    fresh = copy.deepcopy(report)  # in memory an equal image's PSNR is inf
    next(q for q in fresh["quality"] if q["method"] == "light-field")["psnr"] = math.inf
    gap_fresh = next(line for line in results_markdown(fresh).splitlines()
                     if line.startswith("| light-field")).split("|")[4]
    assert gap_fresh == " — "  # as read back from JSON, not "−∞"
    report = json.loads(json.dumps(to_json(report)))
    light_field = next(q for q in report["quality"] if q["method"] == "light-field")
    light_field["psnr"] = light_field["bound_psnr"] = None
    for row in report["resolution"] + report["probe_count"]:
        for measured in row["marchers"].values():
            measured["psnr"] = measured["bound_psnr"] = None
    text = results_markdown(report)
    quality = next(line for line in text.splitlines() if line.startswith("| light-field"))
    assert quality.split("|")[2:4] == [" ∞ ", " ∞ "]
    for size in ("16²", "32²"):
        row = next(line for line in text.splitlines() if line.startswith(f"| {size}"))
        assert row.rstrip(" |").endswith("∞ | ∞")
    counted = next(line for line in text.splitlines() if line.startswith("| 2x2x2"))
    assert counted.rstrip(" |").endswith("∞ | ∞")


def test_the_study_judges_lost_pixels_among_those_not_proven_empty():
    """Section 1's note reads its row's shares as probe-render does: 10 % of all pixels lost
    is a third of the 30 % the probes did not prove empty, and worth a word; the same 10 %
    of a view the object fills is not. The baselines' rows are not read."""
    def rows(failures, miss):
        return [{"method": "environment", "failures": 0.0, "miss": 0.0},
                {"method": "light-field", "failures": failures, "miss": miss}]

    note = study_lost_note(rows(0.10, 0.70), "2x2x2")
    assert note is not None and note.startswith("33% of the light field's pixels")
    assert "of the 2x2x2 grid" in note and "--grid" in note
    assert study_lost_note(rows(0.10, 0.0), "2x2x2") is None


def _solid_block(path):
    """A solid 16³ block in the middle of a 32³ box (marked by four corner voxels): the
    room view's eye, 30 % in from the box's +z face, lies inside the block."""
    from voxfield.svo.io import save_octree

    axis = np.arange(8, 24)
    block = np.stack(np.meshgrid(axis, axis, axis, indexing="ij"), -1).reshape(-1, 3)
    corners = np.array([[0, 0, 0], [31, 31, 31], [0, 31, 0], [31, 0, 31]])
    coords = np.concatenate([block, corners])
    colours = np.random.default_rng(0).random((len(coords), 3)).astype(np.float32)
    save_octree(build_octree(VoxelScene(coords, colours, name="block")), path)
    return path


def test_the_default_view_of_a_solid_model_looks_from_around_it(tmp_path, capsys):
    """A solid model filling its box (T-Rex.vox) put the default room view's eye inside a
    voxel, and the study refused to run without another --camera; the default now looks
    from around it (orbit), and an explicit room view is still refused."""
    from voxfield.cli import main
    from voxfield.render.camera import preset_camera
    from voxfield.render.framing import content_box

    scene = str(_solid_block(tmp_path / "block.npz"))
    common = ["--resolutions", "8,16", "--probe-counts", "1x1x1", "--marchers", "dda",
              "--orderings", "nearest", "--repeats", "1", "--size", "16", "--quiet"]
    assert main(["study", "probes", scene, "--camera", "room", "--out",
                 str(tmp_path / "room"), *common]) == 2
    assert "is inside a voxel" in capsys.readouterr().err
    assert main(["study", "probes", scene, "--out", str(tmp_path / "auto"), *common]) == 0
    report = json.loads((tmp_path / "auto" / "results.json").read_text())
    block = open_octree(scene)
    orbit = preset_camera("orbit", *(np.asarray(b, np.float64) for b in content_box(block)),
                          size=16)
    assert report["camera"] == orbit.params.tolist()


def test_the_default_view_of_a_terrain_looks_down_on_it():
    """As ``probe-render`` and ``render`` look at a terrain: from above (the room view's eye
    over a terrain's box stood under its hills)."""
    from voxfield.cli.cmd_study import probe_study_view
    from voxfield.cli.main import build_parser
    from voxfield.cli.options import open_octree as open_scene
    from voxfield.cli.options import scene_camera

    args = build_parser("study").parse_args(["study", "probes", "terrain:desert",
                                             "--footprint", "64", "--size", "16"])
    octree = open_scene(args)
    top = scene_camera(argparse.Namespace(**{**vars(args), "camera": "top"}), octree)
    assert args.camera == "auto"
    assert probe_study_view(args, octree).params.tolist() == top.params.tolist()
