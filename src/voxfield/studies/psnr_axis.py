"""PSNR on a plot's y axis, where an image equal to the reference scores ∞.

No finite axis holds an infinite PSNR (``None`` once read back from ``results.json``). Drawn
as NaN, as the figures did, the best points vanished without a word, and a panel of them only
was empty under a made-up axis (-0.04 to 0.04 dB). Here they sit on the panel's top edge as
triangles, and the panel says what the triangles mean.
"""

from __future__ import annotations

import math

import numpy as np

#: The gid of what stands for an infinite PSNR, so ``finish_psnr_axis`` can tell it apart.
INFINITE_GID = "psnr-infinite"
INFINITE_NOTE = "▲ on the top edge: ∞ dB (equal to the reference)"


def is_infinite_psnr(value) -> bool:
    """Whether ``value`` is an infinite PSNR (``None``: JSON's spelling of one)."""
    return value is None or (isinstance(value, float | int) and math.isinf(value)
                             and value > 0)


def plot_psnr(ax, xs, psnrs, **style):
    """``ax.plot(xs, psnrs, **style)`` with the infinite PSNRs as triangles on the top edge
    (x where they were measured); returns the line of the finite ones."""
    xs, psnrs = list(xs), list(psnrs)
    finite = [math.nan if is_infinite_psnr(p) else float(p) for p in psnrs]
    line = ax.plot(xs, finite, **style)[0]
    top = [x for x, p in zip(xs, psnrs, strict=True) if is_infinite_psnr(p)]
    if top:
        ax.plot(top, [1.0] * len(top), transform=ax.get_xaxis_transform(), clip_on=False,
                linestyle="none", marker="^", markersize=9, color=line.get_color(),
                gid=INFINITE_GID)
    return line


def psnr_hline(ax, value, **style) -> None:
    """``ax.axhline`` at a PSNR, or along the top edge where it is infinite."""
    if is_infinite_psnr(value):  # in axes units: it leaves the data limits alone
        ax.plot([0.0, 1.0], [1.0, 1.0], transform=ax.transAxes, clip_on=False,
                gid=INFINITE_GID, **style)
    else:
        ax.axhline(float(value), **style)


def finish_psnr_axis(ax) -> None:
    """Say what the top-edge triangles mean, where a panel has any; a panel with no finite
    PSNR at all loses its y tick labels, which would name values nothing has."""
    lines = ax.get_lines()
    if not any(line.get_gid() == INFINITE_GID for line in lines):
        return
    ax.text(0.02, 0.9, INFINITE_NOTE, transform=ax.transAxes, fontsize=7, va="top")
    finite = [line for line in lines if line.get_gid() != INFINITE_GID
              and np.isfinite(np.asarray(line.get_ydata(), dtype=float)).any()]
    finite += [c for c in ax.collections if np.isfinite(c.get_offsets()).all(axis=1).any()]
    if not finite:
        ax.set_yticks([])
