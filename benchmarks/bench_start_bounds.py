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

A second table does the same for what the renderers run now: 16 rays a pixel through the
column-top walk (``surface_approach.trace_over_columns``) from the raster's whole-pixel
bounds (``render.beam.raster_beam``), against

- **per-stratum rasters**: the pyramid's level-L cells drawn into an image of the pixels'
  4×4 strata (each CMJ sample lies in its own), so that every ray starts at its stratum's
  bound, with the drawing's time (the pixels' direction limits serve their strata);
- **oracle starts**: every ray started where it first dips into a level-L cell box (the
  walk at level L from the camera), at no cost: what per-ray bounds at that level could buy.
"""

from __future__ import annotations

import argparse
import math
import sys
import time

import numpy as np

# First, so that Numba's kernel cache is the folder voxfield keys on its source digest
# (inside the caller's NUMBA_CACHE_DIR, if set): an unkeyed folder would keep kernels
# compiled against another file's old code after an edit.
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
    camera = view_camera(octree, view, args.size)
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


#: Sample grid side of the column-walk table: 16 rays a pixel, as the reference renders.
STRATA = 4
#: Pyramid levels of the per-stratum rasters and of the oracle starts.
STRATUM_LEVELS = (0, 1, 2)


def make_column_tracer():
    """A parallel loop of ``trace_over_columns`` (walk, then settle) over rays with their own
    start times, at LOD 0."""
    from numba import njit, prange

    from voxfield.kernels.surface_approach import approach_surface, trace_over_columns
    from voxfield.kernels.traversal import new_scratch

    @njit(nogil=True)
    def trace_chunk(rays, starts, inner, depth, columns, first, last, t_hit, steps):
        scratch = new_scratch(depth)
        for k in range(first, last):
            node, _, t, _, n = trace_over_columns(
                rays[k, 0], rays[k, 1], rays[k, 2], rays[k, 3], rays[k, 4], rays[k, 5],
                starts[k], math.inf, inner, depth, depth, scratch, columns)
            t_hit[k] = t if node >= 0 else math.inf
            steps[k] = n

    @njit(nogil=True, parallel=True)
    def trace_all(rays, starts, inner, depth, columns, t_hit, steps):
        n = rays.shape[0]
        chunk = 64
        for c in prange((n + chunk - 1) // chunk):
            trace_chunk(rays, starts, inner, depth, columns, c * chunk,
                        min(n, (c + 1) * chunk), t_hit, steps)

    @njit(nogil=True, parallel=True)
    def first_dips(rays, columns, level, depth, out):
        """Per ray, where it first dips into a level-``level`` cell box (inf: never)."""
        for k in prange(rays.shape[0]):
            verdict, t, _, cx, cz = approach_surface(
                rays[k, 0], rays[k, 1], rays[k, 2], rays[k, 3], rays[k, 4], rays[k, 5], 0.0,
                math.inf, level, depth, columns)
            if verdict == 0:
                out[k] = math.inf
                continue
            # A falling ray crosses the cell's top (rounded up to the level) inside the cell.
            top = columns.tops[columns.level_offset[level] + cx * columns.level_depth[level]
                               + cz]
            top = (top + (1 << level) - 1) & ~((1 << level) - 1)
            dy = rays[k, 4]
            out[k] = max(t, (top - rays[k, 1]) / dy) if dy < 0.0 else t

    return trace_all, first_dips


def stratum_bounds(camera, columns, level: int, repeats: int) -> tuple[np.ndarray, float]:
    """The level-``level`` cells drawn into the (4H)×(4W) image of the pixels' strata, each
    bound holding for every ray through its stratum; and the least seconds it took in
    ``repeats`` drawings."""
    import dataclasses

    import numba

    from voxfield.kernels.column_raster import direction_limits, draw_cell_boxes

    strata = dataclasses.replace(camera, width=camera.width * STRATA,
                                 height=camera.height * STRATA)
    cam = strata.params
    to_camera = np.linalg.inv(np.array([cam[4:7], cam[7:10], cam[10:13]]).T)
    parts = numba.get_num_threads()
    best = math.inf
    for _ in range(repeats):
        start = time.perf_counter()
        # A stratum's rays are among its pixel's: the pixel's limits hold for it.
        pixel_limits = direction_limits(camera.params, camera.width, camera.height, 0.5)
        seconds = time.perf_counter() - start
        limits = np.repeat(np.repeat(pixel_limits, STRATA, axis=0), STRATA, axis=1)
        nearest = np.full((parts, strata.height, strata.width), np.inf)
        drawn = np.zeros(parts, np.int64)
        start = time.perf_counter()
        ok = draw_cell_boxes(cam, to_camera, strata.width, strata.height, columns.tops,
                             columns.floors, int(columns.level_offset[level]),
                             int(columns.level_width[level]), int(columns.level_depth[level]),
                             level, 0, 0.5, limits, parts, nearest, drawn)
        if not ok:
            sys.exit("a cell box reaches the camera's eye plane: no raster bounds")
        bound = nearest.min(axis=0)
        best = min(best, seconds + time.perf_counter() - start)
    return bound, best


def run_columns_view(octree, columns, view: str, args, tracers) -> list[dict]:
    from voxfield.kernels.beam import start_distance
    from voxfield.render.beam import pixel_start_bounds
    from voxfield.render.primary import tile_order

    trace_all, first_dips = tracers
    camera = view_camera(octree, view, args.size)
    spp = STRATA * STRATA
    origins, dirs = camera.rays(side=STRATA, seed=0)  # pixel after pixel, samples j·4 + i
    order = (np.arange(len(origins)).reshape(-1, spp)
             [tile_order(camera.height, camera.width)].ravel())
    rays = np.ascontiguousarray(np.concatenate([origins, dirs], axis=1)[order])
    pixel, sample = np.divmod(order, spp)
    row, col = np.divmod(pixel, camera.width)
    j, i = np.divmod(sample, STRATA)
    to_start = np.vectorize(start_distance, otypes=[float])
    whole = pixel_start_bounds(octree, camera, columns, stop_level=octree.depth,
                               side=STRATA, whole_pixel=True)
    variants = {"whole-pixel raster (the renderer's)":
                (to_start(whole.bound[row, col]), whole.seconds)}
    for level in STRATUM_LEVELS:
        bound, seconds = stratum_bounds(camera, columns, level, args.repeats)
        variants[f"per-stratum raster, level {level}"] = (
            to_start(bound[STRATA * row + j, STRATA * col + i]), seconds)
    for level in STRATUM_LEVELS:
        dips = np.empty(len(rays))
        first_dips(rays, columns, level, octree.depth, dips)
        variants[f"oracle: first level-{level} box"] = (to_start(dips), 0.0)
    n = len(rays)
    base = next(iter(variants))
    t_ref, steps = np.empty(n), np.empty(n, np.int64)
    trace_all(rays, variants[base][0], octree.inner_nodes, octree.depth, columns, t_ref, steps)
    best = dict.fromkeys(variants, math.inf)
    cells = {}
    t_out = np.empty(n)
    for _ in range(args.repeats):
        for name, (starts, _) in variants.items():
            start = time.perf_counter()
            trace_all(rays, starts, octree.inner_nodes, octree.depth, columns, t_out, steps)
            best[name] = min(best[name], time.perf_counter() - start)
            cells[name] = steps.mean()
            if not np.array_equal(t_out, t_ref):
                sys.exit(f"{view} {name}: hits differ from the whole-pixel-bound trace")
    rows = []
    for name, (_, bound_s) in variants.items():
        total = best[name] + bound_s
        rows.append({"view": view, "start": name, "trace_ms": best[name] * 1e3,
                     "beam_ms": bound_s * 1e3, "steps": cells[name], "mrays": n / total / 1e6,
                     "speedup": (best[base] + variants[base][1]) / total})
    return rows


def view_camera(octree, view: str, size: int):
    from voxfield.render.camera import oblique_camera, top_down_camera

    lo, hi = octree.voxel_bounds
    return (top_down_camera(lo, hi, size=size, fov_deg=90) if view == "top"
            else oblique_camera(lo, hi, size=size, fov_deg=90, elevation_deg=45))


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
    from voxfield.svo.column_tops import octree_column_tops

    columns = octree_column_tops(octree)
    tracers = make_column_tracer()
    rows = []
    for view in ("top", "oblique"):
        rows += run_columns_view(octree, columns, view, args, tracers)
    print(f"\n### Start bounds for the column walk: {args.recipe} {args.footprint}², "
          f"{args.size}² pixels, {STRATA * STRATA} rays/px, LOD 0, "
          f"{numba.get_num_threads()} threads, best of {args.repeats}\n")
    print("| view | rays start at | bounds ms | trace ms | steps/ray | Mrays/s "
          "| × whole-pixel raster |")
    print("|---|---|---:|---:|---:|---:|---:|")
    for r in rows:
        print(f"| {r['view']} | {r['start']} | {r['beam_ms']:.1f} | {r['trace_ms']:.0f} | "
              f"{r['steps']:.2f} | {r['mrays']:.2f} | {r['speedup']:.2f} |")
    return 0


if __name__ == "__main__":
    from voxfield.cli.exits import report_failures

    raise SystemExit(report_failures("bench_start_bounds", main))
