"""Primary-ray and light-field throughput on a CUDA GPU beside the CPU, same rays, same run.

    pip install -e ".[cuda]"                          # numba-cuda with CUDA 12 wheels
    python benchmarks/bench_gpu.py                    # mountain 2048², 1920×1080, 1 and 16 rays/px
    python benchmarks/bench_gpu.py --footprint 2048 8192 --repeats 5
    python benchmarks/bench_gpu.py --check-ptx        # no GPU: compile the kernel to sm_90 PTX

Rows: the reference (16 rays/px) and LOD-0 (1 ray/px) renderers, top-down and 45° views,
and the light-field trace from a probe layer over the terrain (``--probe-grid``),
``device="cuda"`` against ``device="cpu"``, beam off on both (the beam pass runs on the CPU
and would time the CPU). GPU figures are kernel time (the first launch, which compiles, and
the one-off octree upload are excluded); every GPU image, depth map and
step map is compared with the CPU's, and any difference is printed. The error-aware renderer
has no CUDA kernel yet: the script says so rather than guess.

``--check-ptx`` needs only ``numba-cuda``: numba-cuda asks the (absent) device for its compute
capability when compiling device functions, so the check answers that query with 9.0 (an
H200) and compiles the primary kernel for both colour storages and the light-field kernel.
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
import time

import numpy as np

from voxfield.cli.exits import report_failures
from voxfield.cli.options import int_at_least, int_between
from voxfield.errors import VoxfieldError
from voxfield.scene.terrain import MAX_FOOTPRINT


def camera(octree, view: str, width: int, height: int):
    from voxfield.render.camera import oblique_camera, top_down_camera

    lo, hi = octree.voxel_bounds
    square = (top_down_camera(lo, hi, size=height, fov_deg=90) if view == "top"
              else oblique_camera(lo, hi, size=height, fov_deg=90, elevation_deg=45))
    return dataclasses.replace(square, width=width, half_width=square.half_height * width
                               / height)


def best_seconds(render, repeats: int):
    best, result = float("inf"), None
    for _ in range(repeats):
        start = time.perf_counter()
        result = render()
        best = min(best, time.perf_counter() - start)
    return best, result


def differences(cpu, gpu) -> list[str]:
    return [f"{name}: {int((getattr(cpu, name) != getattr(gpu, name)).sum())} differ"
            for name in ("image", "depth", "normal", "hit_count", "steps", "finest_lod")
            if not np.array_equal(getattr(cpu, name), getattr(gpu, name))]


def run(args) -> int:
    from voxfield.render.device import cuda_available
    from voxfield.render.primary import render_lod, render_reference
    from voxfield.scene.terrain.recipes import recipe_layout
    from voxfield.svo.streamed_build import build_octree_streamed

    if not cuda_available():
        print("bench_gpu: no CUDA GPU is visible (see --check-ptx for a GPU-less check)",
              file=sys.stderr)
        return 2
    from numba import cuda

    name = cuda.get_current_device().name if hasattr(cuda, "get_current_device") else "simulator"
    name = name.decode() if isinstance(name, bytes) else name
    print(f"GPU: {name}, CPU threads: {args.threads or 'all'}")
    print("\n| scene | view | rays/px | GPU Mrays/s | GPU Gsteps/s | CPU Mrays/s | GPU/CPU "
          "| same pixels |")
    print("|---|---|---:|---:|---:|---:|---:|---|")
    for footprint in args.footprint:
        octree = build_octree_streamed(recipe_layout(args.recipe, footprint=footprint))
        for view in args.views:
            cam = camera(octree, view, args.width, args.height)
            for side in args.spp_side:
                # The GPU walks the octree alone; so does the CPU render it is held to
                # (the same steps), without the column-top walk.
                def on(device, octree=octree, cam=cam, side=side):
                    if side == 1:
                        return render_lod(octree, cam, lod=0, device=device, beam=False,
                                          threads=args.threads, columns=False)
                    return render_reference(octree, cam, side=side, device=device,
                                            beam=False, threads=args.threads, columns=False)
                on("cuda")  # compile and upload
                _, gpu = best_seconds(lambda: on("cuda"), args.repeats)
                _, cpu = best_seconds(lambda: on("cpu"), args.cpu_repeats)
                rays = gpu.total_rays
                diff = differences(cpu, gpu)
                gpu_mrays = rays / gpu.seconds / 1e6
                gpu_gsteps = gpu.total_steps / gpu.seconds / 1e9
                print(f"| {args.recipe} {footprint}² | {view} | {side * side} | "
                      f"{gpu_mrays:,.0f} | {gpu_gsteps:.2f} | {rays / cpu.seconds / 1e6:.2f} | "
                      f"{cpu.seconds / gpu.seconds:,.0f}× | "
                      f"{'yes' if not diff else '; '.join(diff)} |", flush=True)
        probe_rows(octree, f"{args.recipe} {footprint}²", args)
    print("\nThe error-aware renderer has no CUDA kernel yet.")
    return 0


def probe_rows(octree, scene: str, args) -> None:
    """The light-field trace of each view from a probe layer over the terrain (``--probe-grid``
    at ``--probe-resolution``²), on the GPU and the CPU: one ray per pixel."""
    from voxfield.lightfield import PackedProbes
    from voxfield.lightfield.probe_render import render_from_probes
    from voxfield.probes.bake import bake_probes
    from voxfield.probes.grid import parse_grid
    from voxfield.probes.probe_set import BakeOptions

    grid = parse_grid(args.probe_grid, octree.voxel_bounds, octree)
    probe_set = bake_probes(octree, grid, BakeOptions(resolution=args.probe_resolution,
                                                      renderer="lod", lod=0))
    packed = PackedProbes.from_probe_set(probe_set)
    print("\n| scene | probes | view | GPU Mrays/s | CPU Mrays/s | GPU/CPU | fetches/ray "
          "| same pixels |\n|---|---|---|---:|---:|---:|---:|---|")
    for view in args.views:
        cam = camera(octree, view, args.width, args.height)

        def on(device, cam=cam):
            return render_from_probes(packed, cam, packed=packed, device=device,
                                      threads=args.threads)
        on("cuda")  # compile and upload
        _, gpu = best_seconds(lambda: on("cuda"), args.repeats)
        _, cpu = best_seconds(lambda: on("cpu"), args.cpu_repeats)
        rays = cam.width * cam.height
        same = all(np.array_equal(getattr(cpu, n), getattr(gpu, n))
                   for n in ("image", "depth", "steps"))
        print(f"| {scene} | {args.probe_grid} at {args.probe_resolution}² | {view} | "
              f"{rays / gpu.seconds / 1e6:,.0f} | {rays / cpu.seconds / 1e6:.2f} | "
              f"{cpu.seconds / gpu.seconds:,.0f}× | {gpu.maps['texel_fetches'].mean():.1f} | "
              f"{'yes' if same else 'no'} |", flush=True)


def check_ptx() -> int:
    from types import SimpleNamespace

    from voxfield.render.device import numba_cuda_installed

    if not numba_cuda_installed():  # Numba's own, deprecated CUDA target cannot compile them
        raise VoxfieldError("--check-ptx compiles with numba-cuda: pip install -e '.[cuda]'")
    import numba.cuda.dispatcher as cuda_dispatcher
    from numba import cuda, types

    cuda_dispatcher.get_current_device = lambda: SimpleNamespace(compute_capability=(9, 0))
    from voxfield.kernels import cuda_primary

    cuda_primary.cuda = cuda
    f64, i64 = types.float64, types.int64
    for colours in (types.uint8[:, ::1], types.float32[:, ::1]):
        signature = (f64[::1], i64, i64, i64[::1], i64, i64, i64[::1], i64, i64, f64, colours,
                     types.uint8[:, :, ::1], f64[:, ::1], i64, types.float32[:, ::1],
                     types.float32[::1], types.float32[:, ::1], types.int32[::1],
                     types.int32[::1], i64[::1], types.int8[::1])
        ptx, _ = cuda.compile_ptx(cuda_primary._render_pixels_cuda, signature, cc=(9, 0))
        local = next((line.split()[-1] for line in ptx.splitlines()
                      if "__local_depot" in line and ".local" in line), "none")
        print(f"colours {colours.dtype}: sm_90 PTX {len(ptx):,} characters, "
              f"per-thread local memory {local}")
    check_probe_ptx(cuda)
    return 0


def tiny_probe_set():
    """Two baked 8² probes over a small built-in scene: argument types for the probe kernel."""
    from voxfield.lightfield import PackedProbes
    from voxfield.probes.bake import bake_probes
    from voxfield.probes.grid import ProbeGrid
    from voxfield.probes.probe_set import BakeOptions
    from voxfield.scene.builtin import pillars
    from voxfield.svo import build_octree

    grid = ProbeGrid([4.5, 9.5, 4.5], [7.0, 1.0, 7.0], [2, 1, 1])
    return PackedProbes.from_probe_set(bake_probes(
        build_octree(pillars(16)), grid, BakeOptions(resolution=8, renderer="lod", lod=0)))


def check_probe_ptx(cuda) -> None:
    """Compile the light-field trace kernel for sm_90, with the argument types a trace
    passes (``lightfield.cuda_trace.kernel_arguments``)."""
    import numba

    from voxfield.kernels import cuda_probe
    from voxfield.lightfield.cuda_trace import kernel_arguments
    from voxfield.lightfield.trace import LightFieldHits, LightFieldOptions

    cuda_probe.cuda = cuda
    packed = tiny_probe_set()
    n = 4
    out = LightFieldHits.empty(n)
    rays = (np.zeros((n, 3)), np.ones((n, 3)), np.zeros(n), np.full(n, np.inf))
    modes = (0, 0, 0, True, LightFieldOptions().params(0.0))
    signature = tuple(numba.typeof(a) for a in kernel_arguments(packed, modes, rays, out))
    ptx, _ = cuda.compile_ptx(cuda_probe._trace_light_field_cuda, signature, cc=(9, 0))
    local = next((line.split()[-1] for line in ptx.splitlines()
                  if "__local_depot" in line and ".local" in line), "none")
    print(f"light-field trace: sm_90 PTX {len(ptx):,} characters, per-thread local memory "
          f"{local}")


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="bench_gpu", description=__doc__.split("\n")[0])
    parser.add_argument("--recipe", default="mountain")
    count = int_at_least(1)
    parser.add_argument("--footprint", type=int_between(2, MAX_FOOTPRINT), nargs="+",
                        default=[2048])
    parser.add_argument("--views", nargs="+", choices=("top", "oblique"),
                        default=["top", "oblique"])
    parser.add_argument("--spp-side", type=int_between(1, 16), nargs="+", default=[1, 4])
    parser.add_argument("--width", type=count, default=1920)
    parser.add_argument("--height", type=count, default=1080)
    parser.add_argument("--repeats", type=count, default=5)
    parser.add_argument("--cpu-repeats", type=count, default=1)
    parser.add_argument("--threads", type=count, default=None, help="CPU threads (default all)")
    parser.add_argument("--probe-grid", default="surface:8x8@24",
                        help="probe layer of the light-field rows (default surface:8x8@24)")
    parser.add_argument("--probe-resolution", type=count, default=256)
    parser.add_argument("--check-ptx", action="store_true")
    args = parser.parse_args(argv)
    return check_ptx() if args.check_ptx else run(args)


if __name__ == "__main__":
    sys.exit(report_failures("bench_gpu", main))
