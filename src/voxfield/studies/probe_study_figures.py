"""Plots and the contact sheet of the probe study (``studies.probe_study``).

Each function takes the study's report (and renders, for the sheet) and returns a matplotlib
Figure; nothing here measures anything.
"""

from __future__ import annotations

import math

import numpy as np

from voxfield.lightfield.probe_render import result_kinds
from voxfield.studies.figures import Panel, contact_sheet
from voxfield.studies.report import fmt_psnr, scene_title

#: Colours of the result-kind map: hit, miss, unknown, fallback, environment.
KIND_COLOURS = {"hit": (0.1, 0.75, 0.2), "miss": (0.15, 0.35, 0.95),
                "unknown": (0.9, 0.1, 0.1), "fallback": (0.95, 0.8, 0.1),
                "environment": (0.7, 0.3, 0.9)}


def _plt():
    # heavy: matplotlib loads only when a figure is drawn
    import matplotlib

    matplotlib.use("Agg")
    # heavy: matplotlib loads only when a figure is drawn
    import matplotlib.pyplot as plt

    return plt


def _value(v) -> float:
    return math.nan if v is None else float(v)


def resolution_figure(report: dict):
    """Fetches per pixel against R (log-log) per marcher, with curves ∝ √r (= R) and ∝ log r
    drawn through the DDA's and the hierarchical trace's first points; PSNR against R."""
    plt = _plt()
    rows = report["resolution"]
    sides = np.array([row["resolution"] for row in rows], float)
    marchers = list(report["growth"])
    fig, (ax, bx) = plt.subplots(1, 2, figsize=(12, 4.4))
    for m in marchers:
        fetches = [row["marchers"][m]["fetches_per_pixel"] for row in rows]
        exponent = report["growth"][m]["exponent_r"]
        label = m if exponent is None else f"{m} (r^{exponent:.2f})"
        ax.plot(sides, fetches, "o-", label=label)
        bx.plot(sides, [_value(row["marchers"][m]["psnr"]) for row in rows], "o-", label=m)
    anchors = {m: rows[0]["marchers"][m]["fetches_per_pixel"] for m in marchers}
    dda = anchors.get("dda", next(iter(anchors.values())))
    ax.plot(sides, dda * sides / sides[0], "k--", lw=1, label="∝ √r (= R)")
    hier = anchors.get("hierarchical", dda)
    ax.plot(sides, hier * np.log(sides ** 2) / np.log(sides[0] ** 2), "k:", lw=1,
            label="∝ log r")
    for a in (ax, bx):
        a.set_xscale("log", base=2)
        a.set_xticks(sides, [f"{int(s)}²" for s in sides])
        a.set_xlabel("probe map resolution R (r = R² texels)")
        a.legend(fontsize=8)
    ax.set_yscale("log")
    ax.set_ylabel("texel fetches per pixel")
    ax.set_title("fetches per pixel (probe thesis §9.1)")
    bx.set_ylabel("PSNR (dB) against the octree")
    bx.set_title("light-field quality")
    fig.suptitle(f"{scene_title(report['scene'])}: grid {report['grid']}")
    fig.tight_layout()
    return fig


def count_figure(report: dict):
    """Failures, fetches and probes tried per pixel against the number of probes."""
    plt = _plt()
    rows = report["probe_count"]
    probes = [row["probes"] for row in rows]
    labels = [row["grid"] for row in rows]
    marchers = list(rows[0]["marchers"])
    fig, axes = plt.subplots(1, 3, figsize=(15, 4.2))
    panels = (("failures", "failures (% of pixels)", 100.0),
              ("fetches_per_pixel", "texel fetches per pixel", 1.0),
              ("probes_tried_per_pixel", "probes tried per pixel", 1.0))
    for ax, (key, title, scale) in zip(axes, panels, strict=True):
        for m in marchers:
            ax.plot(probes, [scale * row["marchers"][m][key] for row in rows], "o-", label=m)
        ax.set_xscale("log")
        ax.set_xticks(probes, [f"{p}\n{g}" for p, g in zip(probes, labels, strict=True)])
        ax.minorticks_off()
        ax.set_xlabel("probes")
        ax.set_title(title)
        ax.legend(fontsize=8)
    axes[1].set_yscale("log")
    fig.suptitle(f"{scene_title(report['scene'])}: probe count, {report['count_resolution']}² maps")
    fig.tight_layout()
    return fig


def ordering_figure(report: dict):
    """First-probe success (bars) per ordering for each probe grid."""
    plt = _plt()
    rows = report["probe_count"]
    orderings = list(rows[0]["orderings"])
    x = np.arange(len(rows))
    width = 0.8 / len(orderings)
    fig, ax = plt.subplots(figsize=(8, 4.2))
    for i, k in enumerate(orderings):
        values = [100 * row["orderings"][k]["first_probe_success"] for row in rows]
        ax.bar(x + (i - (len(orderings) - 1) / 2) * width, values, width, label=k)
    ax.set_xticks(x, [f"{row['grid']} ({row['probes']})"
                      for row in rows])
    ax.set_xlabel("probe grid (probes)")
    ax.set_ylabel("first probe answers (% of pixels)")
    ax.set_ylim(0, 100)
    ax.legend(fontsize=8)
    ax.set_title(f"{scene_title(report['scene'])}: first-probe success per ordering")
    fig.tight_layout()
    return fig


def kind_image(result) -> np.ndarray:
    """The result-kind map as colours (``KIND_COLOURS``; black for anything else)."""
    kind = np.asarray(result.maps["result_kind"])
    out = np.zeros((*kind.shape, 3), np.float32)
    for name, code in result_kinds().items():
        out[kind == code] = KIND_COLOURS.get(name, (0.0, 0.0, 0.0))
    return out


def fetch_scale(result) -> float:
    """The fetch count ``fetch_image`` shows as white: the 99th percentile, at least 1."""
    return max(float(np.percentile(result.maps["texel_fetches"], 99)), 1.0)


def fetch_image(result) -> np.ndarray:
    """Fetches per pixel as grey levels, white at ``fetch_scale``."""
    fetches = np.asarray(result.maps["texel_fetches"], np.float32)
    return np.clip(fetches / fetch_scale(result), 0.0, 1.0)


def contact_sheet_figure(report: dict, reference, renders: dict):
    """The reference and each probe render of section 1 with its PSNR, then the light-field
    render's result kinds and fetch map, and the quality table as text."""
    quality = {q["method"]: q for q in report["quality"]}
    cells: list = [Panel("octree (LOD 0, pixel centres)", reference.image)]
    for method, result in renders.items():
        q = quality.get(method, {})
        title = f"{method}: {fmt_psnr(q)} dB" if "psnr" in q else method
        cells.append(Panel(title, result.image))
    lf = renders.get("light-field")
    if lf is not None:
        cells.append(Panel("result kind (green hit, blue miss, red unknown, yellow fallback)",
                           kind_image(lf), linear_rgb=False))
        cells.append(Panel(f"light-field texel fetches per pixel (black 0, white "
                           f"{fetch_scale(lf):.0f} or more)", fetch_image(lf), linear_rgb=False))
    lines = [f"{'method':<12} {'PSNR':>7} {'SSIM':>7} {'fail%':>6}"]
    for q in report["quality"]:
        lines.append(f"{q['method']:<12} {fmt_psnr(q):>7} {_value(q['ssim']):7.4f} "
                     f"{100 * q['failures']:6.1f}")
    cells.append("\n".join(lines))
    grid = report["grid"]
    return contact_sheet(cells, columns=4,
                         title=f"{scene_title(report['scene'])}: probes {grid} at "
                               f"{report['quality_resolution']}² vs the octree")
