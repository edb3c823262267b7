"""The exposed-face triangle mesh of an octree's voxels, for triangle ray tracers (Embree).

A benchmark against a triangle tracer is only fair when both trace the same solid: the mesh
here is exactly the boundary of the union of the voxels at one LOD, two triangles per face
that no occupied neighbour covers, wound counter-clockwise seen from outside (so the
right-hand normal points out of the solid). Interior faces are never emitted, which keeps the
2048² mountain terrain (22.3M voxels) at 56.7M triangles instead of 268M.

Built with NumPy only, no per-voxel Python loop: nodes are sorted by linear key, ±z
neighbours are adjacent keys, ±x and ±y neighbours are found with ``np.searchsorted`` (sorted
queries, so the searches stay in cache); shared corners are deduplicated by merging sorted runs.
"""

from __future__ import annotations

import numpy as np

from voxfield.errors import VoxfieldError

__all__ = ["exposed_faces", "face_mask"]

#: Face directions in the order of the traversal's normal codes: -x, +x, -y, +y, -z, +z.
DIRECTIONS = ((0, -1), (0, 1), (1, -1), (1, 1), (2, -1), (2, 1))


def _node_grid(octree, lod: int) -> tuple[np.ndarray, np.ndarray]:
    """Node positions at ``lod`` in node units, shifted so the smallest is (0, 0, 0)."""
    if not 0 <= lod <= octree.depth:
        raise VoxfieldError(f"LOD must be between 0 and {octree.depth} for this octree, got {lod}")
    grid = octree.lod_voxels(lod) >> lod
    if len(grid) == 0:
        return grid.reshape(0, 3), np.zeros(3, np.int64)
    origin = grid.min(axis=0)
    return grid - origin, origin


def _linear_keys(grid: np.ndarray, dims: np.ndarray, pad: int = 0) -> np.ndarray:
    """Row-major keys (x slowest, z fastest): sorting by key sorts lexicographically."""
    return ((grid[:, 0] + pad) * dims[1] + (grid[:, 1] + pad)) * dims[2] + (grid[:, 2] + pad)


def face_mask(grid: np.ndarray) -> np.ndarray:
    """``(N, 6)`` bool: face ``k`` (order of ``DIRECTIONS``) of node ``i`` has no neighbour.

    ``grid`` holds unique non-negative integer positions, sorted lexicographically (x, y, z)
    for speed (any order is correct, sorted order makes every search cache-friendly). Keys
    index the grid's bounding box padded by one node on every side, so ``key ± stride`` is
    the neighbour's key and never wraps into another row.
    """
    n = len(grid)
    exposed = np.ones((n, 6), bool)
    if n == 0:
        return exposed
    dims = grid.max(axis=0) + 3  # one node of padding below and above
    if float(dims[0]) * float(dims[1]) * float(dims[2]) >= 2.0**62:
        raise VoxfieldError(f"node grid {dims.tolist()} is too large for 64-bit keys")
    keys = _linear_keys(grid, dims, pad=1)
    order = None
    if n > 1 and not np.all(keys[1:] > keys[:-1]):
        order = np.argsort(keys, kind="stable")
        keys = keys[order]
        if not np.all(keys[1:] != keys[:-1]):
            raise VoxfieldError("duplicate node positions; the mesh would not be a closed surface")
    strides = (int(dims[1] * dims[2]), int(dims[2]), 1)
    for k, (axis, sign) in enumerate(DIRECTIONS):
        stride = strides[axis]
        if stride == 1:
            # z neighbours are adjacent in sorted key order: no search needed.
            has = np.zeros(n, bool)
            if sign > 0:
                has[:-1] = keys[1:] == keys[:-1] + 1
            else:
                has[1:] = keys[:-1] == keys[1:] - 1
        else:
            # Sorted queries into sorted keys: ~25x faster than the same search shuffled.
            query = keys + sign * stride
            pos = np.searchsorted(keys, query)
            np.minimum(pos, n - 1, out=pos)
            has = keys[pos] == query
            del query, pos
        if order is None:
            exposed[:, k] = ~has
        else:
            exposed[order, k] = ~has
    return exposed


def exposed_faces(
    octree, lod: int = 0, *, shared_vertices: bool = True
) -> tuple[np.ndarray, np.ndarray]:
    """Vertices (float32 ``V×3``, octree space) and triangles (int32 ``T×3``) of the voxel
    faces at ``lod`` not shared with an occupied neighbour at that LOD.

    Two triangles per exposed face, counter-clockwise seen from outside; faces come grouped by
    direction (-x, +x, -y, +y, -z, +z), each group in (x, y, z) order of its node. With
    ``shared_vertices`` (default) each lattice corner is one vertex (about half the memory
    and an indexed, watertight mesh); otherwise every face has four vertices of its own
    (a little faster to build, same geometry). Coordinates are exact in float32 (< 2**24).
    The 22.3M-voxel 2048² terrain takes ~21 s and ~3 GB of temporaries (one core).
    """
    grid, origin = _node_grid(octree, lod)
    size = 1 << lod
    if len(grid) > 1:
        # Lexicographic order makes every search below and every corner stream sorted.
        grid = grid[np.argsort(_linear_keys(grid, grid.max(axis=0) + 1), kind="stable")]
    exposed = face_mask(grid)
    # Lattice points (node corners) are keyed on the (extent + 1)^3 corner grid; the key is
    # increasing in (x, y, z), so each (direction, corner) column below is a sorted run.
    vdims = (grid.max(axis=0) + 2) if len(grid) else np.ones(3, np.int64)
    strides = np.array([vdims[1] * vdims[2], vdims[2], 1], np.int64)
    runs = []
    for k, (axis, sign) in enumerate(DIRECTIONS):
        base = _linear_keys(grid[exposed[:, k]], vdims)
        if sign > 0:
            base += strides[axis]
        du = strides[(axis + 1) % 3]
        dv = strides[(axis + 2) % 3]
        # e_u × e_v = +e_axis, so (p0, p0+u, p0+u+v, p0+v) is counter-clockwise about +axis.
        offsets = (0, du, du + dv, dv) if sign > 0 else (0, dv, du + dv, du)
        runs.append(np.stack([base + off for off in offsets]))  # (4, F_k), each row sorted
        del base
    counts = [r.shape[1] for r in runs]
    keys = np.concatenate([r.ravel() for r in runs])
    del exposed, grid, runs
    if shared_vertices and len(keys):
        # A stable argsort merges the 24 sorted runs quickly; ids then scatter back.
        perm = np.argsort(keys, kind="stable")
        ordered = keys[perm]
        del keys
        first = np.empty(len(ordered), bool)
        first[0] = True
        np.not_equal(ordered[1:], ordered[:-1], out=first[1:])
        small = np.int32 if len(ordered) < 2**31 else np.int64  # ids < len(ordered)
        ids = np.cumsum(first, dtype=small)
        ids -= 1
        flat = np.empty(len(ordered), small)
        flat[perm] = ids
        del perm, ids
        keys = ordered[first]
        del ordered, first
    else:
        flat = np.arange(len(keys), dtype=np.int64)
    if len(keys) >= 2**31:
        raise VoxfieldError(f"{len(keys):,} vertices do not fit 32-bit triangle indices")
    vertices = np.empty((len(keys), 3), np.float32)
    for i in range(0, len(keys), 1 << 22):  # chunks keep the int64 temporaries small
        x, rest = np.divmod(keys[i : i + (1 << 22)], strides[0])
        y, z = np.divmod(rest, strides[1])
        for axis, c in enumerate((x, y, z)):
            vertices[i : i + len(c), axis] = (c + origin[axis]) * size
    del keys
    # Back from the run layout [direction][corner][face] to one row of corners per face.
    quads = np.empty((sum(counts), 4), np.int32)
    row = 0
    for f in counts:
        quads[row : row + f] = flat[4 * row : 4 * (row + f)].reshape(4, f).T
        row += f
    del flat
    triangles = np.empty((2 * len(quads), 3), np.int32)
    triangles[0::2] = quads[:, [0, 1, 2]]
    triangles[1::2] = quads[:, [0, 2, 3]]
    return vertices, triangles
