"""Texel fetches per ray of the three single-probe marchers, and what they answer.

    python benchmarks/bench_probe_march.py                       # 64², 128², 256² maps
    python benchmarks/bench_probe_march.py --resolutions 32,64 --rays 5000

One probe inside the built-in Cornell box (open on one side), baked at LOD 0 at each map
resolution; rays start within 1.5 voxels of it in random directions (a fixed seed) and run
unbounded, so those leaving through the open side must be proved misses. Per marcher and
resolution: mean texel fetches per ray (the probe thesis's cost measure, §9.1), the share of
misses and of rays the probe gave up on (unknown), and the throughput on this machine (best of
``--repeats``, after a warm-up trace). The thesis's claims: the DDA's fetches grow as the
map's side, the hierarchical trace's as its logarithm, the 3D march's not with the map at all
(a fixed world step).
"""

from __future__ import annotations

import argparse
import time

import numpy as np

# First, so that Numba's kernel cache is the folder voxfield keys on its source digest.
import voxfield  # noqa: F401
from voxfield.lightfield import MISS, UNKNOWN, LightFieldOptions, PackedProbes, trace_single
from voxfield.probes.bake import bake_probes
from voxfield.probes.grid import ProbeGrid
from voxfield.probes.probe_set import BakeOptions
from voxfield.svo.open import open_octree

#: A point inside the Cornell box clear of its blocks and walls (the light-field tests' probe).
PROBE = np.array([16.3, 20.7, 20.1])
MARCHERS = ("march3d", "dda", "hierarchical")


def rays_near_the_probe(count: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    origins = PROBE + rng.uniform(-1.5, 1.5, (count, 3))
    dirs = rng.normal(size=(count, 3))
    return origins, dirs / np.linalg.norm(dirs, axis=1, keepdims=True)


def measure(packed: PackedProbes, origins, dirs, marcher: str, repeats: int) -> dict:
    options = LightFieldOptions(marcher=marcher)
    trace_single(packed, 0, origins[:16], dirs[:16], options)  # compile and warm
    best = np.inf
    for _ in range(repeats):
        start = time.perf_counter()
        hits = trace_single(packed, 0, origins, dirs, options)
        best = min(best, time.perf_counter() - start)
    return {"fetches": float(hits.fetches.mean()), "miss": float(np.mean(hits.kind == MISS)),
            "unknown": float(np.mean(hits.kind == UNKNOWN)), "mrays": len(origins) / best / 1e6}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--resolutions", default="64,128,256",
                        help="comma-separated map sides (default 64,128,256)")
    parser.add_argument("--rays", type=int, default=20000, help="rays (default 20000)")
    parser.add_argument("--repeats", type=int, default=3, help="timed runs (default 3)")
    parser.add_argument("--seed", type=int, default=0, help="ray seed (default 0)")
    args = parser.parse_args()
    sides = [int(text) for text in args.resolutions.split(",")]
    octree = open_octree("builtin:cornell")
    origins, dirs = rays_near_the_probe(args.rays, args.seed)
    print(f"{args.rays} rays near one probe in builtin:cornell, unbounded (seed {args.seed})")
    print(f"{'R':>5} {'marcher':>13} {'fetches/ray':>12} {'miss %':>7} {'unknown %':>10} "
          f"{'Mrays/s':>8}")
    for side in sides:
        grid = ProbeGrid(PROBE, [1, 1, 1], [1, 1, 1])
        packed = PackedProbes.from_probe_set(
            bake_probes(octree, grid, BakeOptions(resolution=side, renderer="lod", lod=0)))
        for marcher in MARCHERS:
            row = measure(packed, origins, dirs, marcher, args.repeats)
            print(f"{side:>5} {marcher:>13} {row['fetches']:>12.1f} {100 * row['miss']:>7.1f} "
                  f"{100 * row['unknown']:>10.1f} {row['mrays']:>8.2f}")


if __name__ == "__main__":
    main()
