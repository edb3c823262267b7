"""The probe thesis's analysis (ch. 9) as a study: quality, cost and failures of rendering a
view from baked probes, against tracing the same view through the octree.

Five sections, each a table in ``results.md`` and most a plot:

1. **Quality** — PSNR/SSIM/RMSE of the light-field, environment-map and box-proxy renders
   against ``render_lod(octree, camera, lod=0)``: one LOD-0 ray per pixel centre, the very rays
   the probe render answers, so differences are the probes' doing, not sampling.
2. **Resolution** — texel fetches per pixel of each marcher as the probe maps grow. The thesis
   (§9.1) bounds a trace by the ray's length in texture space: ``O(√r)`` texels for the DDA,
   ``O(log r)`` for the hierarchical trace, ``r`` the texels per map (``R²``). We fit the
   growth exponent (slope of log fetches against log r) per marcher.
3. **Probe count** — failures (rays every probe lost: ``UNKNOWN``/``FALLBACK``) and fetches as
   the grid gets denser; the thesis argues cost *falls* with density, as some probe of the cage
   sees the ray nearly end-on.
4. **Ordering** — how often the first probe of the cage answers the ray (``HIT`` or ``MISS``
   with one probe tried), per first-probe heuristic.
5. **Wall time** — the probe render against direct octree tracing of the same view, both warmed
   up first so compilation is excluded.

Runs resume through ``StudyFolder``: every measurement is an item keyed by its parameters and
the scene's fingerprint. Bakes are not stored (a 4×4×4 grid at 512² is ~250 MB); a re-run bakes
only what a missing item needs, and a finished study re-runs without baking at all.
"""

from __future__ import annotations

import math
import re
import time
import warnings
from collections.abc import Sequence
from dataclasses import asdict, replace
from pathlib import Path

import numpy as np

from voxfield.checks import is_integer
from voxfield.errors import VoxfieldError
from voxfield.lightfield.accuracy import depth_agreement, perfect_trace_image
from voxfield.lightfield.packed import PackedProbes
from voxfield.lightfield.probe_render import (
    lost_rays_note,
    lost_share_of,
    render_from_probes,
    result_kinds,
)
from voxfield.lightfield.trace import MARCHERS as KNOWN_MARCHERS
from voxfield.lightfield.trace import ORDERINGS as KNOWN_ORDERINGS
from voxfield.lightfield.trace import checked_options
from voxfield.metrics import compare_images
from voxfield.probes.bake import bake_probes, warm_up
from voxfield.probes.distributed import bake_probes_dask
from voxfield.probes.folder_bake import check_finish_memory
from voxfield.probes.grid import (
    DEFAULT_CLEARANCE_FRACTION,
    ProbeGrid,
    placement_problem,
    relocate,
    surface_layer,
    surface_spec,
)
from voxfield.probes.probe_set import MAX_RESOLUTION, MIN_RESOLUTION, BakeOptions
from voxfield.progress import progress_bar
from voxfield.render.camera import Camera
from voxfield.render.primary import render_lod
from voxfield.studies.probe_study_figures import (
    contact_sheet_figure,
    count_figure,
    ordering_figure,
    resolution_figure,
)
from voxfield.studies.report import (
    StudyFolder,
    fmt,
    fmt_psnr,
    markdown_table,
)

#: Map sides of the resolution section (the issue's 64² … 1024²).
THESIS_RESOLUTIONS = (64, 128, 256, 512, 1024)
#: Probe grids of the probe-count section, sparse to dense.
DEFAULT_PROBE_COUNTS = ("1x1x1", "2x2x2", "3x3x3", "4x4x4")
ORDERINGS = ("signed-dot", "nearest", "fixed")
MARCHERS = ("march3d", "dda", "hierarchical")
QUALITY_METHODS = ("light-field", "environment", "box-proxy")
#: Largest map side the probe-count and ordering sections bake by default: they bake up to
#: dozens of probes, and cost trends need no 1024² maps.
COUNT_RESOLUTION_CAP = 256
#: Section 3 says when a grid's perfect-trace bound stays below this: its maps are too coarse
#: for the view, so its failures and PSNR say little about the trace.
BOUND_FLOOR_DB = 30.0
#: Relocation keeps probes at least this far (voxels) from surfaces, or the grid default (a
#: fifth of the spacing) when that is smaller: a lone probe's default would be a fifth of the
#: scene, which no probe in a cluttered scene can reach.
RELOCATION_CLEARANCE = 4.0
#: The thesis's claimed growth of fetches per pixel with r = R² texels (exponent of r).
THESIS_CLAIMS = {"march3d": "no bound (fixed world step)", "dda": "O(√r): exponent 0.5",
                 "hierarchical": "O(log r): exponent → 0"}


def run_probe_study(
    octree, out_dir: str | Path, *, scene_name: str = "scene", camera: Camera,
    grid_counts: Sequence[int] | str = (1, 1, 1),
    resolutions: Sequence[int] = THESIS_RESOLUTIONS,
    probe_counts: Sequence[Sequence[int] | str] = DEFAULT_PROBE_COUNTS,
    orderings: Sequence[str] = ORDERINGS, marchers: Sequence[str] = MARCHERS,
    count_resolution: int | None = None, options=None, relocate_probes: bool = True,
    channel: str = "albedo", timing_repeats: int = 3, seed: int = 0, progress: bool = False,
    fresh: bool = False, scheduler=None,
) -> dict:
    """Run the five sections on one scene and view (resumable); write results.json,
    results.md, the plots and contact_sheet.png into ``out_dir``; return the report.

    ``grid_counts`` is the main grid (sections 1, 2 and 5) and ``probe_counts`` the grids of
    sections 3 and 4, baked at ``count_resolution`` (default: the largest of ``resolutions``
    up to 256). A grid is probes per axis fitted to the scene's voxel box (``(2, 2, 2)`` or
    ``"2x2x2"``), or ``"surface:NXxNZ@H"``: one layer H voxels above a terrain's surface
    (``probes.grid.surface_layer``). Section 1 uses the largest resolution.
    ``options`` (``LightFieldOptions``) sets epsilon, backface and fallback; the marcher and
    ordering are varied by the study (the options' own are the defaults elsewhere). With
    ``relocate_probes`` probes are moved out of geometry (``probes.grid.relocate``) first.
    """

    options = checked_options(options)
    plan = _checked_plan(camera, grid_counts, resolutions, probe_counts, orderings, marchers,
                         count_resolution, timing_repeats)
    folder = StudyFolder(out_dir, study="study probes", fresh=fresh, scheduler=scheduler)
    study = _Study(octree, camera, folder, options, channel=channel, seed=seed,
                   relocate_probes=relocate_probes, scene_name=scene_name)
    main = plan["grid"]
    quality_r = max(plan["resolutions"])
    count_r = plan["count_resolution"]
    total = (len(plan["resolutions"]) * len(plan["marchers"]) + len(QUALITY_METHODS)
             + len(plan["probe_counts"]) * (len(plan["marchers"]) + len(plan["orderings"])))
    with progress_bar(total=total, desc="probe study", unit="item", enabled=progress) as bar:
        # every grid checked (and relocated) before any render: one with nothing to bake is
        # refused before the octree's reference render, not after it
        for spec in dict.fromkeys((main, *plan["probe_counts"])):
            study.describe_grid(spec)
        reference = study.reference()
        resolution_rows = []
        quality_rows = []
        timing = None
        for r in plan["resolutions"]:
            row = {"resolution": r, "bake": study.bake_cost(main, r), "marchers": {}}
            for marcher in plan["marchers"]:
                row["marchers"][marcher] = study.measure(main, r, "light-field",
                                                         marcher=marcher)
                bar.update(1)
            resolution_rows.append(row)
            if r == quality_r:
                for method in QUALITY_METHODS:
                    quality_rows.append({"method": method, **study.measure(
                        main, r, method, keep_render=True)})
                    bar.update(1)
                timing = study.timing(main, r, plan["marchers"], timing_repeats)
        count_rows = []
        for spec in plan["probe_counts"]:
            row = {"grid": spec, "probes": study.describe_grid(spec)["probes"],
                   "bake": study.bake_cost(spec, count_r), "marchers": {}, "orderings": {}}
            for marcher in plan["marchers"]:
                row["marchers"][marcher] = study.measure(spec, count_r, "light-field",
                                                         marcher=marcher)
                bar.update(1)
            for ordering in plan["orderings"]:
                row["orderings"][ordering] = study.measure(spec, count_r, "light-field",
                                                           ordering=ordering)
                bar.update(1)
            count_rows.append(row)
    study.drop_bake()
    lost_note = study_lost_note(quality_rows, main, fallback=options.fallback)
    notes = [] if lost_note is None else [lost_note]
    for note in notes:
        warnings.warn(note, UserWarning, stacklevel=2)

    report = {
        "study": "probes", "scene": scene_name, "width": camera.width, "height": camera.height,
        "camera": camera.params.tolist(), "grid": main, "seed": seed, "channel": channel,
        "options": _options_dict(options), "relocated": relocate_probes,
        "quality_resolution": quality_r, "count_resolution": count_r,
        "reference": {"renderer": "render_lod(lod=0): one LOD-0 ray per pixel centre",
                      "hit_fraction": float(np.mean(reference.hit_count > 0))},
        "quality": quality_rows, "resolution": resolution_rows,
        "growth": growth_fits(resolution_rows, plan["marchers"]),
        "probe_count": count_rows, "timing": timing,
        "grids": study.grid_notes, "notes": notes, "metrics_on": "linear RGB in [0, 1]",
        "items": {"computed": len(folder.computed), "reused": len(folder.reused)},
    }

    folder.write_json("results.json", report)
    folder.write_text("results.md", results_markdown(report))
    folder.write_figure("fetches_vs_resolution.png", resolution_figure(report))
    folder.write_figure("probe_count.png", count_figure(report))
    folder.write_figure("orderings.png", ordering_figure(report))
    folder.write_figure("contact_sheet.png", contact_sheet_figure(
        report, reference, study.kept), dpi=int(min(160, max(90, camera.width / 3))))
    folder.publish_report()
    return report


def study_lost_note(quality_rows: list[dict], grid: str, *,
                    fallback: bool = True) -> str | None:
    """``lost_rays_note`` for section 1's light-field render, with what to do about it."""
    row = next(q for q in quality_rows if q["method"] == "light-field")
    note = lost_rays_note(lost_share_of(row["failures"], row["miss"]), f"the {grid} grid",
                          fallback=fallback)
    return None if note is None else (
        f"{note}, and so do section 1's light-field figures; see contact_sheet.png, and place "
        "the camera where the probes see (--eye/--target) or use a denser --grid")


# --------------------------------------------------------------------------- checks


def _checked_plan(camera, grid_counts, resolutions, probe_counts, orderings, marchers,
                  count_resolution, timing_repeats) -> dict:
    """The study's parameters, validated, as plain tuples; bad ones raise VoxfieldError."""
    if not isinstance(camera, Camera):
        raise VoxfieldError(f"camera must be a voxfield Camera, got {type(camera).__name__}")
    resolutions = tuple(sorted(set(_positive_ints(resolutions, "probe resolutions"))))
    for r in resolutions:
        if not MIN_RESOLUTION <= r <= MAX_RESOLUTION:
            raise VoxfieldError(f"probe resolution {r} is outside {MIN_RESOLUTION}.."
                                f"{MAX_RESOLUTION}")
    if len(resolutions) < 2:
        raise VoxfieldError("the resolution section needs at least two probe resolutions to "
                            "fit a growth rate")
    if count_resolution is None:
        capped = [r for r in resolutions if r <= COUNT_RESOLUTION_CAP]
        count_resolution = max(capped) if capped else resolutions[0]
    elif not (is_integer(count_resolution)
              and MIN_RESOLUTION <= count_resolution <= MAX_RESOLUTION):
        raise VoxfieldError(f"count resolution must be a map side in {MIN_RESOLUTION}.."
                            f"{MAX_RESOLUTION}, got {count_resolution!r}")
    if isinstance(probe_counts, str):
        raise VoxfieldError("give the probe-count section a list of grids")
    specs = [grid_spec(c) for c in probe_counts]
    if not specs:
        raise VoxfieldError("give at least one probe grid for the probe-count section")
    for name, values, known in (("ordering", orderings, KNOWN_ORDERINGS),
                                ("marcher", marchers, KNOWN_MARCHERS)):
        if isinstance(values, str) or not values:
            raise VoxfieldError(f"give a list of at least one {name}")
        for v in values:
            if v not in known:
                raise VoxfieldError(f"unknown {name} {v!r}; choose from {', '.join(known)}")
    if not is_integer(timing_repeats) or timing_repeats < 1:
        raise VoxfieldError(f"timing repeats must be an integer >= 1, got {timing_repeats!r}")
    grid = grid_spec(grid_counts)
    # Before any bake, as ``bake`` refuses it: a 200³ probe-count grid baked until the
    # machine killed the study for memory, without a word.
    check_finish_memory(_probes_in(grid), max(resolutions))
    for spec in specs:
        check_finish_memory(_probes_in(spec), int(count_resolution))
    return {"grid": grid, "resolutions": resolutions,
            "probe_counts": tuple(dict.fromkeys(specs)), "orderings": tuple(orderings),
            "marchers": tuple(marchers), "count_resolution": int(count_resolution)}


def _probes_in(spec: str) -> int:
    """How many probes the grid ``grid_spec`` names: NX·NY·NZ, or NX·NZ in one layer."""
    surface = surface_spec(spec)
    if surface is not None:
        (nx, nz), _ = surface
        return nx * nz
    return math.prod(_grid_counts(spec))


def _positive_ints(values, what: str) -> list[int]:
    try:
        out = [int(v) for v in values]
        exact = all(int(v) == v for v in values)
    except (TypeError, ValueError):
        raise VoxfieldError(f"{what} must be whole numbers, got {values!r}") from None
    if not out or not exact or any(v < 1 for v in out):
        raise VoxfieldError(f"{what} must be whole numbers >= 1, got {values!r}")
    return out


def grid_spec(value) -> str:
    """A study grid's canonical name: ``"NXxNYxNZ"`` (probes per axis, fitted to the scene's
    box) from that text, ``(nx, ny, nz)`` or ``n``; or ``"surface:NXxNZ@H"``."""
    if isinstance(value, str):
        surface = surface_spec(value)
        if surface is not None:
            (nx, nz), height = surface
            return f"surface:{nx}x{nz}@{height:g}"
    return "x".join(map(str, _grid_counts(value)))


def _grid_counts(value) -> tuple[int, int, int]:
    """Probes per axis from ``(nx, ny, nz)``, ``"NXxNYxNZ"`` or a single ``n`` (n per axis)."""
    if isinstance(value, str):
        return parse_counts(value)
    if is_integer(value):
        value = (value,) * 3
    counts = _positive_ints(value, "probe counts")
    if len(counts) != 3:
        raise VoxfieldError(f"probe counts need three numbers (x, y, z), got {value!r}")
    return tuple(counts)


_COUNTS = re.compile(r"^\s*(\d+)\s*(?:[x×]\s*(\d+)\s*[x×]\s*(\d+))?\s*$", re.IGNORECASE)


def parse_counts(text: str) -> tuple[int, int, int]:
    """``"4x1x4"`` → (4, 1, 4); ``"3"`` → (3, 3, 3)."""
    match = _COUNTS.match(text)
    if not match:
        raise VoxfieldError(f"cannot read probe counts {text!r}; give NXxNYxNZ like 4x1x4")
    nx, ny, nz = match.groups()
    counts = (int(nx),) * 3 if ny is None else (int(nx), int(ny), int(nz))
    if min(counts) < 1:
        raise VoxfieldError(f"probe counts must be >= 1, got {text!r}")
    return counts


# --------------------------------------------------------------------------- measuring


class _Study:
    """Bakes (one kept in memory at a time), renders and cached measurements of one view."""

    def __init__(self, octree, camera, folder: StudyFolder, options, *, channel: str,
                 seed: int, relocate_probes: bool, scene_name: str):
        self.octree = octree
        self.camera = camera
        self.folder = folder
        self.options = options
        self.channel = channel
        self.seed = seed
        self.relocate_probes = relocate_probes
        self._relocation = f"clearance<={RELOCATION_CLEARANCE}" if relocate_probes else False
        self.view = {"scene": scene_name, "fingerprint": octree.fingerprint(channel),
                     "camera": camera.params.tolist(), "width": camera.width,
                     "height": camera.height, "seed": seed, "channel": channel}
        self.grid_notes: dict[str, dict] = {}
        self.kept: dict[str, object] = {}
        self._bake_key = None
        self._bake = None
        self._reference = None

    # --- probes -------------------------------------------------------------------------

    def grid(self, spec: str):
        """The grid ``spec`` names (``grid_spec``) on this scene, relocated out of geometry if
        asked."""
        surface = surface_spec(spec)
        if surface is not None:
            grid = surface_layer(self.octree, *surface)
        else:
            lo, hi = self.octree.voxel_bounds
            grid = ProbeGrid.fit(lo, hi, parse_counts(spec))
        summary = None
        if self.relocate_probes:
            clearance = min(RELOCATION_CLEARANCE,
                            DEFAULT_CLEARANCE_FRACTION * float(grid.spacing.min()))
            grid, moved = relocate(grid, self.octree, clearance=clearance, seed=self.seed)
            summary = moved.summary()
        problem, nothing_to_bake = placement_problem(
            grid, self.octree, relocated=self.relocate_probes,
            relocate_with="leaving out --no-relocate")
        if nothing_to_bake:  # the rule bake and probe-resolution refuse by
            raise VoxfieldError(f"the {spec} grid: {problem}")
        return grid, summary

    def describe_grid(self, spec: str) -> dict:
        """Probes, enabled probes and what relocation did, for the report (cached)."""
        def compute() -> dict:
            grid, summary = self.grid(spec)
            return {"probes": grid.count, "enabled": int(np.count_nonzero(grid.enabled)),
                    "positions": np.asarray(grid.positions)[np.asarray(grid.enabled)].tolist(),
                    "relocation": summary}

        note = self.folder.value_item("grid", {**self.view, "grid": spec,
                                               "relocate": self._relocation}, compute)
        self.grid_notes[spec] = note
        return note

    def probe_set(self, spec: str, resolution: int):
        """The baked probe set and its packed maps; the last bake is kept for reuse."""
        key = (spec, int(resolution))
        if self._bake_key != key:
            self.drop_bake()
            grid, _ = self.grid(spec)
            bake = BakeOptions(resolution=int(resolution), renderer="lod", lod=0,
                               channel=self.channel, seed=self.seed)
            if self.folder.scheduler in (None, "serial"):  # the bake's seconds, warm
                warm_up(self.octree, grid.positions[0], bake)
            start = time.perf_counter()
            if self.folder.scheduler in (None, "serial"):
                probe_set = bake_probes(self.octree, grid, bake)
            else:  # the probes as tasks: the same maps (``probes.distributed``)
                probe_set = bake_probes_dask(self.octree, grid, bake,
                                             scheduler=self.folder.scheduler)
            seconds = time.perf_counter() - start
            self._bake = (probe_set, PackedProbes.from_probe_set(probe_set), seconds)
            self._bake_key = key
        return self._bake

    def drop_bake(self) -> None:
        self._bake_key = None
        self._bake = None

    def _params(self, spec: str, resolution: int, **extra) -> dict:
        return {**self.view, "grid": spec, "resolution": int(resolution),
                "relocate": self._relocation, "bake": "lod0", **extra}

    def bake_cost(self, spec, resolution: int) -> dict:
        """Probes baked, texels, rays and seconds of one bake (renderer ``lod`` at LOD 0)."""
        def compute() -> dict:
            probe_set, _, seconds = self.probe_set(spec, resolution)
            cost = probe_set.cost_summary()
            return {"probes": int(np.count_nonzero(probe_set.enabled)),
                    "texels_per_probe": int(resolution) ** 2, "seconds": seconds,
                    "rays": cost.get("rays"), "steps": cost.get("steps")}

        # The bake's seconds depend on where it ran: a scheduled bake is its own item.
        scheduler = self.folder.scheduler
        where = {} if scheduler in (None, "serial") else {"scheduler": str(scheduler)}
        return self.folder.value_item("bake", self._params(spec, resolution, **where),
                                      compute)

    # --- renders --------------------------------------------------------------------------

    def reference(self):
        """The direct octree render of the same rays: one LOD-0 ray per pixel centre."""
        if self._reference is None:
            self._reference = self.folder.render_item("reference", self.view, lambda: render_lod(
                self.octree, self.camera, lod=0, seed=self.seed, channel=self.channel))
        return self._reference

    def _render(self, spec, resolution, method, options):

        probe_set, packed, _ = self.probe_set(spec, resolution)
        if method == "light-field":
            return render_from_probes(probe_set, self.camera, method=method, options=options,
                                      packed=packed, seed=self.seed)
        return render_from_probes(probe_set, self.camera, method=method, seed=self.seed)

    def measure(self, spec, resolution: int, method: str, *, marcher: str | None = None,
                ordering: str | None = None, keep_render: bool = False) -> dict:
        """Quality and cost of one probe render; ``keep_render`` also caches its image and
        maps for the contact sheet."""
        options = None
        extra: dict = {"method": method}
        if method == "light-field":
            options = replace(self.options, marcher=marcher or self.options.marcher,
                              ordering=ordering or self.options.ordering)
            extra["options"] = _options_dict(options)
        params = self._params(spec, resolution, **extra)
        name = f"{method}-{_item_name(spec)}-r{resolution}"
        if keep_render:
            result = self.folder.render_item(
                f"render-{name}", params,
                lambda: self._render(spec, resolution, method, options))
            self.kept[method] = result
            measured = self.folder.value_item(f"measure-{name}", params,
                                              lambda: measurements(self.reference(), result))
        else:
            measured = self.folder.value_item(
                f"measure-{name}", params,
                lambda: measurements(self.reference(),
                                     self._render(spec, resolution, method, options)))
        return {**measured, "bound_psnr": self.bound(spec, resolution)}

    def bound(self, spec, resolution: int) -> float:
        """PSNR of the perfect-trace bound of these probes (``lightfield.accuracy``)."""
        def compute() -> float:
            _, packed, _ = self.probe_set(spec, resolution)
            reference = self.reference()
            image = perfect_trace_image(packed, self.camera, reference.depth,
                                        colour_filter=self.options.colour_filter,
                                        colour_probe=self.options.colour_probe)
            return compare_images(np.clip(reference.image, 0, 1), np.clip(image, 0, 1))["psnr"]

        return self.folder.value_item(f"bound-{_item_name(spec)}-r{resolution}",
                                      self._params(spec, resolution,
                                                   colour_probe=self.options.colour_probe,
                                                   colour_filter=self.options.colour_filter),
                                      compute)

    def timing(self, spec, resolution: int, marchers, repeats: int) -> dict:
        """Warm wall times (the best of ``repeats``) of the direct octree render and of each
        probe render of the same view; compilation is excluded by a first untimed run."""
        params = self._params(spec, resolution, marchers=list(marchers), repeats=repeats,
                              options=_options_dict(self.options))

        def best(render) -> float:
            render()
            return min(render().seconds for _ in range(repeats))

        def compute() -> dict:
            direct = best(lambda: render_lod(self.octree, self.camera, lod=0, seed=self.seed,
                                             channel=self.channel))
            probe: dict = {}
            for marcher in marchers:
                options = replace(self.options, marcher=marcher)
                probe[f"light-field ({marcher})"] = best(
                    lambda o=options: self._render(spec, resolution, "light-field", o))
            for method in QUALITY_METHODS[1:]:
                probe[method] = best(lambda m=method: self._render(spec, resolution, m, None))
            return {"direct": direct, "probe": probe, "repeats": repeats,
                    "pixels": self.camera.width * self.camera.height}

        return self.folder.value_item(f"timing-r{resolution}", params, compute)


def _gap(quality: dict) -> float | None:
    """Bound minus PSNR in dB; None (not ±∞) where either is infinite, fresh or read back
    as null, so a table reads the same from the cache."""
    bound, psnr = quality.get("bound_psnr"), quality.get("psnr")
    if bound is None or psnr is None or not math.isfinite(bound - psnr):
        return None
    return bound - psnr


def _bound_cell(quality: dict) -> str:
    """The perfect-trace bound's PSNR cell: ``∞`` where the bound equals the reference, ``—``
    for a row without one (the baselines)."""
    return fmt_psnr({"psnr": quality["bound_psnr"]}) if "bound_psnr" in quality else "—"


def _item_name(spec: str) -> str:
    """A grid's name as part of an item's file name."""
    return re.sub(r"[^A-Za-z0-9_.-]+", "_", spec)


def measurements(reference, result) -> dict:
    """What every section reads from a probe render: answer kinds as fractions of pixels,
    per-pixel fetches, steps and probes tried, first-probe success, quality, seconds."""
    codes = result_kinds()
    kind = np.asarray(result.maps["result_kind"]).ravel()
    tried = np.asarray(result.maps["probes_tried"]).ravel()
    fetches = np.asarray(result.maps["texel_fetches"], np.float64).ravel()
    n = max(kind.size, 1)
    fractions = {name: float(np.count_nonzero(kind == code)) / n for name, code in codes.items()}
    answered = (kind == codes["hit"]) | (kind == codes["miss"])
    return {
        **fractions,
        "failures": fractions["unknown"] + fractions["fallback"],
        "fetches_per_pixel": float(fetches.mean()),
        "fetches_p95": float(np.percentile(fetches, 95)),
        "fetches_max": float(fetches.max(initial=0)),
        "steps_per_pixel": float(np.asarray(result.steps, np.float64).mean()),
        "probes_tried_per_pixel": float(tried.mean()),
        "first_probe_success": float(np.count_nonzero(answered & (tried == 1))) / n,
        "seconds": float(result.seconds),
        **compare_images(reference.image, result.image),
        "depth": depth_agreement(result.depth, reference.depth),
    }


def growth_fits(rows: list[dict], marchers: Sequence[str]) -> dict:
    """Per marcher: the exponent of fetches per pixel in r = R² texels (least-squares slope of
    log fetches on log r) and the fetches added per doubling of R (slope on log₂ R), the
    second being the log r model's constant."""
    out = {}
    log_r = np.log([row["resolution"] ** 2 for row in rows])
    log2_side = np.log2([row["resolution"] for row in rows])
    for marcher in marchers:
        fetches = np.array([row["marchers"][marcher]["fetches_per_pixel"] for row in rows])
        if np.all(fetches > 0):
            exponent = float(np.polyfit(log_r, np.log(fetches), 1)[0])
        else:
            exponent = None
        out[marcher] = {"exponent_r": exponent,
                        "per_doubling": float(np.polyfit(log2_side, fetches, 1)[0]),
                        "claim": THESIS_CLAIMS.get(marcher, "")}
    return out


def _options_dict(options) -> dict:
    return {k: v for k, v in asdict(options).items()}


# --------------------------------------------------------------------------- report


def _kinds_cells(m: dict) -> list[str]:
    return [fmt(100 * m["hit"], ".1f"), fmt(100 * m["miss"], ".1f"),
            fmt(100 * m["unknown"], ".1f"), fmt(100 * m["fallback"], ".1f")]


def results_markdown(report: dict) -> str:
    """The study's tables as Markdown."""
    o = report["options"]
    grid = report["grid"]
    lines = [
        f"# Probe analysis (probe thesis ch. 9) — {report['scene']}, "
        f"{report['width']}×{report['height']}",
        "",
        f"Main grid {grid} "
        f"{'over the surface' if grid.startswith('surface:') else 'fitted to the voxel box'}"
        f"{', probes relocated out of geometry' if report['relocated'] else ''}. Probes baked "
        "with `BakeOptions(renderer='lod', lod=0)` (one LOD-0 ray per texel centre). Light-field "
        f"options: epsilon {o['epsilon']} (value {o['epsilon_value']}, k {o['epsilon_k']}, "
        f"front {o.get('epsilon_front', 'inf')} texels), hits refined within "
        f"{o.get('refine_window', 0)} texels, consensus "
        f"{'on' if o.get('consensus') else 'off'}, ring {'on' if o.get('ring') else 'off'}, "
        f"backface {'on' if o['backface'] else 'off'}, fallback "
        f"{'on' if o['fallback'] else 'off'}; marcher {o['marcher']} and ordering "
        f"{o['ordering']} unless a table varies them. Reference: {report['reference']['renderer']}"
        " — the same rays the probe render answers. Metrics on linear RGB in [0, 1]. Kinds are "
        "percentages of pixels: hit, miss (a probe proved the ray empty), unknown / fallback "
        "(every probe tried lost the ray; fallback reads the nearest probe as an environment "
        "map).",
        "",
        f"Where this differs from `voxfield bake`: the study bakes with the exact LOD-0 "
        f"renderer (bake's default is {BakeOptions().renderer}) and relocates with a clearance "
        f"of min({RELOCATION_CLEARANCE:g} voxels, {DEFAULT_CLEARANCE_FRACTION:g} × spacing) "
        f"(bake: {DEFAULT_CLEARANCE_FRACTION:g} × spacing), so its maps hold no LOD error and "
        "lone probes can still move.",
        "",
    ]
    for spec, note in report["grids"].items():
        reloc = f"; {note['relocation']}" if note.get("relocation") else ""
        lines.append(f"- grid {spec}: {note['enabled']} of {note['probes']} probes "
                     f"enabled{reloc}")
    lines.append("")

    lines += [f"## 1. Quality against the octree ({report['quality_resolution']}² probes, "
              f"grid {grid})", ""]
    rows = [[q["method"] + (f" ({o['marcher']})" if q["method"] == "light-field" else ""),
             fmt_psnr(q), _bound_cell(q),
             fmt(_gap(q), ".2f"),
             fmt(q["ssim"], ".4f"), fmt(q["rmse"], ".4f"),
             fmt(q.get("depth", {}).get("p99"), ".2f"),
             fmt(None if "depth" not in q else 100 * q["depth"]["within_1"], ".1f"),
             *_kinds_cells(q), fmt(q["fetches_per_pixel"], ".1f")] for q in report["quality"]]
    lines.append(markdown_table(["method", "PSNR (dB)", "bound (dB)", "gap (dB)", "SSIM",
                                 "RMSE", "depth p99", "depth ≤ 1 %", "hit %", "miss %",
                                 "unknown %", "fallback %", "fetches/px"], rows))
    rule = {"footprint": "whose texel is smallest there",
            "parallel": "that sees it most nearly along the ray"}[o.get("colour_probe",
                                                                       "parallel")]
    lines += [f"**Note:** {note}.\n" for note in report.get("notes", [])]
    lines.append("The bound gives every pixel its true hit point and reads the probe "
                 f"{rule} among those that see it, as the trace reads a hit; depth columns "
                 "compare t with the octree's over the pixels it sees (voxels).\n")
    lines.append("The environment and box-proxy baselines answer every ray from the probe "
                 "nearest the ray origin (4 bilinear fetches); their kind is hit where the "
                 "proxy box gave a surface, else environment.\n")

    marchers = list(report["growth"])
    lines += [f"## 2. Texel fetches per pixel as probe resolution grows (grid {grid})", ""]
    rows = []
    for row in report["resolution"]:
        r = row["resolution"]
        cells = [f"{r}²", fmt(row["bake"]["seconds"], ".2f")]
        cells += [fmt(row["marchers"][m]["fetches_per_pixel"], ".1f") for m in marchers]
        cells += [fmt(100 * row["marchers"][m]["failures"], ".1f") for m in marchers]
        cells += [fmt_psnr(row["marchers"][m]) for m in marchers]
        rows.append(cells)
    lines.append(markdown_table(
        ["R", "bake s", *(f"fetches ({m})" for m in marchers),
         *(f"fail % ({m})" for m in marchers), *(f"PSNR ({m})" for m in marchers)], rows))
    rows = [[m, fmt(g["exponent_r"], ".3f"),
             fmt(None if g["exponent_r"] is None else 2 * g["exponent_r"], ".3f"),
             fmt(g["per_doubling"], ".2f"), g["claim"]] for m, g in report["growth"].items()]
    lines.append("Growth fit over the resolutions above: exponent of r = R² texels (log-log "
                 "slope; √r gives 0.5, R² gives 1), the same in R, and fetches added per "
                 "doubling of R (the log r model's slope).\n")
    lines.append(markdown_table(["marcher", "exponent in r", "exponent in R",
                                 "fetches per doubling", "thesis §9.1"], rows, align="lrrrl"))

    lines += [f"## 3. Failures and fetches as probe count grows ({report['count_resolution']}²"
              " probes)", ""]
    rows = []
    for row in report["probe_count"]:
        cells = [row["grid"], str(row["bake"]["probes"])]
        for m in marchers:
            c = row["marchers"][m]
            cells += [fmt(100 * c["failures"], ".1f"), fmt(c["fetches_per_pixel"], ".1f"),
                      fmt(c["probes_tried_per_pixel"], ".2f")]
        cells.append(fmt_psnr(row["marchers"][marchers[-1]]))
        cells.append(_bound_cell(row["marchers"][marchers[-1]]))
        rows.append(cells)
    headers = ["grid", "probes"]
    for m in marchers:
        headers += [f"fail % ({m})", f"fetches ({m})", f"probes tried ({m})"]
    headers += [f"PSNR ({marchers[-1]})", "bound (dB)"]
    lines.append(markdown_table(headers, rows))
    bounds = {row["grid"]: row["marchers"][marchers[-1]].get("bound_psnr")
              for row in report["probe_count"]}
    low = [spec for spec, bound in bounds.items() if bound is not None and bound < BOUND_FLOOR_DB]
    if low:
        lines.append(f"The bound is below {BOUND_FLOOR_DB:g} dB for {', '.join(low)}: at "
                     f"{report['count_resolution']}² the maps themselves cannot show this view "
                     "well, whatever the trace does; a larger --count-resolution raises "
                     "it.\n")

    orderings = list(report["probe_count"][0]["orderings"])
    lines += [f"## 4. First-probe success per ordering ({report['count_resolution']}² probes, "
              f"{o['marcher']})", "",
              "Share of pixels the first probe of the cage answers (hit or miss with one probe "
              "tried); failures and fetches per pixel beside it.", ""]
    rows = []
    for row in report["probe_count"]:
        cells = [row["grid"]]
        cells += [fmt(100 * row["orderings"][k]["first_probe_success"], ".1f")
                  for k in orderings]
        cells += [fmt(100 * row["orderings"][k]["failures"], ".1f") for k in orderings]
        cells += [fmt(row["orderings"][k]["fetches_per_pixel"], ".1f") for k in orderings]
        rows.append(cells)
    lines.append(markdown_table(
        ["grid", *(f"first-probe % ({k})" for k in orderings),
         *(f"fail % ({k})" for k in orderings), *(f"fetches ({k})" for k in orderings)], rows))

    t = report["timing"]
    lines += [f"## 5. Wall time against direct octree tracing ({report['quality_resolution']}² "
              f"probes, grid {grid})", "",
              f"Best of {t['repeats']} warm runs (compilation excluded), {t['pixels']:,} "
              "pixels, one ray per pixel; this machine's cores.", ""]
    rows = [["octree (render_lod, LOD 0)", fmt(1000 * t["direct"], ".1f"),
             fmt(t["pixels"] / t["direct"] / 1e6, ".2f"), "1.00"]]
    rows += [[name, fmt(1000 * s, ".1f"), fmt(t["pixels"] / s / 1e6, ".2f"),
              fmt(s / t["direct"], ".2f")] for name, s in t["probe"].items()]
    lines.append(markdown_table(["renderer", "ms", "Mrays/s", "× octree time"], rows))
    lines += ["## Files", "",
              "- `fetches_vs_resolution.png`: fetches per pixel per marcher against R (log-log) "
              "with √r and log r reference curves; PSNR per R",
              "- `probe_count.png`: failures, fetches and probes tried per pixel against probes",
              "- `orderings.png`: first-probe success per ordering against probes",
              "- `contact_sheet.png`: reference, the three probe renders, result kinds and "
              "fetches per pixel", ""]
    return "\n".join(lines)
