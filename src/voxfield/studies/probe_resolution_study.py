"""Probe bake cost and quality per map resolution (EA §5.5, Tables 5.29–5.30, for probes).

The EA thesis motivates error-aware rendering with low-resolution probe baking (§1.3) and
measures its scaling over image sizes on a top-down view (§5.5). This study asks the same of
probes: at each octahedral resolution, bake the same probes with the reference baker (4×4 CMJ
rays per texel at LOD 0) and with cheaper bakers whose LOD follows the texel-footprint cone
(``lod``, ``adaptive``, ``error-aware``), and compare radiance cost and quality.

Costs are the radiance pass (the renderer's rays, discarded ones included, and traversal
steps); every baker also pays the same exact geometry pass (one LOD-0 ray per texel, for
distance and normal), reported once per resolution. Quality is PSNR/RMSE/SSIM of the stored
float16 radiance against the reference bake's, on linear RGB clipped to [0, 1]; over several
probes RMSE is pooled (root of the mean squared error), PSNR derived from it, SSIM averaged.

Given a ``StudyFolder``, every probe bake is an item of it (maps and cost, keyed by the scene,
position and bake options), so an interrupted study resumes where it stopped and a rerun with
the same options bakes nothing again; the reused bakes keep the seconds they were timed at.
"""

from __future__ import annotations

import dataclasses
import math
import warnings
from collections.abc import Sequence

import numpy as np

from voxfield.error_table.table import THESIS_DECAY, THESIS_THRESHOLD
from voxfield.errors import VoxfieldError
from voxfield.metrics import compare_images
from voxfield.probes.bake import RADIANCE_FIELDS, bake_probe, warm_up
from voxfield.probes.probe_set import MIN_RESOLUTION, BakeCost, BakeOptions, ProbeMaps
from voxfield.progress import progress_bar
from voxfield.studies.report import StudyFolder, fmt, fmt_psnr, markdown_table
from voxfield.svo.octree import Octree

STUDY_RESOLUTIONS = (64, 128, 256)
CHEAP_BAKERS = ("lod", "adaptive", "error-aware")


def probe_resolution_study(
    octree: Octree, positions, resolutions: Sequence[int] = STUDY_RESOLUTIONS, *,
    bakers: Sequence[str] = CHEAP_BAKERS, threshold: float = THESIS_THRESHOLD,
    decay: float = THESIS_DECAY, samples: int = 4, seed: int = 0, channel: str = "albedo",
    threads: int | None = None, scene_name: str = "scene", progress: bool = False,
    folder: StudyFolder | None = None,
) -> dict:
    """Bake the probes at ``positions`` (N, 3) with the reference and each of ``bakers`` at
    every resolution; returns a JSON-friendly report (``rows``: one per resolution and baker,
    the reference's included) that ``probe_resolution_markdown`` formats. With a ``folder``
    each bake is cached there as it finishes and read back on a rerun."""
    positions = np.asarray(positions, np.float64).reshape(-1, 3)
    if len(positions) == 0:
        raise VoxfieldError("the study needs at least one probe position")
    unknown = [b for b in bakers if b not in CHEAP_BAKERS]
    if unknown:
        raise VoxfieldError(f"unknown baker(s) {unknown}; choose from {', '.join(CHEAP_BAKERS)}")
    common = {"channel": channel, "seed": seed, "threshold": threshold, "decay": decay,
              "samples": samples}
    fingerprint = octree.fingerprint(channel)
    bakes = _Bakes(octree, fingerprint, positions, folder, threads)
    rows = []
    total = len(resolutions) * (1 + len(bakers)) * len(positions)
    with progress_bar(total=total, desc="probe resolution", unit="bake",
                      enabled=progress) as bar:
        for resolution in resolutions:
            reference = bakes.all(BakeOptions(resolution=resolution, renderer="reference",
                                              **common), bar)
            rows.append(_row(resolution, "reference", reference, None))
            for baker in bakers:
                maps = bakes.all(BakeOptions(resolution=resolution, renderer=baker, **common),
                                 bar)
                rows.append(_row(resolution, baker, maps, reference))
    notes = unrefined_notes(rows, threshold)
    for note in notes:  # the command line prints a warning as a note, --quiet or not
        warnings.warn(note, UserWarning, stacklevel=2)
    return {
        "scene": scene_name, "fingerprint": fingerprint,
        "depth": octree.depth, "probes": positions.tolist(), "resolutions": list(resolutions),
        "threshold": threshold, "decay": decay, "reference_samples": samples * samples,
        "seed": seed, "channel": channel, "lod_rule": "texel-footprint cone, scale 1",
        "metrics_on": "float16 radiance as linear RGB clipped to [0, 1]", "rows": rows,
        "notes": notes,
    }


_MAP_ARRAYS = ("radiance", "distance", "normal")


class _Bakes:
    """The study's probe bakes, each an item of ``folder`` (where one is given) keyed by
    the scene (``fingerprint``: octree and channel), the probe's position and the bake
    options its baker reads (``bake_key``). A baker is warmed up before its first bake in
    this run, so the seconds column times warm bakers; a rerun that finds every bake cached
    compiles and bakes nothing."""

    def __init__(self, octree: Octree, fingerprint: str, positions: np.ndarray,
                 folder: StudyFolder | None, threads: int | None) -> None:
        self.octree, self.fingerprint, self.positions = octree, fingerprint, positions
        self.folder, self.threads = folder, threads
        self._warm: set[BakeOptions] = set()

    def all(self, options: BakeOptions, bar) -> list[ProbeMaps]:
        """Every probe baked with ``options``, in position order."""
        maps = []
        for index, position in enumerate(self.positions):
            maps.append(self.one(index, position, options))
            bar.update(1)
        return maps

    def one(self, index: int, position: np.ndarray, options: BakeOptions) -> ProbeMaps:
        if self.folder is None:
            return self._bake(position, options)
        params = {"fingerprint": self.fingerprint, "position": position.tolist(),
                  "options": bake_key(options)}
        name = f"bake-{options.renderer}-{options.resolution}-probe{index}"
        data, arrays = self.folder.item(
            name, params, lambda: _as_item(self._bake(position, options)), valid=_is_bake)
        return _from_item(data, arrays)

    def _bake(self, position: np.ndarray, options: BakeOptions) -> ProbeMaps:
        warm = dataclasses.replace(options, resolution=MIN_RESOLUTION)
        if warm not in self._warm:
            warm_up(self.octree, position, options, threads=self.threads)
            self._warm.add(warm)
        return bake_probe(self.octree, position, options, threads=self.threads)


#: What every bake reads, whichever its radiance renderer.
_EVERY_BAKE_READS = ("resolution", "renderer", "channel", "seed")


def bake_key(options: BakeOptions) -> dict:
    """The bake options that ``options.renderer`` reads: a rerun with another
    ``--threshold`` bakes the error-aware probes again and reuses the rest, as the threshold
    study reuses its reference and adaptive renders."""
    read = (*_EVERY_BAKE_READS, *RADIANCE_FIELDS[options.renderer])
    return {name: value for name, value in options.to_dict().items() if name in read}


def _as_item(maps: ProbeMaps) -> tuple[dict, dict[str, np.ndarray]]:
    """A bake as a cached item: its cost as JSON, its maps as arrays."""
    return dataclasses.asdict(maps.cost), {name: getattr(maps, name) for name in _MAP_ARRAYS}


def _from_item(data: dict, arrays: dict[str, np.ndarray]) -> ProbeMaps:
    return ProbeMaps(*(arrays[name] for name in _MAP_ARRAYS), cost=BakeCost.from_record(data))


def _is_bake(data, arrays: dict) -> bool:
    """Whether a cached item holds a bake ``_from_item`` reads back."""
    try:
        _from_item(data, arrays)
    except (VoxfieldError, ValueError, KeyError, TypeError):
        return False
    return True


def unrefined_notes(rows: list[dict], threshold: float) -> list[str]:
    """A sentence for each resolution where the error-aware baker refined no texel: its
    row then measures its first rays alone, which a reader would take for the algorithm."""
    return [f"at {r['resolution']}² the error-aware baker refined no texel (one ray a "
            f"texel): no node its rays met passed the threshold {threshold:g}; a lower "
            "--threshold makes it refine"
            for r in rows if r["baker"] == "error-aware" and r["rays_per_texel"] == 1.0]


def _row(resolution: int, baker: str, maps, reference) -> dict:
    texels = len(maps) * resolution * resolution
    rays = sum(m.cost.radiance_rays for m in maps)
    steps = sum(m.cost.radiance_steps for m in maps)
    row = {
        "resolution": resolution, "baker": baker, "probes": len(maps), "texels": texels,
        "rays": rays, "rays_per_texel": rays / texels, "steps": steps,
        "steps_per_texel": steps / texels,
        "seconds": sum(m.cost.radiance_seconds for m in maps),
        "geometry_rays": sum(m.cost.geometry_rays for m in maps),
        "geometry_steps": sum(m.cost.geometry_steps for m in maps),
        "geometry_seconds": sum(m.cost.geometry_seconds for m in maps),
        "covered_texels": int(sum(np.isfinite(m.distance).sum() for m in maps)),
    }
    if reference is not None:
        scores = [compare_images(_linear(r.radiance), _linear(m.radiance))
                  for r, m in zip(reference, maps, strict=True)]
        rmse = math.sqrt(sum(s["rmse"] ** 2 for s in scores) / len(scores))
        row.update({"rmse": rmse, "psnr": -20.0 * math.log10(rmse) if rmse > 0 else math.inf,
                    "ssim": sum(s["ssim"] for s in scores) / len(scores)})
    return row


def _linear(radiance: np.ndarray) -> np.ndarray:
    return np.clip(radiance.astype(np.float32), 0.0, 1.0)


def probe_resolution_markdown(report: dict) -> str:
    """The report as two Markdown tables (cost like EA Table 5.29, quality like 5.30)."""
    rows = sorted(report["rows"], key=lambda r: (-r["resolution"], r["baker"] != "reference"))
    cost = [[f"{r['resolution']}²", r["baker"], fmt(r["rays"]), fmt(r["rays_per_texel"], ".3f"),
             fmt(r["steps"]), fmt(r["steps_per_texel"], ".2f"), fmt(r["seconds"], ".4f")]
            for r in rows]
    geometry = [[f"{r['resolution']}²", fmt(r["geometry_rays"]), fmt(r["geometry_steps"]),
                 fmt(r["geometry_seconds"], ".4f")]
                for r in rows if r["baker"] == "reference"]
    quality = [[f"{r['resolution']}²", r["baker"], fmt_psnr(r, ".3f"), fmt(r["rmse"], ".5f"),
                fmt(r["ssim"], ".4f")] for r in rows if r["baker"] != "reference"]
    return "\n".join([
        f"# Probe bake resolution study — {report['scene']}",
        "",
        f"{len(report['probes'])} probe(s); octree depth {report['depth']}; reference: "
        f"{report['reference_samples']} CMJ rays per texel at LOD 0; cheaper bakers: "
        f"{report['lod_rule']}; error-aware threshold {report['threshold']}, decay "
        f"{report['decay']}; seed {report['seed']}. Radiance pass only (rays include "
        f"discarded ones); metrics on {report['metrics_on']}.",
        "",
        "## Radiance pass cost (like EA Table 5.29)",
        "",
        markdown_table(["map", "baker", "rays", "rays/texel", "steps", "steps/texel",
                        "seconds"], cost, align="llrrrrr"),
        "## Geometry pass (distance + normal, every baker alike)",
        "",
        markdown_table(["map", "rays", "steps", "seconds"], geometry),
        "## Radiance similarity to the reference bake (like EA Table 5.30)",
        "",
        markdown_table(["map", "baker", "PSNR", "RMSE", "SSIM"], quality, align="llrrr"),
        *[f"Note: {note}." for note in report.get("notes", [])],
    ])
