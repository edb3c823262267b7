"""Octree build time and peak memory on ~20M voxels (the EA thesis's terrain scale).

    python benchmarks/bench_build.py                 # synthetic 2048² heightfield, ~20M voxels
    python benchmarks/bench_build.py --scene terrain:mountain --footprint 2048

Peak memory is the process's high-water RSS (VmHWM), measured in a fresh child process per run.
"""

from __future__ import annotations

import argparse
import json
import multiprocessing as mp
import time

import numpy as np

from voxfield.cli.exits import report_failures
from voxfield.cli.options import int_at_least, int_between
from voxfield.scene.terrain import MAX_FOOTPRINT


def synthetic_terrain(footprint: int, depth_fill: int):
    """Rolling hills with every column filled ``depth_fill`` voxels down (no files needed)."""
    from voxfield.scene.voxel_scene import VoxelScene

    x, z = np.meshgrid(np.arange(footprint), np.arange(footprint), indexing="ij")
    f = footprint / 2048
    top = (200 * f + 120 * f * np.sin(x / (97 * f)) * np.cos(z / (131 * f))
           + 40 * f * np.sin((x + z) / (23 * f))).astype(np.int64)
    counts = np.full(top.size, depth_fill)
    cols = np.repeat(np.arange(top.size, dtype=np.int64), counts)
    y = np.repeat(top.ravel(), counts) - (np.arange(cols.size) - np.repeat(
        np.cumsum(counts) - counts, counts))
    coords = np.stack([cols // footprint, y, cols % footprint], axis=1)
    t = (y - y.min()) / max(1, np.ptp(y))
    color = np.stack([0.3 + 0.5 * t, 0.5 + 0.2 * t, 0.2 + 0.1 * t], axis=1)
    return VoxelScene(coords, color, name=f"synthetic{footprint}")


def _peak_rss_mib() -> float:
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith("VmHWM:"):
                return int(line.split()[1]) / 1024
    return float("nan")


def _run(args, queue) -> None:
    from voxfield.scene.loaders import SceneOptions, load_scene
    from voxfield.svo.build import build_octree

    t0 = time.perf_counter()
    if args.scene == "synthetic":
        scene = synthetic_terrain(args.footprint, args.fill)
    else:
        scene = load_scene(args.scene, SceneOptions(terrain_footprint=args.footprint))
    load_s = time.perf_counter() - t0
    rss_scene = _peak_rss_mib()
    octree = build_octree(scene, lod_colour=args.lod_colour)
    queue.put({
        "scene": scene.name,
        "voxels": len(scene),
        "nodes": octree.node_count,
        "depth": octree.depth,
        "scene_seconds": round(load_s, 2),
        "build_seconds": round(octree.build_seconds, 2),
        "octree_MiB": round(octree.bytes_per_node()["total"] * octree.node_count / 2**20, 1),
        "peak_rss_after_scene_MiB": round(rss_scene, 1),
        "peak_rss_MiB": round(_peak_rss_mib(), 1),
    })


def main() -> None:
    parser = argparse.ArgumentParser(prog="bench_build", description=__doc__.splitlines()[0])
    parser.add_argument("--scene", default="synthetic",
                        help="'synthetic' or any scene description (e.g. terrain:mountain)")
    parser.add_argument("--footprint", type=int_between(2, MAX_FOOTPRINT), default=2048)
    parser.add_argument("--fill", type=int_at_least(1), default=5,
                        help="synthetic: voxels per column")
    parser.add_argument("--lod-colour", default="mean", choices=("mean", "surface", "facing"),
                        help="coarse-colour rule (default mean: the structure alone; facing "
                        "adds 24 bytes per inner node and its own pass)")
    args = parser.parse_args()
    queue = mp.get_context("spawn").Queue()
    proc = mp.get_context("spawn").Process(target=_run, args=(args, queue))
    proc.start()
    result = queue.get()
    proc.join()
    print(json.dumps(result, indent=2))
    print()
    print("| scene | voxels | nodes | depth | build s | octree MiB | peak RSS MiB |")
    print("|---|---:|---:|---:|---:|---:|---:|")
    print(f"| {result['scene']} | {result['voxels']:,} | {result['nodes']:,} | {result['depth']} "
          f"| {result['build_seconds']} | {result['octree_MiB']} | {result['peak_rss_MiB']} |")


if __name__ == "__main__":
    raise SystemExit(report_failures("bench_build", main))
