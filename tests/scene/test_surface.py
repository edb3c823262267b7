"""The exposed-face mesh against analytic cases and a dense-grid brute force."""

from __future__ import annotations

import numpy as np
import pytest

from random_scenes import random_scene
from voxfield.errors import VoxfieldError
from voxfield.scene.surface import exposed_faces
from voxfield.scene.voxel_scene import VoxelScene
from voxfield.svo import build_octree
from voxfield.svo.octree import Octree


def octree_of(coords) -> Octree:
    coords = np.asarray(coords)
    return build_octree(VoxelScene(coords, np.full((len(coords), 3), 0.5), name="t"))


def normals_and_areas(vertices, triangles):
    p = vertices[triangles].astype(np.float64)
    cross = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    area = np.linalg.norm(cross, axis=1) / 2
    return cross / (2 * area[:, None]), area


def dense_exposed_count(coords, lod=0) -> int:
    """Faces between an occupied and an empty cell of a padded boolean grid (np.diff)."""
    g = np.asarray(coords) >> lod
    g = np.unique(g - g.min(axis=0), axis=0)
    grid = np.zeros(tuple(g.max(axis=0) + 3), bool)
    grid[tuple((g + 1).T)] = True
    return int(sum(np.count_nonzero(np.diff(grid, axis=a)) for a in range(3)))


def edge_counts(triangles) -> np.ndarray:
    """How many triangles use each undirected edge, and whether directed edges pair up."""
    edges = np.concatenate([triangles[:, [0, 1]], triangles[:, [1, 2]], triangles[:, [2, 0]]])
    undirected = np.sort(edges, axis=1)
    _, counts = np.unique(undirected, axis=0, return_counts=True)
    return counts, edges


@pytest.mark.parametrize("shared", [True, False])
def test_single_voxel_is_a_unit_cube_with_outward_normals(shared):
    octree = octree_of([[3, 5, 2]])
    v, t = exposed_faces(octree, shared_vertices=shared)
    assert v.dtype == np.float32 and t.dtype == np.int32
    assert t.shape == (12, 3)
    assert len(v) == (8 if shared else 24)
    normal, area = normals_and_areas(v, t)
    assert area.sum() == pytest.approx(6.0)
    # Outward: the normal points from the cube centre to the triangle's centroid side.
    centroid = v[t].mean(axis=1)
    lo = v.min(axis=0)
    outward = np.einsum("ij,ij->i", normal, centroid - (lo + 0.5))
    assert np.all(outward > 0)
    # Each axis direction appears on exactly two triangles.
    assert sorted(map(tuple, np.round(normal).astype(int).tolist())) == sorted(
        [tuple(s * np.eye(3, dtype=int)[a]) for a in range(3) for s in (-1, 1)] * 2
    )


def test_two_adjacent_voxels_share_no_face():
    v, t = exposed_faces(octree_of([[0, 0, 0], [1, 0, 0]]))
    assert len(t) == 20
    _, area = normals_and_areas(v, t)
    assert area.sum() == pytest.approx(10.0)


def test_solid_block_emits_only_its_outer_faces():
    coords = np.stack(np.meshgrid(*[np.arange(3)] * 3, indexing="ij"), -1).reshape(-1, 3)
    v, t = exposed_faces(octree_of(coords))
    assert len(t) == 2 * 54
    normal, _ = normals_and_areas(v, t)
    centroid = v[t].mean(axis=1)
    # Every triangle lies on the block's boundary and faces away from its centre.
    assert np.all(np.isclose(centroid, 0).any(axis=1) | np.isclose(centroid, 3).any(axis=1))
    assert np.all(np.einsum("ij,ij->i", normal, centroid - 1.5) > 0)


@pytest.mark.parametrize("seed", [0, 1, 2])
@pytest.mark.parametrize("lod", [0, 1, 2])
def test_exposed_face_count_matches_dense_brute_force(seed, lod):
    scene = random_scene(seed, n=900, size=20)
    octree = build_octree(scene)
    _, t = exposed_faces(octree, lod)
    assert len(t) == 2 * dense_exposed_count(octree.lod_voxels(0), lod)


def test_lod_mesh_is_in_octree_space_with_node_size():
    # LOD 1 nodes (size 2) at (0, 0, 0) and (2, 2, 2): two cubes touching at one corner.
    octree = octree_of([[0, 0, 0], [2, 2, 2], [3, 2, 3]])
    v, t = exposed_faces(octree, lod=1)
    assert len(t) == 24
    _, area = normals_and_areas(v, t)
    assert area.sum() == pytest.approx(2 * 6 * 4)
    assert v.min(axis=0).tolist() == [0, 0, 0] and v.max(axis=0).tolist() == [4, 4, 4]
    assert np.unique(v).tolist() == [0, 2, 4]


def fill_edge_contacts(grid: np.ndarray) -> np.ndarray:
    """Fill cells until no two voxels touch only along an edge (non-manifold edges)."""
    grid = grid.copy()
    while True:
        changed = False
        for a, b in ((0, 1), (0, 2), (1, 2)):
            g = np.moveaxis(grid, (a, b), (0, 1))  # a view: writes land in grid
            p, q, r, s = g[:-1, :-1], g[1:, 1:], g[1:, :-1], g[:-1, 1:]
            diagonal = p & q & ~r & ~s
            anti = r & s & ~p & ~q
            if diagonal.any() or anti.any():
                r |= diagonal
                p |= anti
                changed = True
        if not changed:
            return grid


def blob(seed: int, n: int = 12) -> np.ndarray:
    rng = np.random.default_rng(seed)
    g = np.stack(np.meshgrid(*[np.arange(n)] * 3, indexing="ij"), -1).reshape(-1, 3)
    inside = np.linalg.norm(g - (n - 1) / 2, axis=1) + rng.normal(0, 1.2, len(g)) < n / 2 - 1
    return fill_edge_contacts(inside.reshape(n, n, n))


@pytest.mark.parametrize("seed", [0, 1])
def test_random_blob_is_closed_watertight_and_consistently_wound(seed):
    occupied = blob(seed)
    coords = np.argwhere(occupied)
    v, t = exposed_faces(octree_of(coords))
    counts, edges = edge_counts(t)
    assert np.all(counts == 2)  # closed, and manifold along every edge
    # Consistent winding: each directed edge is used once, and so is its reverse.
    directed = np.unique(edges, axis=0)
    assert len(directed) == len(edges)
    assert np.array_equal(directed, np.unique(edges[:, ::-1], axis=0))
    # Divergence theorem: the enclosed volume is the voxel count.
    p = v[t].astype(np.float64)
    volume = np.einsum("ij,ij->i", p[:, 0], np.cross(p[:, 1], p[:, 2])).sum() / 6
    assert volume == pytest.approx(len(coords))
    assert len(t) == 2 * dense_exposed_count(coords)


def test_edge_contact_is_closed_but_not_manifold():
    """Voxels touching only along an edge: that edge carries four triangles, winding still pairs."""
    _, t = exposed_faces(octree_of([[0, 0, 0], [1, 1, 0]]))
    assert len(t) == 24
    counts, edges = edge_counts(t)
    assert sorted(set(counts.tolist())) == [2, 4] and (counts == 4).sum() == 1
    fwd, n_fwd = np.unique(edges, axis=0, return_counts=True)
    rev, n_rev = np.unique(edges[:, ::-1], axis=0, return_counts=True)
    assert np.array_equal(fwd, rev) and np.array_equal(n_fwd, n_rev)


def test_lod_out_of_range_is_an_error():
    octree = octree_of([[0, 0, 0], [3, 1, 2]])
    with pytest.raises(VoxfieldError, match="LOD"):
        exposed_faces(octree, lod=octree.depth + 1)
