"""The lighting study (EA §5.3): per-channel rows, the geometric renderer's channel-blind cost,
tables and files, resumption, and a clear refusal without baked channels."""

from __future__ import annotations

import numpy as np
import pytest

from voxfield.errors import VoxfieldError
from voxfield.lighting import bake_sun_lighting, parse_suns
from voxfield.render import Camera
from voxfield.scene.builtin import pillars
from voxfield.studies.lighting_study import image_luminance, run_lighting_study
from voxfield.svo import build_octree


@pytest.fixture(scope="module")
def lit():
    octree, _ = bake_sun_lighting(build_octree(pillars(32)), parse_suns("noon,evening"),
                                  sky_rays=4)
    return octree, Camera.look_at((40, 30, 45), (16, 4, 16), fov_deg=55, width=24)


def test_rows_tables_and_resumption(lit, tmp_path):
    octree, camera = lit
    report = run_lighting_study(octree, camera, tmp_path, threshold=0.2)
    rows = {r["channel"]: r for r in report["rows"]}
    assert list(rows) == ["albedo", "noon", "evening"]  # the day's order
    # The geometric error ignores colour: EA casts the same rays whatever the lighting
    # (thesis §4: "ray counts ... are therefore identical"); colour-aware ones may differ.
    assert len({r["error_aware"]["rays"] for r in rows.values()}) == 1
    for row in rows.values():
        assert row["lighting_aware"]["rays"] >= row["error_aware"]["rays"]
    assert rows["evening"]["luminance"] < rows["noon"]["luminance"]
    text = (tmp_path / "results.md").read_text()
    assert "Table 5.19" in text and "EA-L" in text
    for name in ("results.json", "lighting.png", "contact_sheet.png"):
        assert (tmp_path / name).is_file()
    again = run_lighting_study(octree, camera, tmp_path, threshold=0.2)
    assert again["rows"] == report["rows"]


def test_without_baked_channels_it_says_how_to_bake(tmp_path):
    octree = build_octree(pillars(16))
    camera = Camera.look_at((20, 15, 25), (8, 2, 8), fov_deg=55, width=8)
    with pytest.raises(VoxfieldError, match="voxfield light"):
        run_lighting_study(octree, camera, tmp_path)
    with pytest.raises(VoxfieldError):
        run_lighting_study(octree, camera, tmp_path, channels=["albedo", "dusk"])


def test_chosen_channels_must_be_two_different_ones(lit, tmp_path):
    """``--channels albedo`` on a lit scene was told the scene had no baked channels."""
    octree, camera = lit
    with pytest.raises(VoxfieldError, match="compares channels: name at least two"):
        run_lighting_study(octree, camera, tmp_path, channels=["albedo"])
    with pytest.raises(VoxfieldError, match="named twice"):
        run_lighting_study(octree, camera, tmp_path, channels=["noon", "noon"])
    assert not any(tmp_path.iterdir())


def test_image_luminance_is_rec709():
    image = np.zeros((2, 2, 3))
    image[..., 1] = 1.0
    assert image_luminance(image) == pytest.approx(0.7152)


def test_baked_channels_are_studied_in_the_day_s_order():
    """Sorted by name they read afternoon, evening, morning, noon; a sun of another name
    comes after the times of day."""
    from voxfield.studies.lighting_study import lighting_channels

    octree = build_octree(pillars(16))
    lit, _ = bake_sun_lighting(octree, parse_suns("evening,noon;dawn=90,5;morning,afternoon"),
                               sky_rays=0)
    assert lighting_channels(lit) == ["albedo", "morning", "noon", "afternoon", "evening",
                                      "dawn"]


def test_the_command_notes_times_a_lit_scene_does_not_bake(tmp_path, capsys):
    """A scene with baked channels is studied as it is: --times changed nothing, without a
    word."""
    from voxfield.cli import main

    lit = tmp_path / "lit.npz"
    assert main(["light", "builtin:pillars", "--times", "noon", "--sky-rays", "0",
                 "--no-preview", "--quiet", "--out", str(lit)]) == 0
    assert main(["study", "lighting", str(lit), "--times", "evening", "--size", "16",
                 "--quiet", "--out", str(tmp_path / "study")]) == 0
    assert capsys.readouterr().err == (
        "voxfield: note: a scene with baked channels (noon) takes no --times (for a scene "
        "without baked channels); ignored\n")


def test_the_command_refuses_a_channel_the_bake_will_not_make_before_baking(
        tmp_path, capsys, monkeypatch):
    """`--channels nosuch` was refused after the study's sun bake, minutes in on a terrain."""
    from cli_output import one_error_line
    from voxfield.cli import cmd_study, main

    def no_bake(*args, **kwargs):
        raise AssertionError("baked")

    monkeypatch.setattr(cmd_study, "bake_sun_lighting", no_bake)
    out = tmp_path / "study"
    assert main(["study", "lighting", "builtin:pillars", "--times", "noon", "--channels",
                 "albedo,nosuch", "--size", "16", "--out", str(out)]) == 2
    assert one_error_line(capsys) == (
        "voxfield: error: --channels nosuch: the scene has no such channel, nor does the study "
        "bake one; it will have albedo, noon")
    assert not out.exists()
