"""A study's output folder: results written atomically, finished items cached so runs resume.

Every file goes through ``atomic_path``, so an interrupted study never leaves half a file.
The report files (results, figures, ``report.html``) are staged in a hidden folder and moved
into place together by ``publish_report``, so a rerun stopped part way leaves the earlier
report whole, never its page beside new tables that a reader would take for one run.
Expensive items (renders, metrics) are cached under ``items/`` as ``NAME-KEY.json`` (plus
``NAME-KEY.npz`` for arrays), ``KEY`` a hash of everything the item depends on; re-running the
study with the same inputs loads them instead of recomputing, and changed inputs get new keys.
The JSON file is written last, so it marks a complete item, and carries a digest of its own
content, so a file this module did not write (hand-edited, or another tool's) is recomputed
rather than trusted with data of the wrong shape.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import shutil
import weakref
import zipfile
import zlib
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np

import voxfield
from voxfield.array_files import load_arrays
from voxfield.atomic import atomic_path, check_writable, save_figure
from voxfield.errors import VoxfieldError
from voxfield.folder_lock import FolderLock
from voxfield.json_output import json_text, to_json
from voxfield.metrics import compare_images, psnr_text
from voxfield.parallel import thread_count
from voxfield.probes.probe_folder import HEADER_NAME as PROBE_SET_HEADER
from voxfield.render.image_io import save_png
from voxfield.render.result import RenderResult
from voxfield.scaleout import check_scheduler, run_tasks
from voxfield.studies.html_report import REPORT_NAME, write_html_report
from voxfield.studies.study_mark import STUDY_FIGURES, STUDY_MARK, read_study_mark

#: Bump when the cached item layout changes, so old caches are recomputed, not misread.
CACHE_VERSION = 2

_RESULT_ARRAYS = ("image", "depth", "normal", "ray_count", "hit_count", "steps", "finest_lod")
_MAP_PREFIX = "map_"


def _json_hash(value, digest_size: int) -> str:
    """A hash of ``value``'s canonical JSON (sorted keys), which a copy loaded from JSON
    reproduces exactly (JSON floats round-trip)."""
    text = json.dumps(to_json(value), sort_keys=True)
    return hashlib.blake2b(text.encode(), digest_size=digest_size).hexdigest()


def _record_digest(record: dict) -> str:
    """The hash ``_store`` writes beside an item's record, over the record as written."""
    return _json_hash(record, 16)


def params_key(params: dict) -> str:
    """A short stable hash of an item's parameters (canonical JSON, sorted keys) and of the
    code that computes it: a changed renderer never serves results of the old one."""
    return _json_hash({"cache_version": CACHE_VERSION, "code": voxfield.SOURCE_DIGEST,
                       **params}, 8)


def result_to_arrays(result: RenderResult) -> tuple[dict, dict[str, np.ndarray]]:
    """Split a RenderResult into JSON metadata and named arrays for the item cache."""
    arrays = {name: np.asarray(getattr(result, name)) for name in _RESULT_ARRAYS}
    arrays.update({_MAP_PREFIX + k: np.asarray(v) for k, v in result.maps.items()})
    meta = {"renderer": result.renderer, "seconds": float(result.seconds),
            "params": to_json(result.params)}
    return meta, arrays


def _is_render(data, arrays: dict) -> bool:
    """Whether a cached item holds what ``result_from_arrays`` needs."""
    return isinstance(data, dict) and all(name in arrays for name in _RESULT_ARRAYS)


def result_from_arrays(meta: dict, arrays: dict[str, np.ndarray]) -> RenderResult:
    """The RenderResult that ``result_to_arrays`` split."""
    missing = [name for name in _RESULT_ARRAYS if name not in arrays]
    if missing:
        raise VoxfieldError(f"cached render lacks {', '.join(missing)}")
    maps = {k[len(_MAP_PREFIX):]: v for k, v in arrays.items() if k.startswith(_MAP_PREFIX)}
    return RenderResult(
        *(arrays[name] for name in _RESULT_ARRAYS), seconds=float(meta.get("seconds", 0.0)),
        renderer=str(meta.get("renderer", "")), params=dict(meta.get("params") or {}), maps=maps,
    )


def compute_item_task(shared, compute, kernel_threads: int | None = None):
    """One study item as a scheduler runs it (module level, so workers can import it)."""
    with thread_count(kernel_threads):
        return compute(shared)


class _as_arrays:
    """``render(shared)`` as an item's (data, arrays); a class, not a closure, so it pickles
    by reference to this module."""

    def __init__(self, render: Callable) -> None:
        self.render = render

    def __call__(self, shared):
        return result_to_arrays(self.render(shared))


class _as_value:
    def __init__(self, compute: Callable) -> None:
        self.compute = compute

    def __call__(self, shared):
        return self.compute(shared), {}


#: Where a run's report files wait until ``publish_report`` moves them into the folder.
STAGING = ".report-in-progress"

#: The report files every study writes, whatever it studies.
REPORT_FILES = ("results.json", "results.md", REPORT_NAME)

class StudyFolder:
    """The folder a study writes; ``computed`` and ``reused`` name the items of this run.

    ``study`` names the command that writes it (``"study thresholds"``, ``"sweep"``): a
    folder holds one study, and another is refused before its work, since its report would
    show the first one's figures beside its own tables."""

    def __init__(self, root: str | Path, *, study: str, fresh: bool = False, scheduler=None):
        self.root = Path(root)
        if self.root.exists() and not self.root.is_dir():
            raise VoxfieldError(f"study output {self.root} exists and is not a folder")
        self.study = study
        if (self.root / PROBE_SET_HEADER).exists():
            raise VoxfieldError(f"{self.root} holds a probe set ({PROBE_SET_HEADER}); give "
                                f"`voxfield {study}` another --out")
        #: The study the folder's mark names (None: none yet); claimed at the first output.
        self._held = self._held_study()
        # A folder that cannot be written fails now, not at the first output after the work.
        check_writable(self.root / STUDY_MARK)
        if self._held is not None and self._held != study:
            raise VoxfieldError(f"{self.root} holds the results of `voxfield {self._held}`; "
                                f"give `voxfield {study}` another --out (one study per folder)")
        self.items_dir = self.root / "items"
        self._check_outputs()
        check_scheduler(scheduler)
        # One job writes a folder at a time (``folder_lock``): one that exists is claimed
        # now, before any work; a new one as it is made. The claim ends with this object.
        self._lock = FolderLock(self.root, f"voxfield {study}")
        self._lock.take()
        weakref.finalize(self, self._lock.release)
        self.fresh = fresh
        #: Where ``batch`` runs independent items (``voxfield.scaleout``; None: one after
        #: another here, each on every core).
        self.scheduler = scheduler
        self.computed: list[str] = []
        self.reused: list[str] = []
        self._written: set[Path] = set()  # items this run wrote (trusted even when fresh)
        self._staged: set[str] = set()  # report files of this run, not yet published

    def _check_outputs(self) -> None:
        """Refuse now, as ``check_writable`` does any output, what met the outputs only
        after the work: a folder named like a report file or figure, which
        ``publish_report`` cannot replace (every render ran, then the study failed), or a
        file where the item cache or the staging folder goes (the first item failed once
        computed)."""
        if not self.root.is_dir():
            return  # made by the first output: nothing in it can be in the way
        for name in (*REPORT_FILES, *STUDY_FIGURES.get(self.study, ())):
            check_writable(self.root / name)
        check_writable(self.items_dir / "item.json")
        check_writable(self.root / STAGING / REPORT_NAME)

    def path(self, name: str) -> Path:
        """Where report file ``name`` lies once published."""
        return self.root / name

    def _mark(self) -> dict:
        """The folder's mark (``read_study_mark``); a folder whose mark cannot be read is
        claimed anew."""
        return read_study_mark(self.root)

    def _held_study(self) -> str | None:
        """The study named in the folder's mark; None where there is none."""
        held = self._mark().get("study")
        return held if isinstance(held, str) else None

    def _claim(self) -> None:
        """The mark written before the folder's first output of this run."""
        self._lock.take(make=True)
        if self._held != self.study:
            self._write_json_file(self.root / STUDY_MARK, {"study": self.study})
            self._held = self.study

    def _published(self) -> set[str]:
        """The report files the mark lists: those of the last published report (and, after
        a publish that was stopped, those of the one before)."""
        names = self._mark().get("report")
        if not isinstance(names, list):
            return set()
        # Plain names only: the mark never makes a publish remove a file outside the folder.
        return {n for n in names if isinstance(n, str) and n == Path(n).name
                and n not in ("", ".", "..", STUDY_MARK, STAGING, "items")}

    def _stage(self, name: str) -> Path:
        """Where this run writes report file ``name`` until ``publish_report``; the first
        call clears what a stopped run left staged."""
        self._claim()
        staging = self.root / STAGING
        if not self._staged:
            shutil.rmtree(staging, ignore_errors=True)
        staging.mkdir(parents=True, exist_ok=True)
        self._staged.add(name)
        return staging / name

    # --- cached items -------------------------------------------------------------------------

    def item(
        self, name: str, params: dict,
        compute: Callable[[], tuple[dict, dict[str, np.ndarray]]], *,
        valid: Callable[[object, dict], bool] | None = None,
    ) -> tuple[dict, dict[str, np.ndarray]]:
        """``compute()``'s (JSON data, arrays), or the cached copy from an earlier run with the
        same ``params``; a cache file that cannot be read, or whose (data, arrays) ``valid``
        refuses, is recomputed, not trusted."""
        cached = self._cached(name, params, valid)
        if cached is not None:
            self.reused.append(name)
            return cached
        return self._store(name, params, *compute())

    def _paths(self, name: str, params: dict) -> tuple[Path, Path]:
        stem = self.items_dir / f"{name}-{params_key({'item': name, **params})}"
        # Not with_suffix: item names may hold dots (thresholds like 0.154).
        return Path(f"{stem}.json"), Path(f"{stem}.npz")

    def _cached(self, name: str, params: dict, valid=None):
        json_path, npz_path = self._paths(name, params)
        if (not self.fresh or json_path in self._written) and json_path.is_file():
            cached = self._load(json_path, npz_path)
            if cached is not None and (valid is None or valid(*cached)):
                return cached
        return None

    def _store(self, name: str, params: dict, data, arrays) -> tuple[dict, dict]:
        self._claim()
        json_path, npz_path = self._paths(name, params)
        if arrays:
            with atomic_path(npz_path) as tmp:
                np.savez_compressed(tmp, **arrays)
        record = to_json({"item": name, "params": params, "data": data,
                          "arrays": sorted(arrays)})
        self._write_json_file(json_path, {**record, "digest": _record_digest(record)})
        self._written.add(json_path)
        self.computed.append(name)
        return record["data"], dict(arrays)

    def batch(self, specs: Sequence[tuple[str, dict, Callable]], *, shared=None,
              bar=None, valid: Callable[[object, dict], bool] | None = None,
              ) -> list[tuple[dict, dict[str, np.ndarray]]]:
        """``item`` for independent items at once: each spec is (name, params,
        ``compute(shared)`` → (JSON data, arrays)). Cached items are read back; the missing
        ones run as tasks on ``self.scheduler`` (``shared`` is scattered to a cluster once,
        ``compute`` must be picklable by cloudpickle there) and each is cached the moment it
        lands, so an interrupted batch resumes. Results come back in spec order; ``bar``
        (a progress bar) advances once per item; ``valid`` as in ``item``."""
        results: list = [None] * len(specs)
        missing = []
        for k, (name, params, _) in enumerate(specs):
            cached = self._cached(name, params, valid)
            if cached is None:
                missing.append(k)
                continue
            self.reused.append(name)
            results[k] = cached
            if bar is not None:
                bar.update(1)

        def land(j: int, value) -> None:
            name, params, _ = specs[missing[j]]
            results[missing[j]] = self._store(name, params, *value)
            if bar is not None:
                bar.update(1)

        run_tasks(compute_item_task, shared, [specs[k][2] for k in missing], land,
                  scheduler=self.scheduler or "serial", name="item", resumes=True)
        return results

    def render_batch(self, specs, *, shared=None, bar=None) -> list[RenderResult]:
        """``batch`` of renders: ``render(shared)`` → RenderResult per spec."""
        wrapped = [(name, params, _as_arrays(render)) for name, params, render in specs]
        return [result_from_arrays(meta, arrays)
                for meta, arrays in self.batch(wrapped, shared=shared, bar=bar,
                                               valid=_is_render)]

    def value_batch(self, specs, *, shared=None, bar=None) -> list[dict]:
        """``batch`` of JSON-only results: ``compute(shared)`` → dict per spec."""
        wrapped = [(name, params, _as_value(compute)) for name, params, compute in specs]
        return [data for data, _ in self.batch(wrapped, shared=shared, bar=bar)]

    def render_item(self, name: str, params: dict, render: Callable[[], RenderResult]
                    ) -> RenderResult:
        """A render, cached like ``item``."""
        meta, arrays = self.item(name, params, lambda: result_to_arrays(render()),
                                 valid=_is_render)
        return result_from_arrays(meta, arrays)

    def value_item(self, name: str, params: dict, compute: Callable[[], dict]) -> dict:
        """A JSON-only result (e.g. metrics), cached like ``item``."""
        data, _ = self.item(name, params, lambda: (compute(), {}))
        return data

    @staticmethod
    def _load(json_path: Path, npz_path: Path):
        """The cached (data, arrays), or None for a file ``_store`` did not write (empty,
        truncated, damaged, edited, or JSON of another shape): such an item is recomputed."""
        try:
            record = json.loads(json_path.read_text())
            if not isinstance(record, dict) or "data" not in record:
                return None
            digest = record.pop("digest", None)
            if digest != _record_digest(record):
                return None
            names = record.get("arrays") or []
            if not isinstance(names, list) or not all(isinstance(k, str) for k in names):
                return None
            arrays = {}
            if names:
                with load_arrays(npz_path) as npz:
                    arrays = {k: npz[k] for k in names}
            return record["data"], arrays
        except (OSError, ValueError, KeyError, TypeError, EOFError, RecursionError,
                zipfile.BadZipFile, zlib.error):
            return None

    # --- outputs ------------------------------------------------------------------------------

    # The writers below stage a report file and return where it lies once published.

    def write_json(self, name: str, data) -> Path:
        self._write_json_file(self._stage(name), data)
        return self.path(name)

    def write_text(self, name: str, text: str) -> Path:
        with atomic_path(self._stage(name)) as tmp:
            tmp.write_text(text, encoding="utf-8")
        return self.path(name)

    def write_png(self, name: str, image: np.ndarray, *, encode_srgb: bool = True) -> Path:
        """A linear image as sRGB PNG (``encode_srgb=False`` for maps that are already grey
        levels or colours)."""
        save_png(image, self._stage(name), encode_srgb=encode_srgb)
        return self.path(name)

    def write_figure(self, name: str, figure, *, dpi: int = 100) -> Path:
        """A matplotlib Figure as PNG; the figure is closed (pyplot keeps every open one)."""
        try:
            save_figure(figure, self._stage(name), dpi=dpi)
            return self.path(name)
        finally:
            import matplotlib.pyplot as plt  # heavy: loaded already by whoever drew the figure

            plt.close(figure)

    def publish_report(self) -> Path:
        """Build ``report.html`` from this run's staged files alone and move them all into
        the folder, the page last; the files of the report before that this run did not
        write again are removed (the page would show a stale figure as this run's).
        Until then the folder shows the earlier report whole; returns the page's path."""
        staging = self.root / STAGING
        write_html_report(staging)
        new = sorted(self._staged | {REPORT_NAME})
        stale = self._published() - set(new)
        # The mark lists both reports while they are swapped: a stopped swap is undone next.
        self._write_json_file(self.root / STUDY_MARK, {"study": self.study,
                                                       "report": sorted(stale | set(new))})
        (self.root / REPORT_NAME).unlink(missing_ok=True)  # no page while tables change
        for name in new:
            if name != REPORT_NAME:
                os.replace(staging / name, self.root / name)
        for name in stale:
            if not (self.root / name).is_dir():
                (self.root / name).unlink(missing_ok=True)
        os.replace(staging / REPORT_NAME, self.root / REPORT_NAME)
        self._write_json_file(self.root / STUDY_MARK, {"study": self.study, "report": new})
        shutil.rmtree(staging, ignore_errors=True)
        self._staged.clear()
        return self.root / REPORT_NAME

    @staticmethod
    def _write_json_file(path: Path, data) -> None:
        with atomic_path(path) as tmp:
            tmp.write_text(json_text(data) + "\n")


def markdown_table(headers: Sequence[str], rows: Sequence[Sequence], *,
                   align: str | None = None) -> str:
    """A GitHub Markdown table; ``align`` is one of ``l``/``r`` per column (default: first
    column left, the rest right)."""
    align = align or "l" + "r" * (len(headers) - 1)
    if len(align) != len(headers) or any(len(r) != len(headers) for r in rows):
        raise ValueError("every row and the alignment need one entry per header")
    rule = ["---:" if a == "r" else "---" for a in align]
    lines = [headers, rule, *[[str(c) for c in r] for r in rows]]
    return "\n".join("| " + " | ".join(line) + " |" for line in lines) + "\n"


def fmt(value, spec: str = ",") -> str:
    """One table cell: ``—`` for missing values, ``∞`` for infinite ones, else ``format``."""
    if value is None:
        return "—"
    if isinstance(value, float) and math.isinf(value):
        return "∞" if value > 0 else "−∞"
    if isinstance(value, float) and math.isnan(value):
        return "—"
    return format(value, spec)


def scene_title(scene: str) -> str:
    """A scene description as figure titles name it: a file (or ``dem:`` file) by its name,
    built-in scenes and terrain recipes as given. A full path says nothing a reader of the
    figure needs and wraps across it; ``results.json`` keeps the description whole."""
    prefix, colon, rest = scene.partition(":")
    if colon and prefix in ("builtin", "terrain"):
        return scene
    if colon and prefix == "dem":
        return f"dem:{Path(rest).name or rest}"
    return Path(scene).name or scene


def scene_record_title(scene: dict) -> str:
    """``scene_title`` of a study's scene record (``compare``, ``shadows``): of the
    description the scene was opened from where the record keeps it, else of the octree's
    name (a study run from the library on an octree it was handed)."""
    return scene_title(scene.get("description") or scene["name"])


def fmt_psnr(quality: dict | None, spec: str = ".2f") -> str:
    """A PSNR cell of a measured image: ``∞`` where it equals the reference (JSON keeps that
    infinity as null, which ``fmt`` would show as missing), ``—`` where nothing was
    compared (no quality, or none with a PSNR: the reference's own row)."""
    if not isinstance(quality, dict) or "psnr" not in quality:
        return "—"
    return psnr_text(quality["psnr"], spec)


def costs(result) -> dict:
    """``rays`` (all cast, discarded included), ``rays_hit_pixels`` (rays of pixels that hit
    geometry), ``steps`` (traversal steps) and ``rays_per_pixel`` (all cast / pixels)."""
    hit = result.hit_count > 0
    pixels = result.ray_count.size
    return {"rays": result.total_rays, "rays_hit_pixels": int(result.ray_count[hit].sum()),
            "steps": result.total_steps, "rays_per_pixel": result.total_rays / pixels}


def costs_and_quality(reference, result) -> dict:
    """``costs`` plus PSNR/RMSE/SSIM/FLIP against the reference (linear RGB)."""
    return {**costs(result), **compare_images(reference.image, result.image)}
