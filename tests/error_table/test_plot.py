"""`voxfield errors show`: the views keep the error's colours where it passes the threshold,
so they can still be read off the colour bar."""

from __future__ import annotations

import numpy as np
from PIL import Image

from voxfield.error_table.plot import plot_mask_error
from voxfield.error_table.table import load_error_table


def test_marking_the_error_above_the_threshold_keeps_most_of_its_colours(tmp_path):
    """Every view of mask 51 above a threshold of 0 against none above a threshold of 1:
    the hatches change a minority of the spheres' pixels (a red tint changed them all)."""
    table = load_error_table()
    everything, nothing = tmp_path / "all.png", tmp_path / "none.png"
    plot_mask_error(table, 51, everything, threshold=0.0)
    plot_mask_error(table, 51, nothing, threshold=1.0)
    a = np.asarray(Image.open(everything).convert("RGB"), np.int64)
    b = np.asarray(Image.open(nothing).convert("RGB"), np.int64)
    assert a.shape == b.shape
    views = (slice(80, 340), slice(470, 1260))  # the three spheres, below the titles
    changed = np.any(np.abs(a[views] - b[views]) > 8, axis=-1)
    coloured = np.any(np.abs(np.diff(b[views], axis=-1)) > 8, axis=-1)  # viridis, not white
    assert coloured.mean() > 0.3
    share = changed[coloured].mean()
    assert 0.05 < share < 0.5, share


def test_the_title_places_a_threshold_off_the_colour_bar(tmp_path, monkeypatch):
    """The errors run 0..1, and so does the bar: a threshold of 5 or -1 has no red line on
    it, which the title still pointed at."""
    from voxfield.error_table import plot

    figures = []
    monkeypatch.setattr(plot, "save_figure", lambda fig, path: figures.append(fig) or path)
    table = load_error_table()
    for threshold in (5.0, -1.0, 0.154):
        plot_mask_error(table, 3, tmp_path / "m.png", threshold=threshold)
    (high, low, inside) = [fig._suptitle.get_text() for fig in figures]
    bar_lines = [len(fig.axes[-1].get_lines()) for fig in figures]
    assert "above the bar's 1: no direction" in high and "red line" not in high
    assert "below the bar's 0: every direction" in low and "red line" not in low
    assert "(the red line on the bar)" in inside
    assert bar_lines == [0, 0, 1]
