"""Random voxel scenes for tests (a module of its own: test files import it by name, which a
``conftest`` would not allow once a subfolder has its own ``conftest``)."""

from __future__ import annotations

import numpy as np

from voxfield.scene.voxel_scene import VoxelScene


def random_scene(seed: int = 0, n: int = 600, size: int = 16) -> VoxelScene:
    rng = np.random.default_rng(seed)
    coords = rng.integers(0, size, size=(n, 3))
    return VoxelScene(coords, rng.random((n, 3)), name=f"random{seed}").dedupe()


def overhanging_terrain(seed: int = 0, size: int = 24) -> VoxelScene:
    """Rolling ground with holes under it, floating ledges and arches: columns whose voxels
    do not form one run, as rays towards the sky meet in caves and under overhangs."""
    rng = np.random.default_rng(seed)
    x, z = np.meshgrid(np.arange(size), np.arange(size), indexing="ij")
    ground = 3 + np.round(2 * np.sin(x / 3.0 + seed) + 2 * np.cos(z / 4.0)).astype(int)
    parts = []
    for y in range(int(ground.max()) + 1):
        below = (y < ground) & ((y >= ground - 2) | (rng.random(ground.shape) < 0.5))
        parts.append(np.stack([x[below], np.full(below.sum(), y), z[below]], axis=1))
    for _ in range(size // 3):  # ledges a few voxels above the ground
        x0, z0 = rng.integers(0, size - 4, size=2)
        w, d = rng.integers(1, 6, size=2)
        y = int(ground[x0, z0]) + int(rng.integers(2, 6))
        xs, zs = np.meshgrid(np.arange(x0, x0 + w), np.arange(z0, z0 + d), indexing="ij")
        parts.append(np.stack([xs.ravel(), np.full(xs.size, y), zs.ravel()], axis=1))
    coords = np.concatenate(parts)
    coords = coords[(coords[:, 0] < size) & (coords[:, 2] < size)]
    return VoxelScene(coords, rng.random((len(coords), 3)), name=f"ledges{seed}").dedupe()


def hollow_shell_terrain(seed: int = 0, size: int = 32) -> VoxelScene:
    """Steep ground two voxels thick over an empty inside, as terrains built with a fill
    depth are: where neighbours differ by more than that, the shell has cracks a ray passes
    through into the hollow under it. A few ledges float above it."""
    rng = np.random.default_rng(seed)
    x, z = np.meshgrid(np.arange(size), np.arange(size), indexing="ij")
    ground = 8 + np.round(6 * np.sin(x / 2.5 + seed) * np.cos(z / 3.0)
                          + rng.integers(0, 3, x.shape)).astype(int)
    parts = [np.stack([x.ravel(), (ground - k).ravel(), z.ravel()], axis=1) for k in (1, 2)]
    for _ in range(size // 4):
        x0, z0 = rng.integers(0, size - 4, size=2)
        y = int(ground[x0, z0]) + int(rng.integers(2, 6))
        xs, zs = np.meshgrid(np.arange(x0, x0 + 3), np.arange(z0, z0 + 3), indexing="ij")
        parts.append(np.stack([xs.ravel(), np.full(xs.size, y), zs.ravel()], axis=1))
    coords = np.concatenate(parts)
    return VoxelScene(coords, rng.random((len(coords), 3)), name=f"shell{seed}").dedupe()


def octree_and_columns(scene: VoxelScene):
    """The scene's octree, its voxels' corners and their column-top pyramid, with cell
    records on any machine, so that the walks in lanes are tested everywhere."""
    from voxfield.svo import build_octree
    from voxfield.svo.column_tops import column_tops

    octree = build_octree(scene)
    voxels = octree.node_coords(octree.depth)
    return octree, voxels, column_tops(voxels, records=True)


def flat_ground(size: int = 64) -> VoxelScene:
    """One layer of grey voxels at y = 0, ``size`` on a side: ground whose top is at y = 1
    everywhere, so a ray's height over it is known exactly."""
    x, z = np.meshgrid(np.arange(size), np.arange(size), indexing="ij")
    coords = np.stack([x.ravel(), np.zeros(x.size, np.int64), z.ravel()], axis=1)
    return VoxelScene(coords, np.full((x.size, 3), 0.5), name="ground")


def pillar_field(seed: int = 0, size: int = 80) -> VoxelScene:
    """Low solid ground with thin pillars of every height scattered over it: a ray that
    clears the ground around it may still meet a tall pillar far away."""
    rng = np.random.default_rng(seed)
    x, z = np.meshgrid(np.arange(size), np.arange(size), indexing="ij")
    height = 1 + (rng.random(x.shape) < 0.3).astype(int)
    pillars = rng.random(x.shape) < 0.01
    height[pillars] = rng.integers(4, 3 * size // 4, int(pillars.sum()))
    coords = np.array([(i, y, k) for i in range(size) for k in range(size)
                       for y in range(int(height[i, k]))])
    return VoxelScene(coords, rng.random((len(coords), 3)), name=f"pillars{seed}")


def any_rays(voxels: np.ndarray, n: int, seed: int):
    """Rays of every kind: down from a camera above (steep and oblique), from lattice points
    with small integer directions (through edges and corners, level ones included), with
    zero ``x`` or ``z`` or straight up and down, from inside voxels, and from random points
    around the scene (beside the footprint and under it)."""
    rng = np.random.default_rng(seed)
    lo, hi = voxels.min(axis=0), voxels.max(axis=0) + 1
    size = float((hi - lo).max())
    parts_o, parts_d = [], []
    o = np.empty((n, 3))
    o[:, [0, 2]] = rng.uniform(lo[[0, 2]] - 2, hi[[0, 2]] + 2, (n, 2))
    o[:, 1] = hi[1] + rng.uniform(0.5, size, n)
    parts_o.append(o)
    d = rng.normal(size=(n, 3))
    d[:, 1] = -np.abs(d[:, 1]) * rng.choice([0.1, 0.5, 2.0, 20.0], n)
    parts_d.append(d)
    parts_o.append(np.round(rng.uniform(lo - 2, hi + 2, (n, 3))))
    parts_d.append(rng.integers(-2, 3, (n, 3)).astype(np.float64))
    o = rng.uniform(lo - 1, hi + 1, (n, 3))
    o[:, [0, 2]] = np.round(o[:, [0, 2]] * 2) / 2
    d = rng.normal(size=(n, 3))
    d[np.arange(n), rng.choice([0, 2], n)] = 0.0
    d[: n // 4, [0, 2]] = 0.0
    parts_o.append(o)
    parts_d.append(d)
    parts_o.append(voxels[rng.integers(0, len(voxels), n)] + rng.random((n, 3)))
    parts_d.append(rng.normal(size=(n, 3)))
    parts_o.append(rng.uniform(lo - 3, hi + 3, (n, 3)))
    parts_d.append(rng.normal(size=(n, 3)))
    origins, directions = np.concatenate(parts_o), np.concatenate(parts_d)
    keep = np.any(directions != 0.0, axis=1)
    return origins[keep], directions[keep]


def rising_rays(voxels: np.ndarray, n: int, seed: int):
    """Rays with ``dy > 0``: the first ``n`` from points on voxel faces (as the bake casts
    them), then from lattice points with small integer directions (through edges and
    corners), with a zero ``x`` or ``z`` (grazing planes), straight up, and from random points
    around the scene."""
    rng = np.random.default_rng(seed)
    lo, hi = voxels.min(axis=0), voxels.max(axis=0) + 1
    parts_o, parts_d = [], []
    corners = voxels[rng.integers(0, len(voxels), n)].astype(np.float64)
    axis = rng.integers(0, 3, n)
    offset = rng.random((n, 3))
    offset[np.arange(n), axis] = rng.integers(0, 2, n)  # exactly on one face plane
    parts_o.append(corners + offset)
    d = rng.normal(size=(n, 3))
    d[:, 1] = np.abs(d[:, 1]) * rng.choice([0.05, 0.3, 1.0], n)
    parts_d.append(d)
    parts_o.append(np.round(rng.uniform(lo - 2, hi + 2, (n, 3))))
    d = rng.integers(-2, 3, (n, 3)).astype(np.float64)
    d[:, 1] = rng.integers(1, 3, n)
    parts_d.append(d)
    o = rng.uniform(lo - 1, hi + 1, (n, 3))
    o[:, [0, 2]] = np.round(o[:, [0, 2]] * 2) / 2
    d = rng.normal(size=(n, 3))
    d[:, 1] = np.abs(d[:, 1]) + 1e-3
    d[np.arange(n), rng.choice([0, 2], n)] = 0.0
    d[: n // 4, [0, 2]] = 0.0
    parts_o.append(o)
    parts_d.append(d)
    parts_o.append(rng.uniform(lo - 3, hi + 3, (n, 3)))
    d = rng.normal(size=(n, 3))
    d[:, 1] = np.abs(d[:, 1])
    parts_d.append(d)
    origins, directions = np.concatenate(parts_o), np.concatenate(parts_d)
    keep = directions[:, 1] > 0.0
    return origins[keep], directions[keep]
