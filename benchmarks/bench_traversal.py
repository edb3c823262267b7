"""Primary-ray throughput of voxfield's SVO traversal, side by side with Embree (issue 2).

    python benchmarks/bench_traversal.py                       # mountain terrain, 2048² and 512²
    python benchmarks/bench_traversal.py --footprint 512 --repeats 5
    python benchmarks/bench_traversal.py --no-peer             # voxfield alone

Both tracers see the same solid and exactly the same rays: Embree (through Open3D's
``RaycastingScene``) traces the exposed-face mesh of the octree's LOD-0 voxels
(``voxfield.scene.surface.exposed_faces``), fed the rays ``Camera.rays`` generates — the
same CMJ samples the voxfield renderers trace. voxfield is timed in its renderers
(``render_lod`` at LOD 0, 1 ray/pixel; ``render_reference``, 16 rays/pixel), which also
shade; Embree's ``cast_rays`` returns t, ids, barycentrics and normals. Compile time is
excluded (a tiny warm-up render), each figure is the best of ``--repeats`` runs.

Agreement: the same float32 rays Embree gets (widened back to float64) go through
``voxfield.kernels.ray_batch.trace_rays``; we report the fraction whose hit/miss matches and
the median |t_voxfield − t_embree| over rays both hit.

Memory: voxfield's figure is every octree array (the whole renderable structure); Embree's
is the mesh arrays handed to it plus the process RSS growth over ``add_triangles`` and the
BVH build (Embree's own buffers and BVH, which Open3D does not expose).

The peer is optional: ``pip install -e .[peer]`` (Open3D, ~900 MB wheel) and, on Debian or
Ubuntu, ``apt-get install libusb-1.0-0`` (``import open3d`` needs ``libusb-1.0.so.0``).
"""

from __future__ import annotations

import argparse
import gc
import math
import os
import sys
import time
from dataclasses import dataclass, field

import numpy as np

os.environ.setdefault(
    "NUMBA_CACHE_DIR", os.path.join(os.path.dirname(__file__), "..", ".numba_cache")
)

PEER_HELP = (
    "Embree peer unavailable ({reason}); install it with `pip install -e .[peer]` "
    "(Open3D) and `apt-get install libusb-1.0-0` (needed by `import open3d`)."
)


def rss_mib() -> float:
    """Resident set size of this process (VmRSS), MiB; NaN where /proc is missing."""
    try:
        with open("/proc/self/status") as f:
            for line in f:
                if line.startswith("VmRSS:"):
                    return int(line.split()[1]) / 1024
    except OSError:
        pass
    return float("nan")


def load_open3d():
    """(module, None) or (None, why it could not be imported)."""
    try:
        import open3d as o3d  # noqa: PLC0415 - optional, heavy

        return o3d, None
    except (ImportError, OSError) as exc:  # OSError: a missing shared library
        return None, str(exc)


@dataclass
class SceneStats:
    name: str
    voxels: int = 0
    nodes: int = 0
    depth: int = 0
    scene_s: float = 0.0
    octree_s: float = 0.0
    octree_mib: float = 0.0
    kernel_mib: float = 0.0
    triangles: int = 0
    vertices: int = 0
    mesh_s: float = 0.0
    mesh_mib: float = 0.0
    embree_build_s: float = float("nan")
    embree_rss_mib: float = float("nan")
    rows: list = field(default_factory=list)


def octree_bytes(octree) -> int:
    arrays = [octree.child_mask, octree.first_child, octree.node_coord, octree.level_offsets]
    return sum(a.nbytes for a in arrays) + sum(a.nbytes for a in octree.attributes.values())


def build_scene(args, footprint: int):
    """The terrain the issue names: a real DEM (``--recipe``) at ``footprint``² columns."""
    from voxfield.scene.terrain import recipe_scene
    from voxfield.svo import build_octree

    t0 = time.perf_counter()
    scene = recipe_scene(args.recipe, footprint=footprint, seed=args.seed)
    t1 = time.perf_counter()
    octree = build_octree(scene)
    t2 = time.perf_counter()
    stats = SceneStats(
        name=f"{args.recipe} {footprint}²", voxels=len(scene), nodes=octree.node_count,
        depth=octree.depth, scene_s=t1 - t0, octree_s=t2 - t1,
        octree_mib=octree_bytes(octree) / 2**20,
        kernel_mib=octree.inner_nodes.nbytes / 2**20,
    )
    return octree, stats


def warm_up() -> None:
    """Compile every kernel we time on a tiny scene, so JIT time is not measured."""
    from voxfield.render.camera import top_down_camera
    from voxfield.render.renderers import render_lod, render_reference
    from voxfield.scene.voxel_scene import VoxelScene
    from voxfield.svo import build_octree

    rng = np.random.default_rng(0)
    coords = rng.integers(0, 8, size=(64, 3))
    tiny = build_octree(VoxelScene(coords, rng.random((64, 3)), name="warm-up").dedupe())
    cam = top_down_camera(*tiny.voxel_bounds, size=8)
    render_lod(tiny, cam, lod=0)
    render_reference(tiny, cam, side=4)
    o, d = cam.rays(side=1, seed=0)
    voxfield_trace(tiny, o, d)


def voxfield_trace(octree, origins, directions, threads=None):
    """Per-ray (hit?, t, steps) from the batch kernel at LOD 0."""
    from voxfield.render.ray_query import trace

    hits = trace(octree, origins, directions, lod=0, threads=threads)
    return hits.hit, hits.t, hits.steps


def best_of(repeats: int, fn):
    """(best seconds, last result) over ``repeats`` calls of ``fn() -> (seconds, result)``."""
    best = math.inf
    result = None
    for _ in range(repeats):
        seconds, result = fn()
        best = min(best, seconds)
    return best, result


def build_embree(o3d, octree, stats: SceneStats, args):
    """Mesh the voxels, hand the mesh to Embree and force the BVH build (a 1-ray query)."""
    from voxfield.scene.surface import exposed_faces

    t0 = time.perf_counter()
    vertices, triangles = exposed_faces(octree, 0, shared_vertices=not args.split_vertices)
    stats.mesh_s = time.perf_counter() - t0
    stats.vertices, stats.triangles = len(vertices), len(triangles)
    stats.mesh_mib = (vertices.nbytes + triangles.nbytes) / 2**20
    gc.collect()
    rss0 = rss_mib()
    t0 = time.perf_counter()
    scene = o3d.t.geometry.RaycastingScene(nthreads=args.threads)
    scene.add_triangles(
        o3d.core.Tensor.from_numpy(vertices),
        o3d.core.Tensor.from_numpy(triangles.view(np.uint32)),
    )
    # Open3D builds the BVH lazily, on the first query.
    scene.cast_rays(o3d.core.Tensor(np.zeros((1, 6), np.float32)), nthreads=args.threads)
    stats.embree_build_s = time.perf_counter() - t0
    stats.embree_rss_mib = rss_mib() - rss0
    del vertices, triangles
    gc.collect()
    return scene


def run_view(o3d, embree, octree, stats: SceneStats, view: str, side: int, args) -> None:
    from voxfield.render.camera import oblique_camera, top_down_camera
    from voxfield.render.renderers import render_lod, render_reference

    lo, hi = octree.voxel_bounds
    if view == "top":
        cam = top_down_camera(lo, hi, size=args.size, fov_deg=90)
    else:
        cam = oblique_camera(lo, hi, size=args.size, fov_deg=90, elevation_deg=45)

    def vox():
        if side == 1:
            r = render_lod(octree, cam, lod=0, threads=args.threads)
        else:
            r = render_reference(octree, cam, side=side, threads=args.threads)
        return r.seconds, r

    vox_s, res = best_of(args.repeats, vox)
    row = {
        "view": view, "spp": side * side, "rays": res.total_rays,
        "vox_mrays": res.total_rays / vox_s / 1e6,
        "steps_per_ray": res.total_steps / res.total_rays,
        "hit_frac": res.hit_count.sum() / res.total_rays,
    }
    if embree is not None:
        origins, directions = cam.rays(side=side, seed=0)
        rays32 = np.concatenate([origins, directions], axis=1).astype(np.float32)
        del origins, directions
        tensor = o3d.core.Tensor.from_numpy(rays32)

        def cast():
            t0 = time.perf_counter()
            out = embree.cast_rays(tensor, nthreads=args.threads)
            return time.perf_counter() - t0, out

        emb_s, out = best_of(args.repeats, cast)
        t_emb = out["t_hit"].numpy().astype(np.float64)
        del out
        row["emb_mrays"] = len(rays32) / emb_s / 1e6
        row["ratio"] = row["vox_mrays"] / row["emb_mrays"]
        if args.occlusions:

            def occlude():
                t0 = time.perf_counter()
                out = embree.test_occlusions(tensor, nthreads=args.threads)
                return time.perf_counter() - t0, out

            occ_s, _ = best_of(args.repeats, occlude)
            row["occ_mrays"] = len(rays32) / occ_s / 1e6
        # Agreement on the identical (float32) rays, through voxfield's batch kernel (also
        # timed: same inputs as Embree, no ray generation or shading).
        wide = rays32.astype(np.float64)
        origins, directions = np.ascontiguousarray(wide[:, :3]), np.ascontiguousarray(wide[:, 3:])

        def batch():
            t0 = time.perf_counter()
            out = voxfield_trace(octree, origins, directions, args.threads)
            return time.perf_counter() - t0, out

        batch_s, (hit_v, t_v, _) = best_of(args.repeats, batch)
        row["batch_mrays"] = len(wide) / batch_s / 1e6
        hit_e = np.isfinite(t_emb)
        agree = hit_v == hit_e
        both = hit_v & hit_e
        dt = np.abs(t_v[both] - t_emb[both])
        row["agree"] = agree.mean()
        row["only_vox"] = int((hit_v & ~hit_e).sum())
        row["only_emb"] = int((hit_e & ~hit_v).sum())
        row["dt_median"] = float(np.median(dt)) if len(dt) else 0.0
        row["dt_p999"] = float(np.quantile(dt, 0.999)) if len(dt) else 0.0
        del origins, directions, dt
        if args.report_mismatches and not agree.all():
            report_mismatches(wide, hit_v, t_v, hit_e, t_emb, side, args.size)
        del rays32, tensor, wide, t_emb
    stats.rows.append(row)
    print(f"  {stats.name} {view} {side * side} rays/px: {fmt_row(row)}", file=sys.stderr)


def report_mismatches(rays, hit_v, t_v, hit_e, t_e, side, size, limit=8) -> None:
    """Print the first few rays the two tracers disagree on, for investigation."""
    bad = np.flatnonzero(hit_v != hit_e)
    spp = side * side
    print(f"    {len(bad)} hit/miss mismatches; first {min(limit, len(bad))}:", file=sys.stderr)
    for i in bad[:limit]:
        pixel, sample = divmod(int(i), spp)
        row, col = divmod(pixel, size)
        o, d = rays[i, :3], rays[i, 3:]
        print(
            f"      ray {i} (pixel {row},{col} sample {sample}) o={o.tolist()} d={d.tolist()} "
            f"voxfield t={t_v[i]:.6g} embree t={t_e[i]:.6g}",
            file=sys.stderr,
        )


def fmt_row(row: dict) -> str:
    return ", ".join(f"{k}={v:.4g}" if isinstance(v, float) else f"{k}={v}" for k, v in row.items())


def num(v, spec: str) -> str:
    return "—" if v is None or (isinstance(v, float) and math.isnan(v)) else format(v, spec)


def print_tables(all_stats: list[SceneStats], peer: bool, args) -> None:
    print(f"\n### Primary-ray throughput ({args.size}² image, 90° FOV, LOD 0, "
          f"{args.threads} threads, best of {args.repeats})\n")
    head = ["scene", "view", "rays/px", "rays", "voxfield Mrays/s", "steps/ray", "hit %"]
    if peer:
        head += ["Embree Mrays/s", "voxfield/Embree", "voxfield batch Mrays/s"]
        if args.occlusions:
            head += ["Embree occl. Mrays/s"]
        head += ["hit/miss agree", "only vox / only Embree", "median |Δt|", "99.9% |Δt|"]
    print("| " + " | ".join(head) + " |")
    print("|" + "|".join("---" for _ in head) + "|")
    for s in all_stats:
        for r in s.rows:
            cells = [s.name, r["view"], str(r["spp"]), f"{r['rays']:,}",
                     num(r["vox_mrays"], ".2f"), num(r["steps_per_ray"], ".1f"),
                     num(100 * r["hit_frac"], ".1f")]
            if peer:
                cells += [num(r.get("emb_mrays"), ".2f"), num(r.get("ratio"), ".2f"),
                          num(r.get("batch_mrays"), ".2f")]
                if args.occlusions:
                    cells += [num(r.get("occ_mrays"), ".2f")]
                cells += [f"{100 * r['agree']:.4f} %", f"{r['only_vox']} / {r['only_emb']}",
                          num(r["dt_median"], ".2g"), num(r["dt_p999"], ".2g")]
            print("| " + " | ".join(cells) + " |")
    print("\n### Build time and memory\n")
    head = ["scene", "voxels", "octree nodes", "octree MiB (traced)", "scene load s",
            "octree build s"]
    if peer:
        head += ["triangles", "vertices", "mesh MiB", "mesh extraction s", "Embree build s",
                 "Embree RSS growth MiB"]
    print("| " + " | ".join(head) + " |")
    print("|" + "|".join("---" for _ in head) + "|")
    for s in all_stats:
        cells = [s.name, f"{s.voxels:,}", f"{s.nodes:,}",
                 f"{s.octree_mib:.0f} ({s.kernel_mib:.0f})",
                 f"{s.scene_s:.1f}", f"{s.octree_s:.1f}"]
        if peer:
            cells += [f"{s.triangles:,}", f"{s.vertices:,}", f"{s.mesh_mib:.0f}",
                      f"{s.mesh_s:.1f}", num(s.embree_build_s, ".1f"),
                      num(s.embree_rss_mib, ".0f")]
        print("| " + " | ".join(cells) + " |")
    print()
    print("voxfield MiB: every octree array (masks, child offsets, node coordinates, colours); "
          "in brackets what the traversal reads (one packed descriptor per inner node). "
          "voxfield Mrays/s: its renderers, ray generation and shading included.")
    if peer:
        print("Embree: the mesh arrays handed over (float32 vertices, uint32 triangles) and the "
              "RSS growth over add_triangles + BVH build; Mrays/s from cast_rays. 'voxfield "
              "batch' is voxfield's trace_rays on exactly the rays cast_rays gets; agreement "
              "and |Δt| (voxel units) compare those two on every ray.")
    try:
        load = os.getloadavg()
        print(f"Load average at the end: {load[0]:.2f} {load[1]:.2f} {load[2]:.2f} "
              f"on {os.cpu_count()} CPUs.")
    except OSError:
        pass


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--recipe", default="mountain",
                   help="terrain recipe (real DEM) from voxfield.scene.terrain (default mountain)")
    p.add_argument("--footprint", type=int, nargs="+", default=[2048, 512],
                   help="terrain footprints (columns per side) to run (default 2048 512)")
    p.add_argument("--views", nargs="+", default=["top", "oblique"], choices=["top", "oblique"])
    p.add_argument("--spp-side", type=int, nargs="+", default=[1, 4],
                   help="rays per pixel side: 1 = LOD renderer, >1 = reference (default 1 4)")
    p.add_argument("--size", type=int, default=512, help="image side in pixels (default 512)")
    p.add_argument("--repeats", type=int, default=3, help="timed runs per figure (best counts)")
    p.add_argument("--threads", type=int, default=2, help="threads for both tracers (default 2)")
    p.add_argument("--seed", type=int, default=0, help="terrain asset scattering seed")
    p.add_argument("--no-peer", action="store_true", help="run voxfield alone")
    p.add_argument("--occlusions", action="store_true",
                   help="also time Embree's test_occlusions (any-hit) on the same rays")
    p.add_argument("--split-vertices", action="store_true",
                   help="four vertices per face instead of shared lattice corners")
    p.add_argument("--report-mismatches", action="store_true",
                   help="print the first rays on which the tracers disagree about hit/miss")
    args = p.parse_args(argv)

    o3d, why = (None, "--no-peer") if args.no_peer else load_open3d()
    if o3d is None and not args.no_peer:
        print(PEER_HELP.format(reason=why), file=sys.stderr)
    print("compiling kernels (warm-up)...", file=sys.stderr)
    warm_up()
    all_stats = []
    for footprint in args.footprint:
        print(f"building {args.recipe} at {footprint}²...", file=sys.stderr)
        octree, stats = build_scene(args, footprint)
        gc.collect()
        embree = build_embree(o3d, octree, stats, args) if o3d is not None else None
        print(f"  {fmt_row({k: v for k, v in vars(stats).items() if k != 'rows'})}",
              file=sys.stderr)
        for view in args.views:
            for side in args.spp_side:
                run_view(o3d, embree, octree, stats, view, side, args)
        all_stats.append(stats)
        del octree, embree
        gc.collect()
    print_tables(all_stats, o3d is not None, args)
    if o3d is None:
        print("\n" + PEER_HELP.format(reason=why))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
