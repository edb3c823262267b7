"""``report.html``: self-contained, holds every table and image of its folder, and works in a
real headless browser (the slider moves the split) where Playwright and Chromium exist."""

from __future__ import annotations

import base64
import json
import os
import re
import shutil

import numpy as np
import pytest
from PIL import Image

from voxfield.cli import main
from voxfield.errors import VoxfieldError
from voxfield.studies.html_report import DIFFERENCE_GAIN, difference_map, write_html_report


@pytest.fixture(scope="module")
def compare_folder(tmp_path_factory):
    folder = tmp_path_factory.mktemp("report") / "compare"
    assert main(["--quiet", "compare", "builtin:sphere", "--size", "24",
                 "--out", str(folder)]) == 0
    return folder


def test_compare_writes_a_self_contained_page(compare_folder):
    html = (compare_folder / "report.html").read_text(encoding="utf-8")
    # Offline: nothing is fetched, every image is embedded.
    assert not re.search(r"""(src|href)\s*=\s*["']?(https?:|//)""", html)
    assert "<script src" not in html and "<link" not in html
    images = re.findall(r'<img[^>]*src="([^"]*)"', html)
    assert images and all(src.startswith("data:image/png;base64,") for src in images)
    # Every Markdown table of results.md is an HTML table.
    markdown = (compare_folder / "results.md").read_text(encoding="utf-8")
    tables = sum(1 for line in markdown.splitlines() if re.match(r"^\| *---", line))
    assert html.count("<table>") == tables > 0
    # One slider per renderer compared with the reference, and every PNG of the folder shown.
    assert html.count('class="slider" data-slider') == 2
    for png in compare_folder.glob("*.png"):
        assert base64.b64encode(png.read_bytes()).decode() in html, png.name


def test_difference_map_of_known_images(tmp_path):
    a = np.zeros((4, 5, 3), np.uint8)
    b = a.copy()
    b[1, 2] = 255 // DIFFERENCE_GAIN + 1  # just over full scale after the gain
    Image.fromarray(a).save(tmp_path / "a.png")
    Image.fromarray(b).save(tmp_path / "b.png")
    same = difference_map(tmp_path / "a.png", tmp_path / "a.png")
    assert np.allclose(same, same[0, 0])  # one colour: zero everywhere
    diff = difference_map(tmp_path / "a.png", tmp_path / "b.png")
    changed = np.any(np.abs(diff - same[0, 0]) > 1e-6, axis=2)
    assert changed.sum() == 1 and changed[1, 2]
    assert diff[1, 2].sum() > 2.5  # inferno's top end is near white


def test_report_command_rebuilds_and_refuses_a_plain_folder(compare_folder, tmp_path, capsys):
    (compare_folder / "report.html").unlink()
    assert main(["report", str(compare_folder), "--quiet"]) == 0
    assert (compare_folder / "report.html").is_file()
    assert main(["report", str(tmp_path)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "no results.json" in err[0]


def test_sweep_and_a_study_write_their_reports(tmp_path):
    sweep = tmp_path / "sweep"
    assert main(["--quiet", "sweep", "builtin:sphere", "--size", "16", "--decays", "0.2",
                 "--thresholds", "0.1,0.3", "--out", str(sweep)]) == 0
    html = (sweep / "report.html").read_text(encoding="utf-8")
    assert "<table>" in html and "sweep" in html.lower()
    assert html.count("data:image/png;base64,") == len(list(sweep.glob("*.png")))


def _chromium() -> str | None:
    for candidate in (os.environ.get("VOXFIELD_CHROMIUM"), "chromium", "chromium-browser",
                      "google-chrome"):
        if candidate and shutil.which(candidate):
            return shutil.which(candidate)
    return None


def test_report_in_a_headless_browser(compare_folder, tmp_path):
    sync_api = pytest.importorskip(
        "playwright.sync_api", reason="Playwright not installed (pip install -e .[browser])")
    executable = _chromium()
    if executable is None:
        pytest.skip("no Chromium found (apt-get install chromium, or set VOXFIELD_CHROMIUM)")
    with sync_api.sync_playwright() as playwright:
        browser = playwright.chromium.launch(executable_path=executable,
                                             args=["--no-sandbox"])
        try:
            page = browser.new_page(viewport={"width": 1200, "height": 900})
            page.goto((compare_folder / "report.html").as_uri())
            assert page.locator("table").count() >= 3
            loaded = page.eval_on_selector_all(
                "img", "imgs => imgs.map(i => i.complete && i.naturalWidth > 0)")
            assert loaded and all(loaded)
            first = page.locator("article.comparison").first
            over = first.locator("img.over")
            clip = "getComputedStyle(e).clipPath"
            assert "50%" in over.evaluate(f"e => {clip}")
            first.locator("input[type=range]").fill("20")
            assert "80%" in over.evaluate(f"e => {clip}")
            first.locator("[data-flip]").click()  # from 20 % the flip shows all of the image
            assert over.evaluate(f"e => {clip}").replace(" ", "") in (
                "inset(0px0%0px0px)", "inset(0px)", "inset(0%0%0%0%)", "inset(0px0px0px0px)")
            shot = tmp_path / "report.png"
            page.screenshot(path=str(shot), full_page=True)
        finally:
            browser.close()
    pixels = np.asarray(Image.open(shot).convert("L"))
    assert pixels.shape[0] > 900 and pixels.std() > 10  # a long page with content, not blank


def test_markup_in_results_is_text_and_paths_stay_in_the_folder(compare_folder, tmp_path):
    folder = tmp_path / "hostile"
    shutil.copytree(compare_folder, folder)
    (folder / "results.md").write_text(
        "# <b>x</b>\n\n| scene |\n|---|\n| <script>alert(1)</script> |\n")
    write_html_report(folder)
    html = (folder / "report.html").read_text(encoding="utf-8")
    assert "<script>alert" not in html and "&lt;script&gt;alert(1)" in html
    assert "<b>x</b>" not in html
    results = json.loads((folder / "results.json").read_text())
    results["comparisons"][0]["maps"] = {"secret": "../../etc/passwd"}
    (folder / "results.json").write_text(json.dumps(results))
    with pytest.raises(VoxfieldError, match="not a file in the study folder"):
        write_html_report(folder)


def test_images_named_in_the_results_are_embedded_where_they_stand_once(compare_folder,
                                                                       tmp_path):
    """`shadows` names its beam profile and contact sheet in results.md: the page linked
    them by relative path (broken once mailed) and showed them again among the figures."""
    folder = tmp_path / "named"
    shutil.copytree(compare_folder, folder)
    png = folder / "beam_profile.png"
    Image.fromarray(np.full((3, 5, 3), 90, np.uint8)).save(png)
    (folder / "results.md").write_text(
        f"# Named\n\nbefore\n\n![the picture]({png.name})\n\nafter\n\n"
        "![outside](../elsewhere.png) ![missing](missing.png)\n")
    with pytest.warns(UserWarning, match="shows missing.png, missing from the folder"):
        write_html_report(folder)
    html = (folder / "report.html").read_text(encoding="utf-8")
    sources = re.findall(r'<img[^>]*src="([^"]*)"', html)
    assert f'src="{png.name}"' not in html
    encoded = base64.b64encode(png.read_bytes()).decode()
    assert html.count(encoded) == 1
    assert html.index("before") < html.index(encoded) < html.index("after")
    # only a file beside results.md is read: other links stay links
    assert "../elsewhere.png" in sources and "missing.png" in sources
