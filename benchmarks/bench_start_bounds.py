"""How much primary-ray time a tighter start bound could save, and what finer beams cost.

    python benchmarks/bench_start_bounds.py                    # mountain terrain, 2048²
    python benchmarks/bench_start_bounds.py --footprint 512 --repeats 5

The beam pass (``render.beam``) starts every ray of a pixel block where no ray of the block
can hit anything yet; most of a primary ray's traversal is then spent near the surface,
descending into nodes it passes beside. This measures two things on the same rays (512²,
one ray per pixel through the pixel centre, in the renderer's 8×8 tile order, LOD 0):

- **oracle starts**: every hitting ray started ``margin`` voxels before its own hit (never
  before its beam bound), for margins 16, 4 and 1. No renderer can know these distances in
  advance; the figures bound what any start-distance scheme (finer beams, cones, previous
  frames) could buy, at zero cost for finding them;
- **finer beams**: the beam pass with its block sides refined coarse to fine (each pass
  starts at its parent's bound), its own time plus the trace time.

Only the traversal is timed (``trace_ray`` over precomputed rays, two threads by default),
best of ``--repeats`` runs, the variants alternating run by run. Hits and times are checked
equal to the beam-start trace's for every variant: a start bound changes only the work.
"""

from __future__ import annotations

import argparse
import math
import sys
import time

import numpy as np

# First, so that Numba's kernel cache is the folder voxfield keys on its source digest (or
# the caller's NUMBA_CACHE_DIR): a fixed folder would keep kernels compiled against another
# file's old code after an edit.
import voxfield  # noqa: F401

MARGINS = (16.0, 4.0, 1.0)
BEAM_CHAINS = ((8,), (8, 4), (8, 4, 2), (8, 4, 2, 1))


def make_tracer():
    """A parallel loop of ``trace_ray`` over rays with their own start times."""
    from numba import njit, prange

    from voxfield.kernels.traversal import new_scratch, trace_ray

    @njit(nogil=True)
    def trace_chunk(origins, dirs, starts, inner, depth, first, last, t_hit, steps):
        scratch = new_scratch(depth)
        for k in range(first, last):
            node, _, t, _, n = trace_ray(
                origins[k, 0], origins[k, 1], origins[k, 2], dirs[k, 0], dirs[k, 1],
                dirs[k, 2], starts[k], math.inf, inner, depth, depth, 0.0, 0.0, scratch)
            t_hit[k] = t if node >= 0 else math.inf
            steps[k] = n

    @njit(nogil=True, parallel=True)
    def trace_all(origins, dirs, starts, inner, depth, t_hit, steps):
        n = origins.shape[0]
        chunk = 64
        for c in prange((n + chunk - 1) // chunk):
            trace_chunk(origins, dirs, starts, inner, depth, c * chunk,
                        min(n, (c + 1) * chunk), t_hit, steps)

    return trace_all


def build(recipe: str, footprint: int, seed: int):
    from voxfield.scene.terrain.recipes import recipe_layout
    from voxfield.svo.streamed_build import build_octree_streamed

    return build_octree_streamed(recipe_layout(recipe, footprint=footprint, seed=seed))


def rays_in_tile_order(camera):
    """One ray per pixel centre, pixels in the renderer's tile order, and their pixels."""
    from voxfield.render.primary import tile_order

    origins, dirs = camera.rays(side=1, seed=0)
    pixels = tile_order(camera.height, camera.width)
    return np.ascontiguousarray(origins[pixels]), np.ascontiguousarray(dirs[pixels]), pixels


def beam_starts(octree, camera, pixels, blocks) -> tuple[np.ndarray, float]:
    from voxfield.kernels.beam import start_distance
    from voxfield.render.beam import plan_beam

    beam = plan_beam(octree, camera, stop_level=octree.depth, blocks=blocks)
    rows, cols = np.divmod(pixels, camera.width)
    bounds = beam.bound[rows // beam.block, cols // beam.block]
    return np.array([start_distance(b) for b in bounds.ravel()]), beam.seconds


def run_view(octree, view: str, args, trace_all) -> list[dict]:
    from voxfield.render.camera import oblique_camera, top_down_camera

    lo, hi = octree.voxel_bounds
    camera = (top_down_camera(lo, hi, size=args.size, fov_deg=90) if view == "top"
              else oblique_camera(lo, hi, size=args.size, fov_deg=90, elevation_deg=45))
    origins, dirs, pixels = rays_in_tile_order(camera)
    n = len(origins)
    base, base_beam_s = beam_starts(octree, camera, pixels, BEAM_CHAINS[0])
    t_ref, steps = np.empty(n), np.empty(n, np.int64)
    trace_all(origins, dirs, base, octree.inner_nodes, octree.depth, t_ref, steps)
    lengths = np.linalg.norm(dirs, axis=1)
    hit = np.isfinite(t_ref)
    variants = {"beam (8,)": (base, base_beam_s)}
    for margin in MARGINS:
        starts = base.copy()
        starts[hit] = np.maximum(t_ref[hit] - margin / lengths[hit], base[hit])
        variants[f"oracle, {margin:g} voxels before the hit"] = (starts, 0.0)
    for blocks in BEAM_CHAINS[1:]:
        variants[f"beam {blocks}"] = beam_starts(octree, camera, pixels, blocks)
    best = dict.fromkeys(variants, math.inf)
    t_out = np.empty(n)
    for _ in range(args.repeats):
        for name, (starts, _) in variants.items():
            start = time.perf_counter()
            trace_all(origins, dirs, starts, octree.inner_nodes, octree.depth, t_out, steps)
            best[name] = min(best[name], time.perf_counter() - start)
            if not np.array_equal(t_out, t_ref):
                sys.exit(f"{view} {name}: hits differ from the beam-start trace")
    rows = []
    for name, (_, beam_s) in variants.items():
        total = best[name] + beam_s
        rows.append({"view": view, "start": name, "trace_ms": best[name] * 1e3,
                     "beam_ms": beam_s * 1e3, "mrays": n / total / 1e6,
                     "speedup": (best["beam (8,)"] + base_beam_s) / total})
    return rows


def main(argv=None) -> int:
    p = argparse.ArgumentParser(prog="bench_start_bounds", description=__doc__.splitlines()[0])
    p.add_argument("--recipe", default="mountain", help="terrain recipe (default mountain)")
    p.add_argument("--footprint", type=int, default=2048, help="columns per side (2048)")
    p.add_argument("--size", type=int, default=512, help="image side in pixels (512)")
    p.add_argument("--repeats", type=int, default=3, help="runs per variant, best kept (3)")
    p.add_argument("--threads", type=int, default=2, help="kernel threads (2)")
    p.add_argument("--seed", type=int, default=0, help="terrain scattering seed")
    args = p.parse_args(argv)
    if args.footprint < 8 or args.size < 8 or args.repeats < 1 or args.threads < 1:
        p.error("footprint and size must be at least 8, repeats and threads at least 1")
    import numba

    numba.set_num_threads(min(args.threads, numba.config.NUMBA_NUM_THREADS))
    octree = build(args.recipe, args.footprint, args.seed)
    trace_all = make_tracer()
    rows = []
    for view in ("top", "oblique"):
        rows += run_view(octree, view, args, trace_all)
    print(f"### Start bounds: {args.recipe} {args.footprint}², {args.size}² rays, 1 ray/px, "
          f"LOD 0, {numba.get_num_threads()} threads, best of {args.repeats}\n")
    print("| view | rays start at | beam pass ms | trace ms | Mrays/s | × beam (8,) |")
    print("|---|---|---:|---:|---:|---:|")
    for r in rows:
        print(f"| {r['view']} | {r['start']} | {r['beam_ms']:.0f} | {r['trace_ms']:.0f} | "
              f"{r['mrays']:.2f} | {r['speedup']:.2f} |")
    return 0


if __name__ == "__main__":
    from voxfield.cli.exits import report_failures

    raise SystemExit(report_failures("bench_start_bounds", main))
