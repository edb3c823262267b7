"""The comparison study: files and tables written, metrics sane, finished items not redone."""

from __future__ import annotations

import json

import numpy as np
import pytest
from PIL import Image

from voxfield.cli.options import default_output
from voxfield.errors import VoxfieldError
from voxfield.render import Camera, render_lod, render_reference
from voxfield.scene.builtin import pillars
from voxfield.studies import compare
from voxfield.studies.report import StudyFolder, markdown_table, params_key
from voxfield.svo import build_octree

IMAGES = ("reference.png", "adaptive.png", "error_aware.png", "adaptive_rays.png",
          "adaptive_variance.png", "error_aware_rays.png", "error_aware_lod.png",
          "contact_sheet.png")
ITEMS = ["reference", "adaptive", "error_aware", "quality_adaptive", "quality_error_aware"]


@pytest.fixture(scope="module")
def scene():
    octree = build_octree(pillars(32))
    camera = Camera.look_at((40, 30, 45), (16, 4, 16), fov_deg=55, width=32)
    return octree, camera


@pytest.fixture
def stub_renderers(monkeypatch):
    """Stand-ins built on the LOD renderer, with the maps the real ones add; counts the
    calls, the warm-up on a few pixels before each left out."""
    calls = []

    def counted(name, camera):
        if camera.width > 4:
            calls.append(name)

    def adaptive(octree, camera, *, base_lod, iterations, **options):
        counted("adaptive", camera)
        result = render_lod(octree, camera, lod=base_lod, **options)
        covered = result.hit_count > 0
        result.maps["variance"] = np.where(covered, 0.5, 0.0)
        result.maps["refinement_class"] = np.where(covered, 1, -1).astype(np.int8)
        result.renderer = "adaptive"
        return result

    def error_aware(octree, camera, *, threshold, decay, base_lod, max_refinements, **options):
        counted("error-aware", camera)
        result = render_lod(octree, camera, lod=0, **options)
        result.maps["refined"] = np.zeros(result.shape, np.int32)
        result.renderer = "error-aware"
        return result

    def reference(octree, camera, **kwargs):
        counted("reference", camera)
        return render_reference(octree, camera, **kwargs)

    renderers = {"reference": reference, "adaptive": adaptive, "error-aware": error_aware}
    monkeypatch.setattr(compare, "render", lambda octree, camera, name, **options:
                        renderers[name](octree, camera, **options))
    return calls


def _check_folder(out, report):
    for name in IMAGES + ("results.json", "results.md"):
        assert (out / name).is_file(), name
    data = json.loads((out / "results.json").read_text())  # strict JSON: no NaN or Infinity
    assert set(data) >= {"study", "scene", "camera", "settings", "notes", "rows", "images"}
    assert [row["renderer"] for row in data["rows"]] == ["reference", "adaptive", "error-aware"]
    reference, *others = data["rows"]
    assert reference["quality"] is None  # the reference is not compared with itself
    for row in others:
        assert set(row["quality"]) == {"psnr", "rmse", "ssim", "flip"}
        assert row["quality"]["psnr"] is None or row["quality"]["psnr"] > 0
        assert 0 <= row["quality"]["rmse"] < 1 and -1 <= row["quality"]["ssim"] <= 1
    for row in data["rows"]:
        cost = row["cost"]
        assert {"rays", "rays_hit", "rays_per_pixel", "traversal_steps", "steps_per_ray",
                "seconds", "ray_histogram", "lod_histogram", "ray_distribution"} <= set(cost)
        assert sum(cost["ray_distribution"].values()) == 32 * 32
    assert reference["cost"]["rays"] == 32 * 32 * 16
    text = (out / "results.md").read_text()
    assert "| reference |" in text and "Table 5.3" in text and "Table 5.4" in text
    assert text.splitlines()[0].startswith("# Renderer comparison")
    assert Image.open(out / "reference.png").size == (32, 32)
    assert Image.open(out / "contact_sheet.png").size[0] > 4 * 32
    assert data == {k: report[k] for k in data}
    return data


def test_writes_the_study_and_resumes_from_cached_items(scene, stub_renderers, tmp_path):
    octree, camera = scene
    out = tmp_path / "study"
    first = compare.run_compare(octree, camera, out, threshold=0.154, decay=0.2, base_lod=2,
                                seed=0)
    _check_folder(out, first)
    assert first["computed"] == ITEMS and first["reused"] == []
    assert stub_renderers == ["reference", "adaptive", "error-aware"]
    cached = {p.name: p.stat().st_mtime_ns for p in (out / "items").iterdir()}
    assert len(cached) == 3 * 2 + 2  # renders: JSON + arrays; metrics: JSON

    second = compare.run_compare(octree, camera, out, threshold=0.154, decay=0.2, base_lod=2,
                                 seed=0)
    assert second["computed"] == [] and second["reused"] == ITEMS
    assert len(stub_renderers) == 3  # nothing rendered again
    assert {p.name: p.stat().st_mtime_ns for p in (out / "items").iterdir()} == cached
    assert second["rows"] == first["rows"]

    # A new threshold changes only the error-aware render and its metrics.
    third = compare.run_compare(octree, camera, out, threshold=0.3, decay=0.2, base_lod=2,
                                seed=0)
    assert third["computed"] == ["error_aware", "quality_error_aware"]
    assert stub_renderers[3:] == ["error-aware"]

    fresh = compare.run_compare(octree, camera, out, threshold=0.3, decay=0.2, base_lod=2,
                                seed=0, fresh=True)
    assert fresh["computed"] == ITEMS


def test_a_corrupt_cache_item_is_recomputed(scene, stub_renderers, tmp_path):
    octree, camera = scene
    compare.run_compare(octree, camera, tmp_path, base_lod=2)
    (npz,) = (tmp_path / "items").glob("reference-*.npz")
    npz.write_bytes(b"not a zip file")
    again = compare.run_compare(octree, camera, tmp_path, base_lod=2)
    assert again["computed"] == ["reference"] and stub_renderers.count("reference") == 2


def test_bad_settings_are_refused(scene, stub_renderers, tmp_path):
    octree, camera = scene
    with pytest.raises(VoxfieldError, match="base LOD"):
        compare.run_compare(octree, camera, tmp_path, base_lod=octree.depth + 1)
    (tmp_path / "file").write_text("")
    with pytest.raises(VoxfieldError, match="not a folder"):
        compare.run_compare(octree, camera, tmp_path / "file", base_lod=2)


def test_with_the_real_renderers(scene, tmp_path):
    pytest.importorskip("voxfield.render.adaptive", reason="adaptive renderer not available")
    pytest.importorskip("voxfield.render.error_aware", reason="error-aware renderer not available")
    octree, camera = scene
    report = compare.run_compare(octree, camera, tmp_path, threshold=0.154, decay=0.2,
                                 base_lod=2, seed=0)
    data = _check_folder(tmp_path, report)
    rows = {row["renderer"]: row for row in data["rows"]}
    ea = rows["error-aware"]["cost"]
    assert ea["ray_distribution"]["other"] == 0  # never more than 21 rays per pixel
    assert ea["rays_hit"] <= ea["rays"] <= rows["reference"]["cost"]["rays"] + 5 * 32 * 32
    assert set(rows["adaptive"]["cost"]["ray_histogram"]) == {"didn't hit", "1", "4", "16",
                                                              "other"}
    assert rows["adaptive"]["cost"]["ray_histogram"]["other"] == 0
    # Cheap renderers are close to, not equal to, the reference.
    for name in ("adaptive", "error-aware"):
        assert rows[name]["quality"]["rmse"] > 0 and rows[name]["quality"]["psnr"] > 10


def test_parent_reuse_row(scene, tmp_path):
    octree, camera = scene
    report = compare.run_compare(octree, camera, tmp_path, threshold=0.05, decay=0.2,
                                 base_lod=2, seed=0, reuse_parent=True)
    rows = {row["renderer"]: row for row in report["rows"]}
    fresh, reused = rows["error-aware"]["cost"], rows[compare.REUSE_ROW]["cost"]
    assert reused["rays"] < fresh["rays"]  # 3 new rays per refinement instead of 4
    assert rows[compare.REUSE_ROW]["quality"]["psnr"] > 10
    assert compare.REUSE_ROW in (tmp_path / "results.md").read_text()
    assert (tmp_path / "error_aware_reuse.png").is_file()
    # the console table's columns line up under the longest name
    from voxfield.cli.cmd_compare import summary_text

    table = summary_text(report).splitlines()[:-1]
    assert len({len(line) for line in table}) == 1
    assert all(line.index(" ", len(compare.REUSE_ROW)) == len(compare.REUSE_ROW)
               for line in table[1:])


def test_command_line_entry(scene, stub_renderers, tmp_path, capsys):
    from voxfield.cli import build_parser

    parser = build_parser()
    out = tmp_path / "cmp"
    args = parser.parse_args(["compare", "builtin:sphere", "--size", "16", "--camera", "orbit",
                              "--base-lod", "1", "--out", str(out)])
    args.quiet = False
    assert args.func(args) == 0
    printed = capsys.readouterr().out
    assert "error-aware" in printed and str(out) in printed
    assert (out / "results.md").is_file()
    with pytest.raises(SystemExit):
        parser.parse_args(["compare", "builtin:sphere", "--base-lod", "fine"])
    assert default_output("compare", "builtin:menger").as_posix() == "out/compare_menger"
    assert default_output("compare", "../data/vox/monu 1.vox").as_posix() == "out/compare_monu_1"


def test_report_helpers():
    assert params_key({"a": 1, "b": [1.0, 2]}) == params_key({"b": [1.0, 2], "a": 1})
    assert params_key({"a": 1}) != params_key({"a": 2})
    assert markdown_table(["x", "y"], [["a", 1]]) == "| x | y |\n| --- | ---: |\n| a | 1 |\n"
    folder = StudyFolder("unused", study="sweep")
    assert folder.path("results.md").name == "results.md"


def test_cache_keys_change_with_the_code(monkeypatch):
    import voxfield

    before = params_key({"a": 1})
    monkeypatch.setattr(voxfield, "SOURCE_DIGEST", "0123456789ab")
    assert params_key({"a": 1}) != before


def test_each_timed_render_follows_a_warm_up_of_its_renderer(scene, monkeypatch, tmp_path):
    """A first call's seconds held the kernels' loading: the 16-ray reference "took" 0.03 s
    and adaptive 0.15 s. Each render now follows the same renderer on a few pixels."""
    octree, camera = scene
    seen = []
    real = compare.render
    monkeypatch.setattr(compare, "render", lambda octree, camera, name, **options: (
        seen.append((name, camera.width)), real(octree, camera, name, **options))[1])
    compare.run_compare(octree, camera, tmp_path / "s", seed=0)
    full = [i for i, (_, width) in enumerate(seen) if width == camera.width]
    assert len(full) == 3
    for i in full:
        assert seen[i - 1] == (seen[i][0], 4)
