"""Ray throughput and memory of voxfield's SVO traversal, side by side with Embree.

    python benchmarks/bench_traversal.py                       # mountain terrain, 2048² and 512²
    python benchmarks/bench_traversal.py --footprint 512 --repeats 5
    python benchmarks/bench_traversal.py --big 8192            # also stream-build an 8192² world
    python benchmarks/bench_traversal.py --no-peer             # voxfield alone

Both tracers see the same solid and exactly the same rays: Embree (through Open3D's
``RaycastingScene``) traces the exposed-face mesh of the octree's LOD-0 voxels
(``voxfield.scene.surface.exposed_faces``), fed the rays ``Camera.rays`` generates — the
same CMJ samples the voxfield renderers trace. voxfield is timed in its renderers
(``render_lod`` at LOD 0, 1 ray/pixel; ``render_reference``, 16 rays/pixel), which also
shade and include their beam pass; Embree's ``cast_rays`` returns t, ids, barycentrics and
normals. Compile time is excluded (a tiny warm-up render), each figure is the best of
``--repeats`` runs, and the two tracers alternate run by run, so a busy machine slows both.
The paired column divides Embree's seconds by voxfield's round by round (the two ran back
to back) and gives their median and range: on a shared machine whose speed drifts by tens of
percent over minutes, the ratio of the two bests can pair a fast moment with a slow one.

Rows:
- primary rays, beam on (the default) and off (every ray starts at the camera), each with the
  column-top walk (the default: rays cross the air in the pyramid of column tops first,
  ``kernels.surface_approach``) and through the octree alone; with 16 rays/pixel and the
  octree alone, or without a beam, the renderer traces in packets
  (``kernels.packet_traversal``);
- incoherent secondary rays: cosine-weighted directions from random points on voxel tops,
  voxfield's any-hit ``ray_query.occluded`` (through the octree alone, and with its
  column-top walk) against Embree's ``test_occlusions`` and closest-hit
  ``ray_query.trace`` against ``cast_rays``.

Agreement: the same float32 rays Embree gets (widened back to float64) go through
``voxfield.render.ray_query``; we report the fraction whose hit/miss matches and the
median |t_voxfield − t_embree| over rays both hit.

Memory: voxfield's figure is the whole octree (every stored array: descriptors, colours,
offsets; ``Octree.nbytes``); Embree's is the mesh arrays handed to it plus the process RSS
growth over ``add_triangles`` and the BVH build (Embree's own buffers and BVH, which Open3D
does not expose). The colour-storage rows show what 8-bit sRGB colours cost in image quality:
the LOD-2 and cone-LOD images' PSNR against the reference, from an 8-bit and a float32 build.

``--big N`` builds an N² world streamed (``voxfield.svo.streamed_build``) and reports build
time, peak RSS, bytes per voxel, render throughput and the memory Embree would need for it:
its exposed faces counted block by block, times the bytes per triangle Embree used in this
run (it is not built). It runs first, so that a footprint too small for the recipe is
refused before the long runs and its peak RSS is its own, not the Embree builds' after it.

The peer is optional: ``pip install -e .[peer]`` (Open3D, ~900 MB wheel) and, on Debian or
Ubuntu, ``apt-get install libusb-1.0-0`` (``import open3d`` needs ``libusb-1.0.so.0``).
"""

from __future__ import annotations

import argparse
import contextlib
import gc
import math
import os
import platform
import resource
import sys
import time
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

# First, so that Numba's kernel cache is the folder voxfield keys on its source digest
# (inside the caller's NUMBA_CACHE_DIR, if set): an unkeyed folder would keep kernels
# compiled against another file's old code after an edit.
import voxfield  # noqa: F401

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


def peak_rss_gib() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 2**20


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
    triangles: int = 0
    vertices: int = 0
    mesh_s: float = 0.0
    mesh_mib: float = 0.0
    embree_build_s: float = float("nan")
    embree_rss_mib: float = float("nan")
    pyramid_s: float = float("nan")
    pyramid_mib: float = float("nan")
    rows: list = field(default_factory=list)
    secondary: list = field(default_factory=list)
    colour: list = field(default_factory=list)

    @property
    def embree_bytes_per_triangle(self) -> float:
        return (self.embree_rss_mib + self.mesh_mib) * 2**20 / max(self.triangles, 1)


def build_scene(args, footprint: int):
    """The terrain the issue names: a real DEM (``--recipe``) at ``footprint``² columns,
    built as ``voxfield`` builds terrains (streamed)."""
    from voxfield.scene.terrain.recipes import recipe_layout
    from voxfield.svo.streamed_build import build_octree_streamed

    t0 = time.perf_counter()
    layout = recipe_layout(args.recipe, footprint=footprint, seed=args.seed)
    t1 = time.perf_counter()
    octree = build_octree_streamed(layout)
    t2 = time.perf_counter()
    stats = SceneStats(
        name=f"{args.recipe} {footprint}²", voxels=octree.voxel_count, nodes=octree.node_count,
        depth=octree.depth, scene_s=t1 - t0, octree_s=t2 - t1,
        octree_mib=octree.nbytes / 2**20,
    )
    return octree, layout, stats


def warm_up() -> None:
    """Compile every kernel we time on a tiny scene, so JIT time is not measured."""
    from voxfield.render.camera import top_down_camera
    from voxfield.render.primary import render_lod, render_reference
    from voxfield.render.ray_query import occluded, trace
    from voxfield.scene.voxel_scene import VoxelScene
    from voxfield.svo import build_octree

    rng = np.random.default_rng(0)
    coords = rng.integers(0, 8, size=(64, 3))
    tiny = build_octree(VoxelScene(coords, rng.random((64, 3)), name="warm-up").dedupe())
    cam = top_down_camera(*tiny.voxel_bounds, size=8)
    for beam in (True, False):
        for columns in (True, False):
            render_lod(tiny, cam, lod=0, beam=beam, columns=columns)
            render_reference(tiny, cam, side=4, beam=beam, columns=columns)
    o, d = cam.rays(side=1, seed=0)
    trace(tiny, o, d)
    trace(tiny, o, d, columns=True)
    occluded(tiny, o, d)


class Timed(NamedTuple):
    best: float  # seconds, the best round
    result: object  # the last round's
    rounds: list  # seconds of every round, in order


def best_of(repeats: int, fns: dict) -> dict:
    """Each ``fn() -> (seconds, result)`` run ``repeats`` times, the functions taking turns
    within each round, as ``Timed``."""
    rounds = {k: [] for k in fns}
    last = {}
    for _ in range(repeats):
        for k, fn in fns.items():
            seconds, last[k] = fn()
            rounds[k].append(seconds)
    return {k: Timed(min(rounds[k]), last[k], rounds[k]) for k in fns}


def paired_ratios(row: dict, ours: Timed, peer: Timed) -> None:
    """The peer's seconds over ours round by round: the two ran back to back, so the
    machine's drift over minutes (10-40 % here) cancels, where the ratio of two bests can
    pair a fast moment of one with a slow one of the other."""
    ratios = np.array(peer.rounds) / np.array(ours.rounds)
    row["paired_median"] = float(np.median(ratios))
    row["paired_min"] = float(ratios.min())
    row["paired_max"] = float(ratios.max())


def paired_cell(row: dict) -> str:
    if "paired_median" not in row:
        return ""
    return (f"{row['paired_median']:.2f} ({row['paired_min']:.2f}–"
            f"{row['paired_max']:.2f})")


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


def camera_for(octree, view: str, size: int):
    """The benchmark's cameras: ``top`` (straight down), ``oblique`` (45°), and ``ground``,
    a game camera low over the south edge looking across the terrain (a ``size`` × ``size/2``
    image), whose rays graze the ground for long stretches: a start-bound or walk change tuned
    on the first two must not cost it."""
    from voxfield.render.camera import Camera, oblique_camera, top_down_camera

    lo, hi = (np.asarray(b, np.float64) for b in octree.voxel_bounds)
    if view == "top":
        return top_down_camera(lo, hi, size=size, fov_deg=90)
    if view == "ground":
        centre = (lo + hi) / 2.0
        extent = max(hi[0] - lo[0], hi[2] - lo[2])
        rise = hi[1] - lo[1]
        eye = (centre[0], lo[1] + 0.9 * rise, hi[2] + 0.07 * extent)
        target = (centre[0], lo[1] + 0.4 * rise, centre[2])
        return Camera.look_at(eye, target, fov_deg=70, width=size, height=max(1, size // 2))
    return oblique_camera(lo, hi, size=size, fov_deg=90, elevation_deg=45)


def run_view(o3d, embree, octree, stats: SceneStats, view: str, side: int, args) -> None:
    from voxfield.render.primary import render_lod, render_reference

    cam = camera_for(octree, view, args.size)

    def vox(beam: bool, columns: bool):
        def run():
            if side == 1:
                r = render_lod(octree, cam, lod=0, threads=args.threads, beam=beam,
                               columns=columns)
            else:
                r = render_reference(octree, cam, side=side, threads=args.threads, beam=beam,
                                     columns=columns)
            return r.seconds, r
        return run

    configs = [(beam, columns) for columns in (True, False) for beam in (True, False)]
    fns = {config: vox(*config) for config in configs}
    rays32 = tensor = None
    if embree is not None:
        origins, directions = cam.rays(side=side, seed=0)
        rays32 = np.concatenate([origins, directions], axis=1).astype(np.float32)
        del origins, directions
        tensor = o3d.core.Tensor.from_numpy(rays32)

        def cast():
            t0 = time.perf_counter()
            out = embree.cast_rays(tensor, nthreads=args.threads)
            return time.perf_counter() - t0, out["t_hit"].numpy()

        fns["embree"] = cast
    timed = best_of(args.repeats, fns)
    for beam, columns in configs:
        seconds, res = timed[beam, columns].best, timed[beam, columns].result
        row = {
            "view": view, "spp": side * side, "beam": beam, "columns": columns,
            "rays": res.total_rays,
            "vox_mrays": res.total_rays / seconds / 1e6,
            "steps_per_ray": res.total_steps / res.total_rays,
            "hit_frac": res.hit_count.sum() / res.total_rays,
        }
        if embree is not None:
            row["emb_mrays"] = len(rays32) / timed["embree"].best / 1e6
            row["ratio"] = row["vox_mrays"] / row["emb_mrays"]
            paired_ratios(row, timed[beam, columns], timed["embree"])
        stats.rows.append(row)
        print(f"  {stats.name} {view} {side * side} rays/px: {fmt_row(row)}", file=sys.stderr)
    if embree is not None:
        agreement(octree, rays32, timed["embree"].result.astype(np.float64),
                  stats.rows[-len(configs)], args)


def agreement(octree, rays32, t_emb, row, args) -> None:
    """Hit/miss agreement and |Δt| on exactly Embree's rays (widened to float64)."""
    from voxfield.render.ray_query import trace

    wide = rays32.astype(np.float64)
    hits = trace(octree, wide[:, :3], wide[:, 3:], threads=args.threads)
    hit_e = np.isfinite(t_emb)
    both = hits.hit & hit_e
    dt = np.abs(hits.t[both] - t_emb[both])
    row["agree"] = float((hits.hit == hit_e).mean())
    row["only_vox"] = int((hits.hit & ~hit_e).sum())
    row["only_emb"] = int((hit_e & ~hits.hit).sum())
    row["dt_median"] = float(np.median(dt)) if len(dt) else 0.0


def secondary_rays(octree, count: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """Cosine-weighted upward rays from random points on random voxel tops (incoherent)."""
    rng = np.random.default_rng(seed)
    leaves = octree.node_coords(octree.depth)
    picks = leaves[rng.integers(0, len(leaves), count)].astype(np.float64)
    origins = picks + np.c_[rng.random(count), np.ones(count), rng.random(count)]
    r = np.sqrt(rng.random(count))
    phi = 2 * np.pi * rng.random(count)
    directions = np.c_[r * np.cos(phi), np.sqrt(1 - r * r), r * np.sin(phi)]
    return origins, directions


def build_column_tops(octree, stats: SceneStats) -> None:
    """The column-top pyramid the renders and the column walk use is set-up, like the
    octree: built once, before and outside the timings."""
    from voxfield.svo.column_tops import octree_column_tops

    t0 = time.perf_counter()
    pyramid = octree_column_tops(octree)
    stats.pyramid_s = time.perf_counter() - t0
    stats.pyramid_mib = sum(a.nbytes for a in pyramid) / 2**20


def run_secondary(o3d, embree, octree, stats: SceneStats, args) -> None:
    """Any-hit and closest-hit queries on incoherent rays against Embree's."""
    from voxfield.render.ray_query import occluded, trace

    origins, directions = secondary_rays(octree, args.secondary_rays, args.seed)
    # Origins on voxel faces: Embree would hit the face it starts on, so both tracers start
    # a hair above it (voxfield's half-open slabs would not need that).
    origins = origins + 1e-3 * directions
    tmin = 0.0
    rays32 = np.concatenate([origins, directions], axis=1).astype(np.float32)
    wide = rays32.astype(np.float64)
    o, d = np.ascontiguousarray(wide[:, :3]), np.ascontiguousarray(wide[:, 3:])

    def any_hit():
        t0 = time.perf_counter()
        out = occluded(octree, o, d, tmin=tmin, threads=args.threads)
        return time.perf_counter() - t0, out

    def closest():
        t0 = time.perf_counter()
        out = trace(octree, o, d, tmin=tmin, threads=args.threads)
        return time.perf_counter() - t0, out

    def any_hit_columns():
        t0 = time.perf_counter()
        out = occluded(octree, o, d, tmin=tmin, threads=args.threads, columns=True)
        return time.perf_counter() - t0, out

    def closest_columns():
        t0 = time.perf_counter()
        out = trace(octree, o, d, tmin=tmin, threads=args.threads, columns=True)
        return time.perf_counter() - t0, out

    fns = {"any": any_hit, "any_columns": any_hit_columns, "closest": closest,
           "closest_columns": closest_columns}
    if embree is not None:
        tensor = o3d.core.Tensor.from_numpy(rays32)

        def occl():
            t0 = time.perf_counter()
            out = embree.test_occlusions(tensor, tnear=tmin, nthreads=args.threads)
            return time.perf_counter() - t0, out.numpy().astype(bool)

        def cast():
            t0 = time.perf_counter()
            out = embree.cast_rays(tensor, nthreads=args.threads)
            return time.perf_counter() - t0, out["t_hit"].numpy()

        fns["emb_any"] = occl
        fns["emb_closest"] = cast
    timed = best_of(args.repeats, fns)
    n = len(o)
    names = {"any": "any-hit", "any_columns": "any-hit, column walk", "closest": "closest hit",
             "closest_columns": "closest hit, column walk"}
    for kind, query in names.items():
        seconds, res = timed[kind].best, timed[kind].result
        closest_hit = kind.startswith("closest")
        blocked = res.hit if closest_hit else res.blocked
        row = {"query": query, "rays": n,
               "vox_mrays": n / seconds / 1e6, "steps_per_ray": res.steps.mean(),
               "blocked": blocked.mean()}
        if embree is not None:
            peer = "closest" if closest_hit else "any"
            embree_timed = timed["emb_" + peer]
            e_out = embree_timed.result
            row["emb_mrays"] = n / embree_timed.best / 1e6
            row["ratio"] = row["vox_mrays"] / row["emb_mrays"]
            paired_ratios(row, timed[kind], embree_timed)
            e_blocked = np.isfinite(e_out) if closest_hit else e_out
            row["agree"] = float((blocked == e_blocked).mean())
        stats.secondary.append(row)
        print(f"  {stats.name} secondary: {fmt_row(row)}", file=sys.stderr)


def run_colour_storage(octree_8bit, layout, stats: SceneStats, args) -> None:
    """PSNR of the LOD-2 and cone-LOD images against the reference, per colour storage."""
    from voxfield.metrics import psnr
    from voxfield.render.primary import render_lod, render_reference
    from voxfield.svo.streamed_build import build_octree_streamed

    exact = build_octree_streamed(layout, colour_storage="float32")
    for view in ("top", "oblique"):
        cam = camera_for(octree_8bit, view, args.size // 2)
        for name, octree in (("srgb8", octree_8bit), ("float32", exact)):
            ref = render_reference(octree, cam, side=4, threads=args.threads)
            row = {"view": view, "storage": name, "octree_mib": octree.nbytes / 2**20}
            for label, lod in (("lod2", 2), ("cone", None)):
                img = render_lod(octree, cam, lod=lod, threads=args.threads).image
                row[label] = psnr(ref.image, img)
            stats.colour.append(row)
            print(f"  {stats.name} colour: {fmt_row(row)}", file=sys.stderr)
    del exact


def count_exposed_faces(layout, block: int = 256) -> int:
    """Exposed voxel faces of a streamed world, block by block with a one-column halo."""
    from voxfield.scene.surface import face_mask

    lo, hi = layout.bounds
    total = 0
    for z0 in range(int(lo[2]), int(hi[2]), block):
        for x0 in range(int(lo[0]), int(hi[0]), block):
            coords, _ = layout.column_block(x0 - 1, z0 - 1, block + 2)
            if not len(coords):
                continue
            grid = coords - coords.min(axis=0)
            faces = face_mask(grid[np.lexsort(grid.T[::-1])])
            c = coords[np.lexsort(grid.T[::-1])]
            core = ((c[:, 0] >= x0) & (c[:, 0] < x0 + block) & (c[:, 2] >= z0)
                    & (c[:, 2] < z0 + block))
            total += int(faces[core].sum())
    return total


def run_big(args) -> dict:
    """Stream-build an N² world, render it, and count its exposed faces (``main`` turns
    them into what Embree would need once a main run has measured its bytes per
    triangle)."""
    from voxfield.render.primary import render_lod
    from voxfield.scene.terrain.recipes import recipe_layout
    from voxfield.svo.streamed_build import build_octree_streamed

    gc.collect()
    footprint = args.big
    t0 = time.perf_counter()
    layout = recipe_layout(args.recipe, footprint=footprint, seed=args.seed)
    t1 = time.perf_counter()
    octree = build_octree_streamed(layout, progress=True)
    t2 = time.perf_counter()
    big = {"name": f"{args.recipe} {footprint}²", "voxels": octree.voxel_count,
           "nodes": octree.node_count, "layout_s": t1 - t0, "build_s": t2 - t1,
           "octree_mib": octree.nbytes / 2**20,
           "bytes_per_voxel": octree.nbytes / octree.voxel_count,
           "peak_rss_gib": peak_rss_gib()}
    for view in ("top", "oblique"):
        cam = camera_for(octree, view, args.size)
        best = min(render_lod(octree, cam, lod=0, threads=args.threads).seconds
                   for _ in range(args.repeats))
        big[f"{view}_mrays"] = args.size * args.size / best / 1e6
    big["peak_rss_gib"] = peak_rss_gib()
    if not args.no_face_count:
        del octree
        gc.collect()
        t3 = time.perf_counter()
        big["triangles"] = 2 * count_exposed_faces(layout)
        big["count_s"] = time.perf_counter() - t3
    del layout
    gc.collect()
    print(f"  big: {fmt_row(big)}", file=sys.stderr)
    return big


def fmt_row(row: dict) -> str:
    return ", ".join(f"{k}={v:.4g}" if isinstance(v, float) else f"{k}={v}" for k, v in row.items())


def num(v, spec: str) -> str:
    return "—" if v is None or (isinstance(v, float) and math.isnan(v)) else format(v, spec)


def table(head: list[str], rows: list[list[str]]) -> None:
    print("| " + " | ".join(head) + " |")
    print("|" + "|".join("---" for _ in head) + "|")
    for cells in rows:
        print("| " + " | ".join(cells) + " |")


def machine_line(o3d) -> str:
    """The processor and the libraries both tracers ran on: on two machines of the same size
    voxfield's 16-ray figures read 3–13 % apart and Embree's alike, so a table says where it was
    measured."""
    import numba  # noqa: PLC0415 - voxfield already imported it

    cpu = platform.processor() or platform.machine()
    fields = {}
    with contextlib.suppress(OSError), open("/proc/cpuinfo", encoding="utf-8") as info:
        for line in info:
            key, _, value = line.partition(":")
            fields.setdefault(key.strip(), value.strip())
    if fields.get("model name"):
        cpu = f"{fields['model name']} (family {fields.get('cpu family', '?')}, model " \
              f"{fields.get('model', '?')})"
    l3 = ""
    cache = "/sys/devices/system/cpu/cpu0/cache/index3/size"
    with contextlib.suppress(OSError), open(cache, encoding="utf-8") as size:
        l3 = f", L3 {size.read().strip()}"
    peer = f", Open3D {o3d.__version__}" if o3d is not None else ""
    return (f"Machine: {cpu}, {os.cpu_count()} logical CPUs{l3}; NumPy {np.__version__}, "
            f"Numba {numba.__version__}{peer}.")


def print_tables(all_stats: list[SceneStats], peer: bool, big: dict | None, args,
                 machine: str = "") -> None:
    print(f"\n### Primary rays ({args.size}² image, 90° FOV, LOD 0, {args.threads} threads, "
          f"best of {args.repeats})\n")
    if machine:
        print(machine + "\n")
    head = ["scene", "view", "rays/px", "beam", "columns", "rays", "voxfield Mrays/s",
            "steps/ray", "hit %"]
    if peer:
        head += ["Embree Mrays/s", "voxfield/Embree", "paired rounds: median (range)",
                 "hit/miss agree", "only vox / only Embree", "median \\|Δt\\|"]
    rows = []
    for s in all_stats:
        for r in s.rows:
            beam = "on" if r["beam"] else "off"
            # Supersampled rays without a beam bound go in packets through the octree alone
            # (``render.primary.pixel_columns``), whatever ``columns`` asks.
            walked = r["columns"] and (r["spp"] == 1 or r["beam"])
            columns = "on" if walked else ("off, packets" if r["spp"] > 1 else "off")
            cells = [s.name, r["view"], str(r["spp"]), beam, columns,
                     f"{r['rays']:,}", num(r["vox_mrays"], ".2f"),
                     num(r["steps_per_ray"], ".1f"), num(100 * r["hit_frac"], ".1f")]
            if peer:
                cells += [num(r.get("emb_mrays"), ".2f"), num(r.get("ratio"), ".2f"),
                          paired_cell(r)]
                if "agree" in r:
                    cells += [f"{100 * r['agree']:.4f} %", f"{r['only_vox']} / {r['only_emb']}",
                              num(r["dt_median"], ".2g")]
                else:
                    cells += ["", "", ""]
            rows.append(cells)
    table(head, rows)

    print(f"\n### Incoherent secondary rays ({args.secondary_rays:,} cosine-weighted rays from "
          "random voxel tops)\n")
    head = ["scene", "query", "voxfield Mrays/s", "steps/ray", "blocked %"]
    if peer:
        head += ["Embree Mrays/s", "voxfield/Embree", "paired rounds: median (range)",
                 "agree"]
    rows = []
    for s in all_stats:
        for r in s.secondary:
            cells = [s.name, r["query"], num(r["vox_mrays"], ".2f"),
                     num(r["steps_per_ray"], ".1f"), num(100 * r["blocked"], ".1f")]
            if peer:
                cells += [num(r.get("emb_mrays"), ".2f"), num(r.get("ratio"), ".2f"),
                          paired_cell(r), f"{100 * r['agree']:.3f} %"]
            rows.append(cells)
    table(head, rows)
    print("\nEmbree: `test_occlusions` for any-hit, `cast_rays` for closest hit; the same "
          "float32 rays, started 0.001 voxel above the faces. The column walk "
          "(`occluded(columns=True)`) and the primary rays with columns on first walk the "
          "column-top pyramid, built once: "
          + "; ".join(f"{s.name} {s.pyramid_s:.2f} s, {s.pyramid_mib:.0f} MiB"
                      for s in all_stats if s.secondary) + ".")

    print("\n### Memory and build\n")
    head = ["scene", "voxels", "octree nodes", "voxfield MiB", "bytes/voxel", "layout s",
            "octree build s"]
    if peer:
        head += ["triangles", "mesh MiB", "Embree build s", "Embree RSS growth MiB",
                 "voxfield/Embree memory"]
    rows = []
    for s in all_stats:
        cells = [s.name, f"{s.voxels:,}", f"{s.nodes:,}", f"{s.octree_mib:.0f}",
                 f"{s.octree_mib * 2**20 / s.voxels:.2f}", f"{s.scene_s:.1f}",
                 f"{s.octree_s:.1f}"]
        if peer:
            embree = s.embree_rss_mib + s.mesh_mib
            cells += [f"{s.triangles:,}", f"{s.mesh_mib:.0f}", num(s.embree_build_s, ".1f"),
                      num(s.embree_rss_mib, ".0f"), f"1/{embree / s.octree_mib:.0f}"]
        rows.append(cells)
    table(head, rows)
    print("\nvoxfield MiB: the whole octree (descriptors, 8-bit sRGB albedo, offsets). Embree: "
          "the mesh arrays handed over (float32 vertices, uint32 triangles) plus the RSS "
          "growth over add_triangles and the BVH build.")

    if any(s.colour for s in all_stats):
        print("\n### Colour storage: image quality against the reference (4×4 rays), "
              f"{args.size // 2}² images\n")
        head = ["scene", "view", "albedo storage", "octree MiB", "LOD 2 PSNR dB",
                "cone LOD PSNR dB"]
        rows = [[s.name, r["view"], r["storage"], f"{r['octree_mib']:.0f}",
                 f"{r['lod2']:.3f}", f"{r['cone']:.3f}"] for s in all_stats for r in s.colour]
        table(head, rows)

    if big:
        print(f"\n### Streamed build: {big['name']}\n")
        head = ["voxels", "nodes", "layout s", "build s", "peak RSS GiB", "octree MiB",
                "bytes/voxel", "top Mrays/s", "oblique Mrays/s", "Embree triangles",
                "Embree GiB (estimate)"]
        table(head, [[f"{big['voxels']:,}", f"{big['nodes']:,}", f"{big['layout_s']:.1f}",
                      f"{big['build_s']:.1f}", f"{big['peak_rss_gib']:.2f}",
                      f"{big['octree_mib']:.0f}", f"{big['bytes_per_voxel']:.2f}",
                      f"{big['top_mrays']:.2f}", f"{big['oblique_mrays']:.2f}",
                      f"{big.get('triangles', 0):,}",
                      num(big.get("embree_gib"), ".0f")]])
        print("\nPeak RSS is the process's by the end of this world's renders, which run "
              "before the other scenes and Embree. The Embree estimate is its triangle count "
              "times the bytes per triangle Embree took in this run; it is not built.")
    try:
        load = os.getloadavg()
        print(f"\nLoad average at the end: {load[0]:.2f} {load[1]:.2f} {load[2]:.2f} "
              f"on {os.cpu_count()} CPUs.")
    except OSError:
        pass


def main(argv=None) -> int:
    from voxfield.cli.options import int_at_least, int_between
    from voxfield.scene.terrain import MAX_FOOTPRINT
    from voxfield.scene.terrain.recipes import RECIPES

    count = int_at_least(1)
    p = argparse.ArgumentParser(prog="bench_traversal", description=__doc__.split("\n\n")[0])
    p.add_argument("--recipe", default="mountain", choices=list(RECIPES),
                   help="terrain recipe (real DEM) from voxfield.scene.terrain (default mountain)")
    p.add_argument("--footprint", type=int_between(2, MAX_FOOTPRINT), nargs="+",
                   default=[2048, 512],
                   help="terrain footprints (columns per side) to run (default 2048 512)")
    p.add_argument("--views", nargs="+", default=["top", "oblique"],
                   choices=["top", "oblique", "ground"])
    p.add_argument("--spp-side", type=int_between(1, 16), nargs="+", default=[1, 4],
                   help="rays per pixel side: 1 = LOD renderer, >1 = reference (default 1 4)")
    p.add_argument("--size", type=count, default=512, help="image side in pixels (default 512)")
    p.add_argument("--repeats", type=count, default=3, help="timed runs per figure (best counts)")
    p.add_argument("--threads", type=count, default=2, help="threads for both tracers (default 2)")
    p.add_argument("--seed", type=int, default=0, help="terrain asset scattering seed")
    p.add_argument("--secondary-rays", type=count, default=1_000_000,
                   help="incoherent secondary rays per scene (default 1,000,000)")
    p.add_argument("--no-colour", action="store_true",
                   help="skip the colour-storage quality rows")
    p.add_argument("--big", type=int_between(2, MAX_FOOTPRINT), default=None, metavar="N",
                   help="also stream-build and render an N² world (e.g. 8192)")
    p.add_argument("--no-face-count", action="store_true",
                   help="with --big: skip counting its exposed faces for the Embree estimate")
    p.add_argument("--no-peer", action="store_true", help="run voxfield alone")
    p.add_argument("--split-vertices", action="store_true",
                   help="four vertices per face instead of shared lattice corners")
    args = p.parse_args(argv)

    o3d, why = (None, "--no-peer") if args.no_peer else load_open3d()
    if o3d is None and not args.no_peer:
        print(PEER_HELP.format(reason=why), file=sys.stderr)
    print("compiling kernels (warm-up)...", file=sys.stderr)
    warm_up()
    big = run_big(args) if args.big else None
    all_stats = []
    bytes_per_triangle = None
    for footprint in args.footprint:
        print(f"building {args.recipe} at {footprint}²...", file=sys.stderr)
        octree, layout, stats = build_scene(args, footprint)
        gc.collect()
        embree = build_embree(o3d, octree, stats, args) if o3d is not None else None
        if embree is not None and bytes_per_triangle is None:
            bytes_per_triangle = stats.embree_bytes_per_triangle
        print(f"  {fmt_row({k: v for k, v in vars(stats).items() if not isinstance(v, list)})}",
              file=sys.stderr)
        build_column_tops(octree, stats)
        for view in args.views:
            for side in args.spp_side:
                run_view(o3d, embree, octree, stats, view, side, args)
        run_secondary(o3d, embree, octree, stats, args)
        del embree
        gc.collect()
        if not args.no_colour:
            run_colour_storage(octree, layout, stats, args)
        all_stats.append(stats)
        del octree, layout
        gc.collect()
    if big is not None and bytes_per_triangle is not None and "triangles" in big:
        big["embree_gib"] = big["triangles"] * bytes_per_triangle / 2**30
    print_tables(all_stats, o3d is not None, big, args, machine_line(o3d))
    if o3d is None:
        print("\n" + PEER_HELP.format(reason=why))
    return 0


if __name__ == "__main__":
    from voxfield.cli.exits import report_failures

    raise SystemExit(report_failures("bench_traversal", main))
