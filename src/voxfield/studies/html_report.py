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
import html
import io
import json
import re
import warnings
from collections.abc import Iterable, Sequence
from pathlib import Path
from urllib.parse import quote

import numpy as np
from PIL import Image

import voxfield
from voxfield.atomic import atomic_path
from voxfield.errors import VoxfieldError

REPORT_NAME = "report.html"
#: |Δ| of 8-bit sRGB images is small; this gain makes a 1/16 difference full scale.
DIFFERENCE_GAIN = 16


def write_html_report(folder: str | Path, *, expected: Iterable[str] = ()) -> Path:
    """Write ``FOLDER/report.html`` from the folder's results; returns its path.

    ``expected`` names figures the folder should hold (those its study always draws, or its
    last report showed): one that is missing is a note, and a card on the page that says
    so, where it was left out without a word."""
    folder = Path(folder)
    html = render_report(folder, expected=expected)
    path = folder / REPORT_NAME
    with atomic_path(path) as tmp:
        tmp.write_text(html, encoding="utf-8")
    return path


def render_report(folder: Path, *, expected: Iterable[str] = ()) -> str:
    """The page's HTML text for a study folder (``expected``: as ``write_html_report``)."""
    results = _read_results(folder)
    _check_fields(folder / "results.json", results)
    entries = results.get("comparisons")
    if entries is None:
        entries = []
    if not isinstance(entries, list):
        raise VoxfieldError(f"{folder / 'results.json'}: \"comparisons\" is "
                            f"{_kind(entries)}, not a list of comparisons")
    comparisons = [_comparison(folder, entry) for entry in entries]
    used = {name for c in comparisons for name in c.pop("files")}
    markdown = _read_markdown(folder / "results.md")
    text, embedded, shown_missing = _embedded_images(folder, markdown)
    used |= embedded
    figures = [p for p in _figures(folder) if p.name not in used]
    named = {*_named_images(folder, results), *expected} - used - set(shown_missing)
    missing = _missing_figures(folder, named)
    if not (comparisons or figures or text.strip()):
        # A results.json of {} beside nothing else made a page of a title alone.
        lost = f" ({', '.join(missing)} missing)" if missing else ""
        raise VoxfieldError(f"{folder}: nothing to report: no comparisons in results.json, no "
                            f"results.md and no PNG figures{lost}; run the study (or compare, "
                            "sweep) into this folder first")
    _note_left_out(folder, markdown_found=(folder / "results.md").exists(),
                   shown_missing=shown_missing, missing=missing,
                   maps=[m for c in comparisons for m in c["missing_maps"]])
    return render_page(title=_title(results), subtitle=_subtitle(results), markdown_text=text,
                       figures=figures, comparisons=comparisons, missing_figures=missing)


def _named_images(folder: Path, results: dict) -> list[str]:
    """The files ``results.json``'s ``images`` names (compare lists every PNG it wrote):
    the page should show each, so one gone from the folder is missing, not merely absent."""
    images = results.get("images")
    if images is None:
        return []
    where = folder / "results.json"
    if not isinstance(images, dict):
        raise VoxfieldError(f"{where}: \"images\" is {_kind(images)}, not an object of "
                            "file names")
    for label, name in images.items():
        if not isinstance(name, str):
            raise VoxfieldError(f"{where}: image {label!r} is {_kind(name)}, not a file name")
    return [_inside(folder, name).name for name in images.values()]


def _missing_figures(folder: Path, names: Iterable[str]) -> list[str]:
    """Of the PNGs the page should show, those the folder lacks, in the figures' order.
    Only plain names count: an expectation never reads a path outside the folder."""
    plain = {n for n in names if isinstance(n, str) and n == Path(n).name
             and n.endswith(".png") and n not in ("", ".", "..")}
    return sorted((n for n in plain if not (folder / n).is_file()), key=_figure_order)


def _note_left_out(folder: Path, *, markdown_found: bool, shown_missing: Sequence[str],
                   missing: Sequence[str], maps: Sequence[str]) -> None:
    """One note for each thing the page cannot show, once it is certain to be written: a
    figure, cost map or the tables gone from the folder made a page that simply lacked
    them, and nobody could tell a damaged folder from a study that drew less."""
    if not markdown_found:
        warnings.warn(f"{folder}: no results.md; the page has no tables", stacklevel=3)
    if shown_missing:
        # Deleted figures left broken images in the page without a word.
        warnings.warn(f"{folder / 'results.md'} shows {', '.join(shown_missing)}, "
                      "missing from the folder; the page shows a broken image there",
                      stacklevel=3)
    if missing:
        warnings.warn(f"{folder}: {_are_missing(missing)}", stacklevel=3)
    if maps:
        warnings.warn(f"{folder}: cost map{'s' if len(maps) > 1 else ''} "
                      f"{_are_missing(maps)}", stacklevel=3)


def _are_missing(names: Sequence[str]) -> str:
    one = len(names) == 1
    return (f"{', '.join(names)} {'is' if one else 'are'} missing from the folder; the page "
            f"marks {'it' if one else 'each'} as missing")


#: A Markdown image of a file beside results.md: ``![beam profile](beam_profile.png)``.
_LOCAL_IMAGE = re.compile(r"!\[([^\]]*)\]\(([\w.-]+\.png)\)")


def _embedded_images(folder: Path, text: str) -> tuple[str, set[str], list[str]]:
    """``text`` with its images of the folder's PNGs as data URIs, where they stand (a
    relative link breaks once the page is mailed), the names so embedded, which the
    figures after it then leave out, and those it shows that the folder lacks."""
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
    return text, embedded, sorted(set(missing))


def render_page(*, title: str, subtitle: str, markdown_text: str, figures: list[Path],
                comparisons: list[dict] = (), missing_figures: Sequence[str] = ()) -> str:
    """One page: comparisons, figures, then the Markdown's tables and notes. A leading
    ``# heading`` in the Markdown becomes the page title. Each of ``missing_figures`` (file
    names) stands among the figures as a card that says it is missing."""
    first, _, rest = markdown_text.partition("\n")
    if first.startswith("# "):
        title, markdown_text = first[2:].strip(), rest
    cards = [(p.name, {"label": _label(p.stem), "src": data_uri(p)}) for p in figures]
    cards += [(name, _missing_card(_label(Path(name).stem), name)) for name in missing_figures]
    cards.sort(key=lambda card: _figure_order(card[0]))
    return _template().render(
        title=title, subtitle=subtitle, comparisons=list(comparisons),
        figures=[card for _, card in cards],
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
    if path.exists() and not path.is_file():
        raise VoxfieldError(f"{path}: a folder, not a voxfield results file")
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
    """``results.md``'s text; a folder without one has no tables (a folder of that name is
    refused: it was taken for none, and the page lost its tables without a word)."""
    if not path.exists():
        return ""
    if path.is_dir():
        raise VoxfieldError(f"{path}: a folder, not the study's tables")
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


def _check_fields(where: Path, results: dict) -> None:
    """Refuse the values the title and subtitle show that are of the wrong kind: a scene of
    ``[1, 2]`` or a study of ``{"a": 1}`` made a page titled with Python's repr of them,
    and a camera width of ``[1]`` a subtitle of "[1]×?"."""
    _optional(where, results, "study", str, "a string")
    scene = results.get("scene")
    if isinstance(scene, dict):
        _optional(where, scene, "name", str, "a string", owner="the scene's ")
        voxels = scene.get("voxels")
        if voxels is not None and not (_whole(voxels) or isinstance(voxels, str)):
            raise VoxfieldError(f"{where}: the scene's \"voxels\" is {_kind(voxels)}, not a "
                                "whole number")
    elif scene is not None and not isinstance(scene, str):
        raise VoxfieldError(f"{where}: \"scene\" is {_kind(scene)}, not a name or an object")
    camera = results.get("camera")
    if isinstance(camera, dict):
        for key in ("width", "height"):
            value = camera.get(key)
            if value is not None and not (_whole(value) and value > 0):
                raise VoxfieldError(f"{where}: the camera's \"{key}\" is {_kind(value)}, not "
                                    "a number of pixels")
        _optional(where, camera, "label", str, "a string", owner="the camera's ")


def _optional(where: Path, record: dict, key: str, kind: type, says: str, *,
              owner: str = "") -> None:
    """``record[key]`` is absent, null or of ``kind``; anything else is refused, naming it
    (``owner``: whose key it is, "the scene's ")."""
    value = record.get(key)
    if value is not None and not isinstance(value, kind):
        raise VoxfieldError(f"{where}: {owner}\"{key}\" is {_kind(value)}, not {says}")


def _whole(value) -> bool:
    return isinstance(value, int) and not isinstance(value, bool)


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
    if isinstance(camera, dict) and camera.get("width") is not None:
        parts.append(f"{camera['width']}×{camera.get('height') or '?'}, camera "
                     f"{camera.get('label') or ''}")
    parts.append(f"voxfield {voxfield.__version__}")
    return " · ".join(parts)


def _figures(folder: Path) -> list[Path]:
    """The folder's readable PNGs, the contact sheet first (it summarises the rest), then
    the view measured; one that is not (truncated, or not a PNG at all) is left out with a
    warning, not embedded as a broken image."""
    pngs = [p for p in sorted(folder.glob("*.png")) if _readable_png(p)]
    return sorted(pngs, key=lambda p: _figure_order(p.name))


def _figure_order(name: str) -> tuple:
    """The figures' order on the page: the contact sheet, the view measured, then by name."""
    stem = Path(name).stem
    return stem != "contact_sheet", stem != "view", name


def _missing_card(label: str, name: str) -> dict:
    """A card in place of an image the folder lacks: a grey box that says which file is
    missing, so the page shows the gap rather than closing over it."""
    text = html.escape(f"missing: {name}", quote=False)
    svg = ('<svg xmlns="http://www.w3.org/2000/svg" width="320" height="120" '
           'viewBox="0 0 320 120"><rect width="320" height="120" fill="#eee" '
           'stroke="#999" stroke-dasharray="6 4"/><text x="160" y="64" font-family="sans-serif" '
           f'font-size="14" text-anchor="middle" fill="#555">{text}</text></svg>')
    return {"label": f"{label} (missing: {name} is not in the folder)",
            "src": "data:image/svg+xml," + quote(svg), "missing": name}


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
    name = entry["name"]
    if not isinstance(name, str):
        raise VoxfieldError(f"{where}: a comparison's \"name\" is {_kind(name)}, not a string")
    _check_entry_fields(where, name, entry)
    maps = entry.get("maps")
    if maps is None:
        maps = {}
    if not isinstance(maps, dict):
        raise VoxfieldError(f"{where}: the maps of comparison {name!r} are {_kind(maps)}, "
                            "not an object")
    image_path = _inside(folder, entry["image"])
    reference_path = _inside(folder, entry["reference"])
    maps = {str(label): _inside(folder, file) for label, file in maps.items()}
    for key, path in (("image", image_path), ("reference", reference_path)):
        if not path.is_file():
            # The slider, and the difference map, are the comparison: none without both.
            raise VoxfieldError(f"{path}: the {key} of comparison {name!r} in {where.name} is "
                                "missing from the folder")
    reference_name = entry.get("reference_name") or "reference"
    cards = [{"label": f"|Δ| against {reference_name}",
              "src": png_uri(difference_map(image_path, reference_path))}]
    missing_maps = []
    for label, path in maps.items():
        if path.is_file():
            cards.append({"label": label, "src": data_uri(path)})
        else:
            # A deleted cost map was dropped from the comparison without a word.
            cards.append(_missing_card(label, path.name))
            missing_maps.append(path.name)
    return {
        "name": name, "image": data_uri(image_path), "reference": data_uri(reference_path),
        "reference_name": reference_name, "summary": entry.get("summary") or "", "maps": cards,
        "missing_maps": missing_maps,
        "files": {image_path.name, reference_path.name, *(p.name for p in maps.values())},
    }


def _check_entry_fields(where: Path, name: str, entry: dict) -> None:
    """A comparison's file names and texts are strings: an image of ``5`` was looked for as
    a file named "5", and a reference name of null shown as "None"."""
    for key in ("image", "reference"):
        if not isinstance(entry[key], str):
            raise VoxfieldError(f"{where}: the {key} of comparison {name!r} is "
                                f"{_kind(entry[key])}, not a file name")
    for key in ("reference_name", "summary"):
        _optional(where, entry, key, str, "a string", owner=f"comparison {name!r}'s ")
    maps = entry.get("maps")
    for label, file in maps.items() if isinstance(maps, dict) else ():
        if not isinstance(file, str):
            raise VoxfieldError(f"{where}: the map {label!r} of comparison {name!r} is "
                                f"{_kind(file)}, not a file name")


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
