"""Cost–quality curves: each cheap renderer swept over its own knob, compared as curves.

One operating point per renderer (the thesis's tables) cannot say which renderer is better
when neither is both cheaper and sharper. Here each renderer traces a curve of (traversal
steps, rays, PSNR, SSIM) against the 4×4 reference:

- error-aware (EA): the error threshold, one curve per decay;
- EA context: EA at the thesis's decay with the context-aware geometric error (no error
  inside a surface of same-shaped neighbours), over the same thresholds;
- EA+colour: EA at the thesis's decay with the colour term (the spread of the children's
  visible luminance) added to the geometric error, over the same thresholds;
- EA+colour→LOD 0: the same, refining straight to the voxels where colour alone asks, with
  parent-ray reuse;
- hybrid: EA at the thesis's decay, then the pixels whose image variance asks for more rays
  refined as the adaptive renderer does (geometry from the error tables, colour from the
  image), over the same thresholds;
- adaptive (A): its variance normalisation (how much image variance asks for 4 or 16 rays);
- LOD: the level sampled (one ray a pixel);
- oracle: the share of pixels refined as A refines them (2×2 or 4×4 rays at LOD 0), chosen
  by their true error against the reference: what a selection rule that knew the answer
  would refine. Its delta over A is the headroom any pixel-selection rule has.

The Bjøntegaard deltas (``studies.bjontegaard``) then give EA's mean PSNR gain over A at
equal steps and its step saving at equal PSNR, per camera (perspective and orthographic).
"""

from __future__ import annotations

import math
import warnings
from pathlib import Path

import numpy as np

from voxfield.error_table.table import THESIS_DECAY
from voxfield.errors import VoxfieldError
from voxfield.kernels.camera_rays import ORTHOGRAPHIC
from voxfield.progress import progress_bar
from voxfield.render.adaptive import (
    VARIANCE_NORMALISATION,
    PixelRefinement,
    render_adaptive,
)
from voxfield.render.camera import Camera
from voxfield.render.error_aware import render_error_aware
from voxfield.render.primary import render_lod, render_reference
from voxfield.studies.bjontegaard import bd_cost, bd_quality
from voxfield.studies.figures import view_sheet
from voxfield.studies.psnr_axis import finish_psnr_axis, plot_psnr
from voxfield.studies.report import (
    StudyFolder,
    costs,
    costs_and_quality,
    fmt,
    fmt_psnr,
    markdown_table,
    scene_title,
)
from voxfield.studies.threshold_study import plot_value
from voxfield.svo.octree import Octree

#: Knob values: from refining almost everything to almost nothing, about four a doubling of
#: the knob. A renderer's cost can jump by an order of magnitude between neighbouring knob
#: values (forest's EA threshold 0.4 → 0.8: 16M → 2M steps), and a Bjøntegaard mean
#: interpolates across such a jump as if the curve were smooth there: with twice as many
#: points the forest hybrid's +0.37 dB over A became −0.01 dB.
CURVE_THRESHOLDS = (0.02, 0.027, 0.037, 0.051, 0.07, 0.096, 0.13, 0.18, 0.24, 0.33, 0.46,
                    0.63, 0.86, 1.2, 1.6)
CURVE_DECAYS = (0.0, THESIS_DECAY)
CURVE_NORMALISATIONS = (0.001, 0.0017, 0.003, 0.0053, 0.0093, 0.016, 0.028, 0.049, 0.086,
                        0.15, 0.26, 0.46, 0.8)
CURVE_LODS = (4, 3, 2, 1, 0)
#: EA's geometric error plus the image variance for colour (``colour_variance``), at the
#: thesis's decay and the adaptive renderer's default normalisation.
HYBRID = f"hybrid d={THESIS_DECAY:g}"
#: EA with the colour term (``colour_term``: the children's visible luminance spread) at
#: weight 1, the thesis's decay.
COLOUR_TERM = 1.0
COLOUR = f"EA+colour d={THESIS_DECAY:g}"
#: The same, but where colour alone asks, the sub-rays go straight to LOD 0, continuing the
#: parent ray (EA §6.2's reuse).
STRAIGHT = f"EA+colour→LOD 0 d={THESIS_DECAY:g}"
#: The EA-family curves beside the plain decays: name → (item prefix, renderer options),
#: each at the thesis's decay over the same thresholds.
CONTEXT = f"EA context d={THESIS_DECAY:g}"
EA_VARIANTS = {
    CONTEXT: ("context", {"context_aware": True}),
    COLOUR: ("colour", {"colour_term": COLOUR_TERM}),
    STRAIGHT: ("straight", {"colour_term": COLOUR_TERM, "colour_to_voxels": True,
                            "reuse_parent": True}),
    HYBRID: ("hybrid", {"colour_variance": VARIANCE_NORMALISATION}),
}
#: The oracle's shares of pixels refined and the rays a side it gives them.
ORACLE_FRACTIONS = (0.002, 0.005, 0.01, 0.02, 0.05, 0.1, 0.2, 0.35, 0.5, 0.75, 1.0)
ORACLE_SIDES = (2, 4)
ORACLE = "oracle"
#: A perspective and an orthographic view of the same ground (EA §5.1.1 and its flat-ground
#: refinement, which only perspective shows).
CURVE_CAMERAS = ("top", "ortho-top")


def ea_curve_name(decay: float) -> str:
    return f"EA d={decay:g}"


def run_curves_study(
    octree: Octree, cameras: dict[str, Camera], out_dir: str | Path, *,
    thresholds=CURVE_THRESHOLDS, decays=CURVE_DECAYS, normalisations=CURVE_NORMALISATIONS,
    lods=CURVE_LODS, base_lod: int | None = 2, seed: int = 0, channel: str = "albedo",
    scene_name: str = "scene", progress: bool = False, fresh: bool = False, scheduler=None,
) -> dict:
    """Sweep every curve under every camera (each point cached and resumable) and write
    results.json, results.md and curves.png into ``out_dir``."""
    if not cameras:
        raise VoxfieldError("the curves study needs at least one camera")
    beyond = [lod for lod in lods if not 0 <= lod <= octree.depth]
    if beyond:  # dropped without a word, a LOD asked for was simply missing from the curve
        warnings.warn(f"LOD {', '.join(map(str, beyond))} left out of the LOD curve: the "
                      f"octree's levels run 0..{octree.depth}", UserWarning, stacklevel=2)
    lods = [lod for lod in lods if 0 <= lod <= octree.depth]
    if min(len(thresholds), len(normalisations), len(lods)) < 2 or not decays:
        raise VoxfieldError("each curve needs at least two knob values (and one decay)")
    folder = StudyFolder(out_dir, study="study curves", fresh=fresh, scheduler=scheduler)
    points = len(cameras) * (1 + (len(decays) + len(EA_VARIANTS)) * len(thresholds)
                             + len(normalisations) + len(lods)
                             + len(ORACLE_FRACTIONS) * len(ORACLE_SIDES))
    report = {"scene": scene_name, "base_lod": base_lod, "seed": seed, "channel": channel,
              "metrics_on": "linear RGB in [0, 1]", "cameras": {}}
    settings = {"base_lod": base_lod, "seed": seed, "channel": channel}
    references = {}
    with progress_bar(total=points, desc="curves", unit="render", enabled=progress) as bar:
        for cam_name, camera in cameras.items():
            sweep = CameraSweep(folder, octree, cam_name, camera, scene_name, settings, bar)
            references[f"{cam_name} camera, 4×4 reference"] = sweep.reference
            curves = {}
            for decay in decays:
                curves[ea_curve_name(decay)] = sweep.curve("threshold", [
                    sweep.point(f"ea-d{decay:g}-t{t:g}", {"decay": decay, "threshold": t},
                                lambda o, c, t=t, d=decay: render_error_aware(
                                    o, c, threshold=t, decay=d, **settings))
                    for t in thresholds])
            for name, (prefix, extra) in EA_VARIANTS.items():
                curves[name] = sweep.curve("threshold", [
                    sweep.point(f"{prefix}-d{THESIS_DECAY:g}-t{t:g}",
                                {"decay": THESIS_DECAY, "threshold": t, **extra},
                                lambda o, c, t=t, extra=extra: render_error_aware(
                                    o, c, threshold=t, decay=THESIS_DECAY, **extra,
                                    **settings))
                    for t in thresholds])
            curves["A"] = sweep.curve("variance_normalisation", [
                sweep.point(f"a-n{n:g}", {"variance_normalisation": n},
                            lambda o, c, n=n: render_adaptive(o, c, variance_normalisation=n,
                                                              **settings))
                for n in normalisations])
            curves["LOD"] = sweep.curve("lod", [
                sweep.point(f"lod{lod}", {"lod": lod}, lambda o, c, lod=lod: render_lod(
                    o, c, lod=lod, seed=seed, channel=channel))
                for lod in lods])
            curves[ORACLE] = sweep.curve("fraction", [
                sweep.point(f"oracle-s{side}-f{f:g}", {"fraction": f, "side": side},
                            lambda o, c, ref, f=f, side=side: render_oracle(
                                o, c, ref, fraction=f, side=side, **settings),
                            needs_reference=True)
                for side in ORACLE_SIDES for f in ORACLE_FRACTIONS])
            sweep.run()
            report["cameras"][cam_name] = {
                "kind": "orthographic" if camera.kind == ORTHOGRAPHIC else "perspective",
                "width": camera.width, "height": camera.height,
                "reference": costs(sweep.reference), "curves": curves,
                "deltas": curve_deltas(
                    curves, [*(ea_curve_name(d) for d in decays), *EA_VARIANTS, ORACLE]),
            }
    folder.write_json("results.json", report)
    folder.write_text("results.md", results_markdown(report))
    folder.write_figure("curves.png", curves_figure(report))
    title = f"The views measured — {scene_title(scene_name)}"
    folder.write_figure("view.png", view_sheet(references, title=title))
    folder.publish_report()
    return report


class CameraSweep:
    """The cached points of one camera: its reference first, then any renderer's point."""

    def __init__(self, folder: StudyFolder, octree: Octree, name: str, camera: Camera,
                 scene_name: str, settings: dict, bar):
        self.folder, self.name, self.camera, self.bar = folder, name, camera, bar
        self.octree = octree
        self.pending: list = []
        self.view = {"scene": scene_name, "fingerprint": octree.fingerprint(settings["channel"]),
                     "camera": camera.params.tolist(), "size": camera.width,
                     "height": camera.height, **settings}
        self.reference = folder.render_item(f"{name}-reference", self.view, lambda: (
            render_reference(octree, camera, side=4, seed=settings["seed"],
                             channel=settings["channel"])))
        self.first_error = first_pass_error(octree, camera, self.reference, **settings)
        bar.update(1)

    def point(self, name: str, params: dict, render, needs_reference: bool = False) -> dict:
        """Costs and quality of ``render(octree, camera)`` (with ``needs_reference``,
        ``render(octree, camera, reference)``), cached under the camera's name: the returned
        point is filled in by ``run``, which computes every point at once."""
        point = dict(params)
        camera = self.camera

        def measure(shared):
            octree, reference, first_error = shared
            result = (render(octree, camera, reference) if needs_reference
                      else render(octree, camera))
            return {**costs_and_quality(reference, result),
                    **selection(result.ray_count, first_error)}

        self.pending.append((point, (f"{self.name}-{name}", {**self.view, **params}, measure)))
        return point

    def run(self) -> None:
        """Compute the pending points (independent items: a batch on the folder's
        scheduler) and fill them in."""
        values = self.folder.value_batch([spec for _, spec in self.pending],
                                         shared=(self.octree, self.reference, self.first_error),
                                         bar=self.bar)
        for (point, _), value in zip(self.pending, values, strict=True):
            point.update(value)
        self.pending.clear()

    @staticmethod
    def curve(knob: str, points: list[dict]) -> dict:
        return {"knob": knob, "points": points}


def first_pass_error(octree: Octree, camera: Camera, reference, *, base_lod: int | None,
                     seed: int, channel: str) -> np.ndarray:
    """Per pixel, the squared error (summed over RGB) of one ray at ``base_lod`` against the
    reference: what every adaptive renderer starts from, and what refining a pixel removes."""
    return _first_pass(octree, camera, reference, base_lod, seed, channel)[1]


def _first_pass(octree, camera, reference, base_lod, seed, channel):
    """The first pass at ``base_lod`` and its per-pixel squared error against the reference."""
    first = render_lod(octree, camera, lod=base_lod, seed=seed, channel=channel)
    truth = np.clip(reference.image, 0.0, 1.0)
    return first, np.sum((np.clip(first.image, 0.0, 1.0) - truth) ** 2, axis=-1)


def selection(ray_count: np.ndarray, first_error: np.ndarray) -> dict:
    """How well a render chose the pixels it refined (more than one ray), against the first
    pass's true error: ``refined_share`` of the pixels; ``selection_precision``, the share of
    them among the as many pixels with the largest error (1: an oracle's choice); and
    ``error_covered``, the share of the first pass's squared error in them."""
    refined = np.asarray(ray_count).reshape(-1) > 1
    error = np.asarray(first_error, np.float64).reshape(-1)
    count = int(refined.sum())
    total = float(error.sum())
    if count == 0:
        return {"refined_share": 0.0, "selection_precision": None, "error_covered": 0.0}
    worst = np.zeros(error.size, bool)
    worst[np.argsort(-error, kind="stable")[:count]] = True
    return {"refined_share": count / error.size,
            "selection_precision": float(np.count_nonzero(refined & worst)) / count,
            "error_covered": float(error[refined].sum()) / total if total > 0 else None}


def render_oracle(octree: Octree, camera: Camera, reference, *, fraction: float, side: int,
                  base_lod: int | None, seed: int, channel: str):
    """The first pass at ``base_lod``, then the ``fraction`` of its pixels with the largest
    true error against ``reference`` re-rendered with ``side``×``side`` rays at LOD 0: A's
    refinement with a perfect choice of pixels. No rule that refines as A does can choose
    better at the same cost, so the gap between this curve and A's (or the hybrid's) is
    what a better error predictor could still win."""
    result, error = _first_pass(octree, camera, reference, base_lod, seed, channel)
    error = error.reshape(-1)
    count = int(round(fraction * error.size))
    worst = np.argsort(-error, kind="stable")[:count]
    worst = np.sort(worst[error[worst] > 0.0])
    if len(worst):
        PixelRefinement(octree, camera, result, seed, octree.kernel_colours(channel)).refine(
            worst, side)
    result.renderer = "oracle"
    return result


def _series(curve: dict, cost: str) -> tuple[list[float], list[float]]:
    """(cost, PSNR) of a curve's points; an infinite PSNR (stored as None) is left out."""
    xs, ys = [], []
    for p in curve["points"]:
        if p.get("psnr") is not None and math.isfinite(p["psnr"]) and p[cost] > 0:
            xs.append(float(p[cost]))
            ys.append(float(p["psnr"]))
    return xs, ys


def curve_deltas(curves: dict, tested: list[str]) -> list[dict]:
    """BD-PSNR (dB) at equal steps and at equal rays, and BD-rate in steps (%), of each tested
    curve against A and against LOD; None with the reason where the curves do not overlap."""
    rows = []
    for name in tested:
        for baseline in ("A", "LOD"):
            row = {"curve": name, "against": baseline}
            for key, cost, fn in (("bd_psnr_steps", "steps", bd_quality),
                                  ("bd_psnr_rays", "rays", bd_quality),
                                  ("bd_steps_percent", "steps", bd_cost)):
                if baseline == "LOD" and cost == "rays":
                    row[key] = None  # one ray a pixel at every level: no curve in rays
                    continue
                try:
                    row[key] = fn(*_series(curves[baseline], cost), *_series(curves[name], cost))
                except VoxfieldError as exc:
                    row[key] = None
                    row.setdefault("note", str(exc))
            rows.append(row)
    return rows


def results_markdown(report: dict) -> str:
    lines = [f"# Cost–quality curves — {report['scene']}", "",
             f"Base LOD {report['base_lod']}, seed {report['seed']}, channel "
             f"{report['channel']}. Quality against the 4×4 reference on linear RGB in [0, 1]. "
             "BD-PSNR: mean PSNR gain of the curve over the baseline at equal cost (log "
             "scale); BD-steps: mean step change at equal PSNR (negative: cheaper).", ""]
    for cam_name, cam in report["cameras"].items():
        lines += [f"## {cam_name} ({cam['kind']}, {cam['width']}×{cam['height']})", "",
                  "### Bjøntegaard deltas", ""]
        lines.append(markdown_table(
            ["curve", "against", "BD-PSNR at equal steps (dB)", "BD-PSNR at equal rays (dB)",
             "BD-steps (%)"],
            [[d["curve"], d["against"], fmt(d["bd_psnr_steps"], "+.2f"),
              fmt(d["bd_psnr_rays"], "+.2f"), fmt(d["bd_steps_percent"], "+.1f")]
             for d in cam["deltas"]]))
        notes = sorted({f"{d['curve']} against {d['against']}: {d['note']}"
                        for d in cam["deltas"] if "note" in d})
        lines += ["LOD casts one ray a pixel at every level, so it has no curve in rays.", ""]
        lines += [f"- {n}" for n in notes]
        lines += ["", "### Points", ""]
        rows = []
        for name, curve in cam["curves"].items():
            for p in curve["points"]:
                side = f" ({p['side']}×{p['side']})" if "side" in p else ""
                rows.append([name, f"{curve['knob']} {fmt(p[curve['knob']], 'g')}{side}",
                             fmt(p["rays"]), fmt(p["steps"]), fmt_psnr(p, ".2f"),
                             fmt(p["ssim"], ".4f"), fmt(p.get("flip"), ".4f"),
                             _percent(p.get("refined_share")),
                             _percent(p.get("selection_precision")),
                             _percent(p.get("error_covered"))])
        lines.append(markdown_table(["curve", "knob", "rays", "steps", "PSNR", "SSIM", "FLIP",
                                     "refined %", "precision %", "error covered %"], rows))
        lines.append("Precision: the share of the refined pixels among as many pixels with "
                     "the largest first-pass error (the oracle's choice scores 100); error "
                     "covered: the share of the first pass's squared error in them.\n")
        lines.append("")
    return "\n".join(lines)


def _percent(share) -> str:
    return fmt(None if share is None else 100 * share, ".1f")


def _sharpest_for_cost(points: list[dict]) -> list[dict]:
    """The points (sorted by steps) no cheaper point beats in PSNR."""
    best = -math.inf
    front = []
    for p in points:
        psnr = math.inf if p.get("psnr") is None else p["psnr"]
        if psnr > best:
            front.append(p)
            best = psnr
    return front


def curves_figure(report: dict):
    # heavy: matplotlib loads only when a figure is drawn
    import matplotlib

    matplotlib.use("Agg")
    # heavy: matplotlib loads only when a figure is drawn
    import matplotlib.pyplot as plt
    from matplotlib.ticker import NullFormatter

    cams = list(report["cameras"].items())
    # (x key, y key, x label, y label) per panel; FLIP (lower is better) where it was measured.
    panels = [("steps", "psnr", "traversal steps", "PSNR (dB)"),
              ("rays", "psnr", "rays", "PSNR (dB)"),
              ("steps", "ssim", "traversal steps", "SSIM")]
    if any(p.get("flip") is not None for _, cam in cams for curve in cam["curves"].values()
           for p in curve["points"]):
        panels.append(("steps", "flip", "traversal steps", "FLIP (lower is better)"))
    fig, axes = plt.subplots(len(cams), len(panels), figsize=(5 * len(panels), 4.0 * len(cams)),
                             squeeze=False)
    # Curves often share points (a colour term that changed nothing, an adaptive renderer
    # that never refined: one point under the LOD curve's): each its own marker, drawn
    # smaller than the one before and hollow, so a point under another still shows.
    markers = "osD^vPX<>*"
    for row, (cam_name, cam) in zip(axes, cams, strict=True):
        for k, (name, curve) in enumerate(cam["curves"].items()):
            points = sorted(curve["points"], key=lambda p: p["steps"])
            style = {"marker": markers[k % len(markers)], "markersize": max(9.0 - 0.6 * k, 4.0),
                     "fillstyle": "none", "markeredgewidth": 1.4}
            if name == ORACLE:  # a bound to look up to: its best points, drawn apart
                points = _sharpest_for_cost(points)
                style = {"linestyle": "--", "color": "0.3", "marker": "."}
            for ax, (x, y, _, _) in zip(row, panels, strict=True):
                if y == "psnr":
                    plot_psnr(ax, [p[x] for p in points], [p.get(y) for p in points],
                              label=name, **style)
                else:
                    ax.plot([p[x] for p in points], [plot_value(p.get(y)) for p in points],
                            label=name, **style)
        for ax, (_, _, x_label, y_label) in zip(row, panels, strict=True):
            ax.set_xscale("log")
            ax.xaxis.set_minor_formatter(NullFormatter())
            ax.set_xlabel(x_label)
            ax.set_ylabel(y_label)
            ax.set_title(f"{cam_name} ({cam['kind']})")
            ax.grid(alpha=0.3)
            finish_psnr_axis(ax)
        row[0].legend(fontsize=8)
    fig.suptitle(f"cost–quality curves — {scene_title(report['scene'])}")
    fig.tight_layout()
    return fig
