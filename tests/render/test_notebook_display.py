"""Results show themselves in Jupyter: a render as its shaded PNG, a probe set as a summary
beside its radiance atlas."""

from __future__ import annotations

import base64
import io
import re

import numpy as np
from PIL import Image

from voxfield.probes.bake import bake_probes
from voxfield.probes.grid import ProbeGrid
from voxfield.probes.probe_set import BakeOptions
from voxfield.render.camera import orbit_camera
from voxfield.render.image_io import png_pixels, shade_for_display
from voxfield.render.primary import render_lod
from voxfield.scene.builtin import cornell
from voxfield.svo.build import build_octree


def test_a_render_displays_as_its_shaded_png():
    octree = build_octree(cornell(16))
    result = render_lod(octree, orbit_camera(*octree.voxel_bounds, size=20), lod=0)
    shown = np.asarray(Image.open(io.BytesIO(result._repr_png_())))
    np.testing.assert_array_equal(shown, png_pixels(shade_for_display(result)))
    assert shown.shape == (20, 20, 3)
    # Without face normals (a probe render) or for a baked light channel: shown as it is.
    result.normal[:] = 0.0
    plain = np.asarray(Image.open(io.BytesIO(result._repr_png_())))
    np.testing.assert_array_equal(plain, png_pixels(result.image))


def test_a_probe_set_displays_its_summary_and_atlas():
    octree = build_octree(cornell(16))
    lo, hi = octree.voxel_bounds
    probes = bake_probes(octree, ProbeGrid.fit(lo, hi, (2, 1, 1)),
                         BakeOptions(resolution=8, renderer="lod", lod=0))
    page = probes._repr_html_()
    assert "2 of 2 baked, grid 2 × 1 × 1" in page and "8² texels" in page
    data = re.search(r"data:image/png;base64,([A-Za-z0-9+/=]+)", page).group(1)
    atlas = Image.open(io.BytesIO(base64.b64decode(data)))
    assert atlas.size == (8 * 2 + 1, 8)  # two tiles side by side, one texel apart
