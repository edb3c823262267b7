"""``report.html``: a study folder as one self-contained page people would rather look at.

The page is rebuilt from what the folder already holds: ``results.json`` (title, scene and the
``comparisons`` a study lists: each image with its reference and cost maps), ``results.md``
(every table and note, converted by python-markdown) and the folder's PNG figures. Images are
embedded as data URIs and the page carries its own style and script, so it opens offline,
mailed or archived, with no file beside it. Difference maps are computed here from the PNGs,
so an old folder gets them too (``voxfield report FOLDER``).
"""

from __future__ import annotations

import base64
import io
import json
import re
import warnings
from pathlib import Path

import numpy as np
from PIL import Image

import voxfield
from voxfield.atomic import atomic_path
from voxfield.errors import VoxfieldError

REPORT_NAME = "report.html"
#: |Δ| of 8-bit sRGB images is small; this gain makes a 1/16 difference full scale.
DIFFERENCE_GAIN = 16


def write_html_report(folder: str | Path) -> Path:
    """Write ``FOLDER/report.html`` from the folder's results; returns its path."""
    folder = Path(folder)
    html = render_report(folder)
    path = folder / REPORT_NAME
    with atomic_path(path) as tmp:
        tmp.write_text(html, encoding="utf-8")
    return path


def render_report(folder: Path) -> str:
    """The page's HTML text for a study folder."""
    results = _read_results(folder)
    entries = results.get("comparisons")
    if entries is None:
        entries = []
    if not isinstance(entries, list):
        raise VoxfieldError(f"{folder / 'results.json'}: \"comparisons\" is "
                            f"{_kind(entries)}, not a list of comparisons")
    comparisons = [_comparison(folder, entry) for entry in entries]
    used = {name for c in comparisons for name in c.pop("files")}
    text, embedded = _embedded_images(folder, _read_markdown(folder / "results.md"))
    used |= embedded
    figures = [p for p in _figures(folder) if p.name not in used]
    if not (comparisons or figures or text.strip()):
        # A results.json of {} beside nothing else made a page of a title alone.
        raise VoxfieldError(f"{folder}: nothing to report: no comparisons in results.json, no "
                            "results.md and no PNG figures; run the study (or compare, sweep) "
                            "into this folder first")
    return render_page(title=_title(results), subtitle=_subtitle(results), markdown_text=text,
                       figures=figures, comparisons=comparisons)


#: A Markdown image of a file beside results.md: ``![beam profile](beam_profile.png)``.
_LOCAL_IMAGE = re.compile(r"!\[([^\]]*)\]\(([\w.-]+\.png)\)")


def _embedded_images(folder: Path, text: str) -> tuple[str, set[str]]:
    """``text`` with its images of the folder's PNGs as data URIs, where they stand (a
    relative link breaks once the page is mailed), and the names so embedded, which the
    figures after it then leave out."""
    embedded: set[str] = set()
    missing: list[str] = []

    def embed(match: re.Match) -> str:
        path = folder / match.group(2)
        if not path.is_file():
            missing.append(path.name)
            return match.group(0)
        if not _readable_png(path):
            return match.group(0)
        embedded.add(path.name)
        return f"![{match.group(1)}]({data_uri(path)})"

    text = _LOCAL_IMAGE.sub(embed, text)
    if missing:
        # Deleted figures left broken images in the page without a word.
        warnings.warn(f"{folder / 'results.md'} shows {', '.join(sorted(set(missing)))}, "
                      "missing from the folder; the page shows a broken image there",
                      stacklevel=3)
    return text, embedded


def render_page(*, title: str, subtitle: str, markdown_text: str, figures: list[Path],
                comparisons: list[dict] = ()) -> str:
    """One page: comparisons, figures, then the Markdown's tables and notes. A leading
    ``# heading`` in the Markdown becomes the page title."""
    first, _, rest = markdown_text.partition("\n")
    if first.startswith("# "):
        title, markdown_text = first[2:].strip(), rest
    return _template().render(
        title=title, subtitle=subtitle, comparisons=list(comparisons),
        figures=[{"label": _label(p.stem), "src": data_uri(p)} for p in figures],
        body=markdown_to_html(markdown_text) if markdown_text.strip() else "",
        difference_gain=DIFFERENCE_GAIN, version=voxfield.__version__,
    )


def write_page(path: Path, **page) -> Path:
    """``render_page`` written atomically to ``path``."""
    html = render_page(**page)
    with atomic_path(path) as tmp:
        tmp.write_text(html, encoding="utf-8")
    return path


def _read_results(folder: Path) -> dict:
    path = folder / "results.json"
    if not folder.is_dir():
        raise VoxfieldError(f"{folder}: no such study folder")
    if not path.is_file():
        raise VoxfieldError(f"{folder}: no results.json; run the study (or compare, sweep) "
                            "into this folder first")
    try:
        results = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise VoxfieldError(f"{path}: unreadable results ({exc})") from exc
    except RecursionError as exc:
        raise VoxfieldError(f"{path}: unreadable results (nested too deeply)") from exc
    if not isinstance(results, dict):
        raise VoxfieldError(f"{path}: not a voxfield results file (expected an object)")
    return results


def _read_markdown(path: Path) -> str:
    """``results.md``'s text; a folder without one has no tables."""
    if not path.is_file():
        return ""
    try:
        return path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise VoxfieldError(f"{path}: unreadable results ({exc})") from exc


def markdown_to_html(text: str) -> str:
    """Markdown as HTML with raw HTML switched off: a scene or file name holding markup
    shows as text, it never runs in the page."""
    # deferred: the Markdown and template libraries load only when a report is written
    from markdown import Markdown
    from markupsafe import Markup

    converter = Markdown(extensions=["tables"], output_format="html")
    converter.preprocessors.deregister("html_block")
    converter.inlinePatterns.deregister("html")
    return Markup(converter.convert(text))


def _template():
    # deferred: the Markdown and template libraries load only when a report is written
    from jinja2 import Environment, PackageLoader, select_autoescape

    env = Environment(loader=PackageLoader("voxfield.studies", "templates"),
                      autoescape=select_autoescape(["html", "j2"]), trim_blocks=True,
                      lstrip_blocks=True)
    return env.get_template("report.html.j2")


def _title(results: dict) -> str:
    study = str(results.get("study", "study")).replace("_", " ")
    scene = results.get("scene")
    name = scene.get("name") if isinstance(scene, dict) else scene
    return f"{study}: {name}" if name else study


def _subtitle(results: dict) -> str:
    parts = []
    scene = results.get("scene")
    if isinstance(scene, dict) and "voxels" in scene:
        voxels = scene["voxels"]
        whole = isinstance(voxels, int) and not isinstance(voxels, bool)
        count = f"{voxels:,}" if whole else str(voxels)
        parts.append(f"{count} voxels")
    camera = results.get("camera")
    if isinstance(camera, dict) and "width" in camera:
        parts.append(f"{camera['width']}×{camera.get('height', '?')}, camera "
                     f"{camera.get('label', '')}")
    parts.append(f"voxfield {voxfield.__version__}")
    return " · ".join(parts)


def _figures(folder: Path) -> list[Path]:
    """The folder's readable PNGs, the contact sheet first (it summarises the rest), then
    the view measured; one that is not (truncated, or not a PNG at all) is left out with a
    warning, not embedded as a broken image."""
    pngs = [p for p in sorted(folder.glob("*.png")) if _readable_png(p)]
    return sorted(pngs, key=lambda p: (p.stem != "contact_sheet", p.stem != "view", p.name))


def _readable_png(path: Path) -> bool:
    try:
        with Image.open(path) as image:
            if image.format != "PNG":
                raise ValueError(f"a {image.format} image")
            image.verify()  # every chunk present and its checksum right, nothing decoded
    except (OSError, ValueError, SyntaxError) as exc:
        warnings.warn(f"{path}: not a readable PNG ({exc}); left out of the report",
                      stacklevel=2)
        return False
    return True


def _label(stem: str) -> str:
    return stem.replace("_", " ")


def _comparison(folder: Path, entry: dict) -> dict:
    """One image against its reference: both embedded, the difference map, the cost maps."""
    where = folder / "results.json"
    if not isinstance(entry, dict):
        raise VoxfieldError(f"{where}: a comparison entry is {_kind(entry)}, not an object")
    missing = [key for key in ("name", "image", "reference") if key not in entry]
    if missing:
        raise VoxfieldError(f"{where}: a comparison entry lacks {', '.join(missing)}")
    name = str(entry["name"])
    maps = entry.get("maps") or {}
    if not isinstance(maps, dict):
        raise VoxfieldError(f"{where}: the maps of comparison {name!r} are {_kind(maps)}, "
                            "not an object")
    image_path = _inside(folder, entry["image"])
    reference_path = _inside(folder, entry["reference"])
    maps = {str(label): _inside(folder, file) for label, file in maps.items()}
    for path in (image_path, reference_path):
        if not path.is_file():
            raise VoxfieldError(f"{path}: an image the results list is missing")
    cards = [{"label": f"|Δ| against {entry.get('reference_name', 'reference')}",
              "src": png_uri(difference_map(image_path, reference_path))}]
    for label, path in maps.items():
        if path.is_file():
            cards.append({"label": label, "src": data_uri(path)})
    return {
        "name": name, "image": data_uri(image_path), "reference": data_uri(reference_path),
        "reference_name": str(entry.get("reference_name", "reference")),
        "summary": str(entry.get("summary", "")), "maps": cards,
        "files": {image_path.name, reference_path.name, *(p.name for p in maps.values())},
    }


def _kind(value) -> str:
    """What a JSON value is, in JSON's words."""
    if value is None or isinstance(value, bool):
        return json.dumps(value)
    if isinstance(value, (int, float)):
        return "a number"
    return {str: "a string", list: "a list", dict: "an object"}.get(type(value), "a value")


def _inside(folder: Path, name) -> Path:
    """A file the results name, which must lie in the folder itself: a report embeds only
    the study's own images."""
    path = folder / str(name)
    if "\0" in str(name) or path.resolve().parent != folder.resolve():
        raise VoxfieldError(f"{folder / 'results.json'} names {name!r}, which is not a file "
                            "in the study folder")
    return path


def difference_map(image_path: Path, reference_path: Path) -> np.ndarray:
    """|Δ| of two sRGB images (mean over channels, ×``DIFFERENCE_GAIN``) on the inferno scale."""
    from matplotlib import colormaps  # heavy: loaded only when a report is written

    a = _rgb(image_path)
    b = _rgb(reference_path)
    if a.shape != b.shape:
        raise VoxfieldError(f"{image_path.name} is {a.shape[1]}×{a.shape[0]} but its reference "
                            f"{reference_path.name} is {b.shape[1]}×{b.shape[0]}")
    delta = np.abs(a - b).mean(axis=2) * DIFFERENCE_GAIN
    return colormaps["inferno"](np.clip(delta, 0.0, 1.0))[..., :3]


def _rgb(path: Path) -> np.ndarray:
    try:
        with Image.open(path) as img:
            return np.asarray(img.convert("RGB"), np.float32) / 255.0
    except OSError as exc:
        raise VoxfieldError(f"{path}: unreadable image ({exc})") from exc


def data_uri(path: Path) -> str:
    return "data:image/png;base64," + base64.b64encode(path.read_bytes()).decode("ascii")


def png_uri(rgb: np.ndarray) -> str:
    buffer = io.BytesIO()
    Image.fromarray((np.clip(rgb, 0, 1) * 255 + 0.5).astype(np.uint8)).save(buffer, "PNG")
    return "data:image/png;base64," + base64.b64encode(buffer.getvalue()).decode("ascii")
