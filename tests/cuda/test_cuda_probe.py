"""The CUDA light-field trace against the CPU's: the same answers for every ray.

Marked ``cuda``: run under Numba's CUDA simulator by ``make test`` or on a real GPU, and
skipped elsewhere. The probes are tiny (the simulator runs a Python thread per ray)."""

from __future__ import annotations

import numpy as np
import pytest

from voxfield.lightfield import HIT, LightFieldOptions, PackedProbes, trace_light_field
from voxfield.lightfield.probe_render import render_from_probes
from voxfield.probes.bake import bake_probes
from voxfield.probes.grid import ProbeGrid
from voxfield.probes.probe_set import BakeOptions
from voxfield.render import Camera
from voxfield.render.device import cuda_available
from voxfield.scene.builtin import pillars
from voxfield.svo import build_octree

pytestmark = [pytest.mark.cuda,
              pytest.mark.skipif(not cuda_available(),
                                 reason="no CUDA GPU and NUMBA_ENABLE_CUDASIM is not set"),
              pytest.mark.filterwarnings("ignore:overflow encountered:RuntimeWarning")]

FIELDS = ("kind", "t", "radiance", "normal", "distance", "probe", "probes_tried", "fetches",
          "steps")


@pytest.fixture(scope="module")
def packed():
    octree = build_octree(pillars(16))
    grid = ProbeGrid([4.5, 9.5, 4.5], [7.0, 1.0, 7.0], [2, 1, 2])
    probe_set = bake_probes(octree, grid, BakeOptions(resolution=8, renderer="lod", lod=0))
    return PackedProbes.from_probe_set(probe_set)


@pytest.mark.parametrize("options", [
    LightFieldOptions(),
    LightFieldOptions(marcher="dda", ordering="signed-dot", consensus=True),
    LightFieldOptions(marcher="march3d", step=1.0, max_steps=24, colour_probe="parallel",
                      colour_filter="nearest"),
], ids=["defaults", "dda-consensus", "march3d"])
def test_gpu_answers_equal_the_cpu(packed, options):
    rng = np.random.default_rng(5)
    origins = rng.uniform([1, 6, 1], [15, 12, 15], (24, 3))
    dirs = rng.normal(size=(24, 3))
    dirs[:4] = [[0, -1, 0], [1, 0, 0], [0, 0, -1], [0.3, -1, 0.2]]  # axis-aligned and steep
    cpu = trace_light_field(packed, origins, dirs, options)
    gpu = trace_light_field(packed, origins, dirs, options, device="cuda")
    for name in FIELDS:
        a, b = getattr(cpu, name), getattr(gpu, name)
        assert np.array_equal(a, b), f"{name}: {int((a != b).sum())} values differ"
    assert (cpu.kind == HIT).any()  # some rays hit: the colour probe path ran


def test_a_probe_render_on_the_gpu_is_the_cpu_image(packed):
    camera = Camera.look_at((8.0, 14.0, 20.0), (8.0, 4.0, 8.0), fov_deg=60.0, width=6,
                            height=5)
    cpu = render_from_probes(packed, camera)
    gpu = render_from_probes(packed, camera, device="cuda")
    for name in ("image", "depth", "normal", "hit_count", "steps"):
        assert np.array_equal(getattr(cpu, name), getattr(gpu, name)), name
    for name in ("probes_tried", "texel_fetches", "result_kind", "probe"):
        assert np.array_equal(cpu.maps[name], gpu.maps[name]), name
