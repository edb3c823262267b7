"""The CUDA primary-ray kernel against the CPU renderer: the same pixels, bit for bit.

The GPU walks the octree alone, so the CPU renders it is held to walk it alone too
(``columns=False``): the same steps as well.

Marked ``cuda``: they run under Numba's CUDA simulator (``make test`` runs them with
``NUMBA_ENABLE_CUDASIM=1``, where the kernel's thread body executes in Python around the
same compiled per-pixel code) or on a real GPU, and skip elsewhere. Scenes are tiny: the
simulator runs one Python thread per GPU thread.
"""

from __future__ import annotations

import numpy as np
import pytest

from random_scenes import random_scene
from voxfield.render import Camera, orbit_camera
from voxfield.render.adaptive import render_adaptive
from voxfield.render.device import cuda_available
from voxfield.render.primary import render_lod, render_reference
from voxfield.scene.builtin import pillars
from voxfield.svo import build_octree

pytestmark = [pytest.mark.cuda,
              pytest.mark.skipif(not cuda_available(),
                                 reason="no CUDA GPU and NUMBA_ENABLE_CUDASIM is not set"),
              # With the JIT off the 32-bit hashes run on NumPy scalars, which warn when they
              # wrap; wrapping is what the hashes mean.
              pytest.mark.filterwarnings("ignore:overflow encountered:RuntimeWarning")]


def _assert_same(cpu, gpu):
    for name in ("image", "depth", "normal", "ray_count", "hit_count", "steps", "finest_lod"):
        a, b = getattr(cpu, name), getattr(gpu, name)
        assert np.array_equal(a, b), f"{name}: {int((a != b).sum())} values differ"


@pytest.fixture(scope="module")
def octree():
    return build_octree(pillars(16))


def cameras(octree):
    lo, hi = octree.voxel_bounds
    yield orbit_camera(lo, hi, size=10)
    yield Camera.orthographic((8, 30, 8), (0.3, -1, 0.2), (0, 0, -1), view_height=18,
                              width=9, height=7)
    yield Camera.octahedral((8.3, 12.1, 7.7), resolution=8)


@pytest.mark.parametrize("lod", [0, 1, None])
def test_lod_renders_equal_the_cpu(octree, lod):
    for camera in cameras(octree):
        for beam in (True, False):
            _assert_same(render_lod(octree, camera, lod=lod, beam=beam, columns=False),
                         render_lod(octree, camera, lod=lod, beam=beam, device="cuda"))


def test_supersampled_reference_equals_the_cpu_packets_and_loop(octree):
    """The CPU traces these in packets (beam off) or the scalar loop (beam on): the GPU's
    per-pixel loop matches both."""
    camera = next(cameras(octree))
    for beam in (True, False):
        _assert_same(render_reference(octree, camera, side=2, beam=beam, columns=False),
                     render_reference(octree, camera, side=2, beam=beam, device="cuda"))


def test_random_scene_with_8bit_colours_and_the_device_arrays_kept():
    octree = build_octree(random_scene(2, n=300, size=16))
    camera = Camera.look_at((20, 18, -6), (8, 6, 8), fov_deg=60, width=8, height=6)
    first = render_lod(octree, camera, lod=0, device="cuda")
    again = render_lod(octree, camera, lod=0, device="cuda")
    _assert_same(render_lod(octree, camera, lod=0, columns=False), first)
    _assert_same(first, again)
    assert [k for k in octree.__dict__["_derived"] if k[0] == "cuda"] == [("cuda", "albedo")]


def test_the_gpu_benchmark_runs_and_finds_the_same_pixels(capsys, shared_data):
    """The benchmark's mountain recipe reads a real elevation model: skipped without it."""
    import importlib.util
    from pathlib import Path

    path = Path(__file__).parents[2] / "benchmarks" / "bench_gpu.py"
    spec = importlib.util.spec_from_file_location("bench_gpu", path)
    bench = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(bench)
    assert bench.main(["--footprint", "32", "--width", "8", "--height", "6", "--repeats",
                       "1", "--views", "oblique", "--probe-grid", "2x1x1",
                       "--probe-resolution", "4"]) == 0
    rows = [line for line in capsys.readouterr().out.splitlines()
            if line.startswith("| mountain")]
    assert len(rows) == 3 and all(row.endswith("| yes |") for row in rows)  # + light field


def test_adaptive_renders_equal_the_cpu(octree):
    """The first pass and every refinement run on the GPU; the variance that picks the
    pixels is the CPU's, so the same pixels refine and the image is the same."""
    camera = next(cameras(octree))
    cpu = render_adaptive(octree, camera, base_lod=1, variance_normalisation=0.01,
                          columns=False)
    gpu = render_adaptive(octree, camera, base_lod=1, variance_normalisation=0.01,
                          device="cuda")
    _assert_same(cpu, gpu)
    assert np.array_equal(cpu.maps["refinement_class"], gpu.maps["refinement_class"])
    assert (cpu.ray_count > 1).any()  # some pixels refined
