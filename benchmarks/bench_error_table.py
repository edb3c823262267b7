"""Error-table precompute time (issue 3 target: 256 masks × 1024 directions × 512² rays < 30 s).

    python benchmarks/bench_error_table.py [--directions 1024] [--resolution 512]

Peer, measured in the same run: Algorithm 1 as the thesis writes it, one ray-cast pass per
child mask (256 passes per direction), timed on a few directions and extrapolated.
"""

from __future__ import annotations

import argparse
import time

import numba
import numpy as np
from numba import njit, prange

from voxfield.cli.exits import report_failures
from voxfield.cli.options import int_at_least
from voxfield.error_table.directions import fibonacci_directions
from voxfield.error_table.table import raycast_errors
from voxfield.kernels.error_raycast import (
    child_hit_bits,
    image_plane_samples,
    orthonormal_basis,
)
from voxfield.kernels.traversal import safe_inverse


@njit(cache=True, parallel=True)
def per_mask_passes(directions, samples):
    """One pass per mask: every ray re-cast for each of the 256 masks (the naive loop)."""
    n_dirs = directions.shape[0]
    hits = np.zeros((n_dirs, 256), np.int64)
    for k in range(n_dirs):
        dx, dy, dz = directions[k, 0], directions[k, 1], directions[k, 2]
        rx, ry, rz, ux, uy, uz = orthonormal_basis(dx, dy, dz)
        ix, iy, iz = safe_inverse(dx), safe_inverse(dy), safe_inverse(dz)
        for m in prange(256):
            count = 0
            entries = np.empty(8)
            for s in range(samples.shape[0]):
                a = samples[s, 0] * 2.0 - 1.0
                b = samples[s, 1] * 2.0 - 1.0
                bits = child_hit_bits(-2.0 * dx + a * rx + b * ux, -2.0 * dy + a * ry + b * uy,
                                      -2.0 * dz + a * rz + b * uz, dx, dy, dz, ix, iy, iz,
                                      entries)
                if bits & m:
                    count += 1
            hits[k, m] = count
    return hits


def main() -> None:
    parser = argparse.ArgumentParser(prog="bench_error_table", description=__doc__.splitlines()[0])
    parser.add_argument("--directions", type=int_at_least(2), default=1024)
    parser.add_argument("--resolution", type=int_at_least(1), default=512)
    parser.add_argument("--peer-directions", type=int_at_least(1), default=2)
    args = parser.parse_args()
    dirs = fibonacci_directions(args.directions)
    raycast_errors(dirs[:2], 8, 0)  # compile outside the timing
    start = time.perf_counter()
    raycast_errors(dirs, args.resolution, 0)
    ours = time.perf_counter() - start
    rays = args.directions * args.resolution**2
    samples = image_plane_samples(args.resolution, 0)
    per_mask_passes(dirs[:1], samples[:16])
    start = time.perf_counter()
    per_mask_passes(dirs[: args.peer_directions], samples)
    peer = (time.perf_counter() - start) / args.peer_directions * args.directions
    print(f"threads: {numba.get_num_threads()}")
    print("| method | directions | rays per direction | seconds | Mrays/s |")
    print("|---|---:|---:|---:|---:|")
    print(f"| one pass, 256-bin histogram | {args.directions} | {args.resolution}² | "
          f"{ours:.1f} | {rays / ours / 1e6:.0f} |")
    print(f"| one pass per mask (extrapolated from {args.peer_directions}) | {args.directions} "
          f"| {args.resolution}² | {peer:.0f} | {256 * rays / peer / 1e6:.0f} |")
    print(f"speed-up of the shared pass: {peer / ours:.0f}×; target < 30 s: "
          f"{'met' if ours < 30 else 'missed'}")


if __name__ == "__main__":
    raise SystemExit(report_failures("bench_error_table", main))
