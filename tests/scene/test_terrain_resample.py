"""Void filling and grid resampling (``voxfield.scene.terrain.resample``)."""

from __future__ import annotations

import numpy as np
from scipy import ndimage
from terrain_helpers import hills

from voxfield.scene.terrain.resample import fill_voids, resample

# --------------------------------------------------------------------------------------------
# Voids


def test_fill_voids_stays_within_the_rim_and_is_smooth():
    hm = hills(48, seed=1, amplitude=100.0)
    elev = hm.elevation.copy()
    yy, xx = np.mgrid[:48, :48]
    hole = (yy - 20) ** 2 + (xx - 25) ** 2 < 8**2
    elev[hole] = np.nan
    filled = fill_voids(elev)
    assert not np.isnan(filled).any()
    assert np.array_equal(filled[~hole], elev[~hole])
    rim = ndimage.binary_dilation(hole, np.ones((3, 3), bool)) & ~hole
    assert elev[rim].min() - 1e-9 <= filled[hole].min()
    assert filled[hole].max() <= elev[rim].max() + 1e-9
    # Smoothing leaves no nearest-fill terraces: more distinct values than rim samples.
    assert len(np.unique(np.round(filled[hole], 6))) > rim.sum()


# --------------------------------------------------------------------------------------------
# Resampling


def test_resample_keeps_constants_and_ramps():
    assert np.allclose(resample(np.full((5, 7), 3.5), (40, 33)), 3.5)
    ramp = np.tile(np.arange(20, dtype=float), (20, 1))
    up = resample(ramp, (20, 80))
    # Output column j samples input position (j + 0.5) / 4 - 0.5; cubic is exact on ramps
    # away from the clamped borders.
    pos = (np.arange(80) + 0.5) / 4 - 0.5
    inner = (pos > 2) & (pos < 17)
    assert np.allclose(up[:, inner], pos[inner])


def test_resample_shrinking_is_antialiased():
    checker = (np.indices((64, 64)).sum(axis=0) % 2).astype(float)
    small = resample(checker, (8, 8))
    assert np.allclose(small, 0.5, atol=0.02)
