"""Voxelizer against independent facts: analytic slabs, a brute-force SAT oracle, closed shells."""

from __future__ import annotations

import warnings

import numba
import numpy as np
import pytest
from PIL import Image
from scipy import ndimage

from voxfield.data import data_root
from voxfield.errors import VoxfieldError
from voxfield.scene.mesh import TriangleMesh, load_mesh
from voxfield.scene.voxel_scene import srgb_to_linear
from voxfield.scene.voxelize import place_mesh, surface_voxels, voxelize_mesh

# --------------------------------------------------------------------------------------------
# Independent reference: brute-force separating-axis test over every voxel, plus a
# closest-point routine written differently from the kernel's (plane projection + edges).


def sat_oracle(tri: np.ndarray, shape) -> np.ndarray:
    """Boolean grid: closed unit voxels overlapping triangle ``tri`` (3×3), 13-axis SAT."""
    idx = np.indices(shape).reshape(3, -1).T
    rel = tri[None, :, :] - (idx + 0.5)[:, None, :]  # N × vertex × xyz
    e = [tri[1] - tri[0], tri[2] - tri[1], tri[0] - tri[2]]
    unit = np.eye(3)
    axes = [unit[0], unit[1], unit[2], np.cross(e[0], e[1])]
    axes += [np.cross(unit[i], ej) for i in range(3) for ej in e]
    hit = np.ones(len(idx), dtype=bool)
    for a in axes:
        p = rel @ a
        r = 0.5 * np.abs(a).sum()
        hit &= ~((p.min(axis=1) > r) | (p.max(axis=1) < -r))
    return hit.reshape(shape)


def _segment_dist(p, a, b):
    d = b - a
    den = d @ d
    s = np.zeros(len(p)) if den == 0 else np.clip((p - a) @ d / den, 0.0, 1.0)
    q = a + s[:, None] * d
    return np.linalg.norm(p - q, axis=1)


def point_triangle_dist(p: np.ndarray, tri: np.ndarray) -> np.ndarray:
    """Distance from points p (N×3) to the triangle: plane projection if inside, else edges."""
    a, b, c = tri
    edges = np.minimum(
        np.minimum(_segment_dist(p, a, b), _segment_dist(p, b, c)), _segment_dist(p, c, a)
    )
    n = np.cross(b - a, c - a)
    nn = n @ n
    if nn == 0.0:
        return edges
    q = p - ((p - a) @ n / nn)[:, None] * n
    # Inside test by signed sub-triangle areas.
    inside = np.ones(len(p), dtype=bool)
    for u, v in ((a, b), (b, c), (c, a)):
        inside &= np.cross(v - u, q - u) @ n >= 0
    plane = np.abs((p - a) @ n) / np.sqrt(nn)
    return np.where(inside, plane, edges)


def _random_triangles(rng, n, size):
    out = []
    for i in range(n):
        centre = rng.uniform(1.0, size - 1.0, 3)
        spread = [0.3, 1.5, 5.0][i % 3]
        out.append(np.clip(centre + rng.normal(0, spread, (3, 3)), 0.05, size - 0.05))
    return out


def test_random_triangles_match_brute_force_oracle():
    """Voxel set and closest-triangle choice agree with the slow NumPy SAT over all 16³ voxels."""
    rng = np.random.default_rng(1234)
    shape = (16, 16, 16)
    tris = _random_triangles(rng, 24, 16)
    # Degenerate triangles: collinear (a segment) and all-equal (a point).
    a, b = rng.uniform(1, 15, 3), rng.uniform(1, 15, 3)
    tris.append(np.stack([a, b, a + 0.37 * (b - a)]))
    p = rng.uniform(1, 15, 3)
    tris.append(np.stack([p, p, p]))
    vertices = np.concatenate(tris)
    triangles = np.arange(len(vertices)).reshape(-1, 3)

    coords, tri, bary = surface_voxels(vertices, triangles, shape)

    hits = np.stack([sat_oracle(t, shape) for t in tris])  # T × grid
    expected = np.argwhere(hits.any(axis=0))
    assert len(coords) == len(expected)
    np.testing.assert_array_equal(coords, expected)  # both x-major sorted
    # Closest covering triangle: least distance from the voxel centre, ties to lower index.
    centres = coords + 0.5
    dist = np.full((len(tris), len(coords)), np.inf)
    for i, t in enumerate(tris):
        cover = hits[i][tuple(coords.T)]
        dist[i, cover] = point_triangle_dist(centres[cover], t)
    best = dist.min(axis=0)
    chosen = dist[tri, np.arange(len(coords))]
    np.testing.assert_allclose(chosen, best, atol=1e-9)
    clear = np.sort(dist, axis=0)[1] - best > 1e-9  # no near-tie
    np.testing.assert_array_equal(tri[clear], dist.argmin(axis=0)[clear])
    # The barycentric point is on the chosen triangle at that distance.
    corners = vertices[triangles[tri]]
    point = np.einsum("nc,ncx->nx", bary.astype(np.float64), corners)
    np.testing.assert_allclose(np.linalg.norm(point - centres, axis=1), best, atol=1e-5)
    assert (bary >= -1e-6).all()


def test_axis_aligned_triangle_gives_the_analytic_slab():
    """A right triangle in the plane y = 3.5: one layer, columns whose square meets it."""
    x0, z0, ax, bz = 2.25, 1.25, 5.5, 4.5
    verts = np.array([[x0, 3.5, z0], [x0 + ax, 3.5, z0], [x0, 3.5, z0 + bz]])
    coords, tri, _ = surface_voxels(verts, np.array([[0, 1, 2]]), (12, 8, 10))
    expected = set()
    for i in range(12):
        for k in range(10):
            if i + 1 < x0 or i > x0 + ax or k + 1 < z0 or k > z0 + bz:
                continue
            # Nearest point of the column square to the right-angle corner.
            px, pz = max(i, x0), max(k, z0)
            if (px - x0) / ax + (pz - z0) / bz <= 1.0:
                expected.add((i, 3, k))
    assert {tuple(c) for c in coords.tolist()} == expected
    assert (tri == 0).all()


def test_quad_on_grid_plane_occupies_both_neighbours():
    """Closed voxels: a surface exactly on a voxel face belongs to both voxels."""
    verts = np.array([[0.5, 4.0, 0.5], [3.5, 4.0, 0.5], [3.5, 4.0, 3.5], [0.5, 4.0, 3.5]])
    coords, _, _ = surface_voxels(verts, np.array([[0, 1, 2], [0, 2, 3]]), (4, 8, 4))
    assert set(np.unique(coords[:, 1]).tolist()) == {3, 4}
    assert len(coords) == 2 * 16


def test_voxelize_mesh_floor_and_wall_slabs():
    """Through voxelize_mesh: a unit floor fills 16×16 voxels of layer 0, a wall one x-layer."""
    verts = np.array(
        [
            [0, 0, 0], [1, 0, 0], [1, 0, 1], [0, 0, 1],  # floor y = 0
            [8.5 / 16, 0, 0], [8.5 / 16, 0.45, 0], [8.5 / 16, 0.45, 1], [8.5 / 16, 0, 1],
        ],
        dtype=float,
    )  # fmt: skip
    tris = np.array([[0, 1, 2], [0, 2, 3], [4, 5, 6], [4, 6, 7]])
    mesh = TriangleMesh(verts, tris, face_color=[[1, 0, 0]] * 2 + [[0, 0, 1]] * 2)
    scene = voxelize_mesh(mesh, 16)
    occupied = {tuple(c) for c in scene.coords.tolist()}
    floor = {(i, 0, k) for i in range(16) for k in range(16)}
    wall = {(8, j, k) for j in range(8) for k in range(16)}  # 0.45 × 16 = 7.2 → layers 0..7
    assert occupied == floor | wall
    colour = dict(zip(map(tuple, scene.coords.tolist()), scene.color.tolist(), strict=True))
    assert colour[(3, 0, 3)] == [1.0, 0.0, 0.0]
    assert colour[(8, 5, 3)] == [0.0, 0.0, 1.0]
    assert scene.emission is None


def _cube(rotation=None, size=1.0):
    corners = np.array([[x, y, z] for x in (0, 1) for y in (0, 1) for z in (0, 1)], float) * size
    faces = [
        [0, 1, 3, 2], [4, 6, 7, 5], [0, 4, 5, 1], [2, 3, 7, 6], [0, 2, 6, 4], [1, 5, 7, 3],
    ]  # fmt: skip
    tris = np.array([[f[0], f[1], f[2]] for f in faces] + [[f[0], f[2], f[3]] for f in faces])
    if rotation is not None:
        corners = corners @ rotation.T
    return TriangleMesh(corners, tris, face_color=np.full((12, 3), 0.5))


def _outside_reaches_inside(scene, connectivity):
    shape = tuple(int(s) + 2 for s in scene.coords.max(axis=0) + 1)
    solid = np.zeros(shape, dtype=bool)
    solid[tuple((scene.coords + 1).T)] = True
    structure = ndimage.generate_binary_structure(3, connectivity)
    labels, _ = ndimage.label(~solid, structure=structure)
    outside = labels == labels[0, 0, 0]
    interior = ~solid & ~outside
    return interior


def test_axis_aligned_cube_is_a_one_voxel_hollow_shell():
    scene = voxelize_mesh(_cube(), 32)
    assert tuple(scene.extent) == (32, 32, 32)
    assert len(scene) == 32**3 - 30**3  # outer layer only: hollow, no holes, no thickening
    interior = _outside_reaches_inside(scene, connectivity=1)
    assert interior.sum() == 30**3


@pytest.mark.parametrize("connectivity", [1, 3])
def test_rotated_closed_meshes_do_not_leak(connectivity):
    """Flood fill from outside never reaches the inside (6- and 26-connected)."""
    import trimesh

    rng = np.random.default_rng(7)
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    cube = _cube(rotation=q)
    sphere_tm = trimesh.creation.icosphere(subdivisions=3)
    sphere = TriangleMesh(
        sphere_tm.vertices, sphere_tm.faces, face_color=np.full((len(sphere_tm.faces), 3), 0.5)
    )
    for mesh, res in ((cube, 40), (sphere, 48)):
        scene = voxelize_mesh(mesh, res)
        interior = _outside_reaches_inside(scene, connectivity)
        assert interior.sum() > 0.2 * res**3 / 8
        centre = tuple(int(c) for c in (scene.coords.min(0) + scene.coords.max(0)) // 2 + 1)
        assert interior[centre]


def test_thread_count_does_not_change_the_result():
    import trimesh

    tm = trimesh.creation.icosphere(subdivisions=2)
    mesh = TriangleMesh(tm.vertices, tm.faces, face_color=np.random.default_rng(0).random((320, 3)))
    before = numba.get_num_threads()
    try:
        numba.set_num_threads(1)
        one = voxelize_mesh(mesh, 40)
    finally:
        numba.set_num_threads(before)
    many = voxelize_mesh(mesh, 40)
    np.testing.assert_array_equal(one.coords, many.coords)
    np.testing.assert_array_equal(one.color, many.color)


def test_vertex_colours_are_interpolated_at_the_closest_point():
    """A quad whose vertex colour ramps along x: voxel column i sees (i + 0.5) / 16."""
    verts = np.array([[0, 0.5, 0], [1, 0.5, 0], [1, 0.5, 1], [0, 0.5, 1]], float)
    vc = np.array([[0, 0, 0], [1, 1, 1], [1, 1, 1], [0, 0, 0]], float)
    mesh = TriangleMesh(verts, [[0, 1, 2], [0, 2, 3]], face_color=np.ones((2, 3)), vertex_color=vc)
    scene = voxelize_mesh(mesh, 16)
    np.testing.assert_allclose(scene.color[:, 0], (scene.coords[:, 0] + 0.5) / 16, atol=1e-4)


def test_textured_obj_quad_samples_the_right_texels(tmp_path):
    """OBJ convention: vt v = 0 is the image bottom; texels are sRGB-decoded, times Kd."""
    img = np.zeros((64, 64, 3), np.uint8)
    img[:32] = (200, 30, 30)  # top half red
    img[32:] = (30, 30, 200)  # bottom half blue
    Image.fromarray(img).save(tmp_path / "tex.png")
    (tmp_path / "q.mtl").write_text("newmtl m\nKd 1 1 0.5\nmap_Kd -s 1 1 1 tex.png\n")
    (tmp_path / "q.obj").write_text(
        "mtllib q.mtl\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n"
        "vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nusemtl m\nf 1/1 2/2 3/3 4/4\n"
    )
    scene = voxelize_mesh(load_mesh(tmp_path / "q.obj"), 16)
    red = srgb_to_linear(np.array([200, 30, 30]) / 255) * [1, 1, 0.5]
    blue = srgb_to_linear(np.array([30, 30, 200]) / 255) * [1, 1, 0.5]
    y = scene.coords[:, 1]
    assert (y >= 9).sum() > 50 and (y <= 6).sum() > 50
    np.testing.assert_allclose(scene.color[y >= 9] - red, 0.0, atol=1e-6)
    np.testing.assert_allclose(scene.color[y <= 6] - blue, 0.0, atol=1e-6)


def test_placement_keeps_axes_and_spans_resolution():
    mesh = _cube()
    mesh = TriangleMesh(mesh.vertices * [2.0, 1.0, 0.5] + 7, mesh.triangles, mesh.face_color)
    place = place_mesh(mesh, 64, padding=3)
    assert place.shape == (64 + 6, 32 + 6, 16 + 6)
    scene = voxelize_mesh(mesh, 64, padding=3)
    lo, hi = scene.bounds
    assert tuple(lo) == (3, 3, 3) and tuple(hi) == (67, 35, 19)
    voxel = place.to_voxel(np.array([[7.0, 7.0, 7.0], [9.0, 8.0, 7.5]]))
    np.testing.assert_allclose(voxel, [[3, 3, 3], [67, 35, 19]], atol=1e-3)


@pytest.mark.parametrize(
    "kwargs", [{"resolution": 0}, {"resolution": 2.5}, {"resolution": "8"}, {"padding": -1}]
)
def test_bad_parameters_raise(kwargs):
    with pytest.raises(VoxfieldError):
        voxelize_mesh(_cube(), **{"resolution": 8, **kwargs})


# --------------------------------------------------------------------------------------------
# Real data


def _mesh_file(*parts):
    path = data_root().joinpath("mesh", *parts)
    if not path.is_file():
        pytest.skip(f"shared data file {path} is absent (set VOXFIELD_DATA to the data folder)")
    return path


def test_cornell_box_512_walls_on_the_correct_sides():
    """Red left wall at -x, green right wall at +x; the light's emission sits under the ceiling."""
    mesh = load_mesh(_mesh_file("cornell", "CornellBox-Original.obj"))
    scene = voxelize_mesh(mesh, 512)
    assert tuple(scene.extent) == (510, 502, 512)  # 2.02, 1.99, 2.03 scaled by 512 / 2.03
    red = np.all(np.isclose(scene.color, [0.63, 0.065, 0.05]), axis=1)
    green = np.all(np.isclose(scene.color, [0.14, 0.45, 0.091]), axis=1)
    assert red.sum() > 0.9 * 502 * 512 and green.sum() > 0.9 * 502 * 512
    x = scene.coords[:, 0]
    # The left wall leans over x in [-1.02, -0.99] (0.03 × 512 / 2.03 ≈ 7.6 voxels); the right
    # wall is the plane x = 1.00, the box's far side.
    assert x[red].max() <= 8 and (x[green] == 509).all()
    # Away from the corners each wall column is red/green throughout.
    mid = (np.abs(scene.coords[:, 1] - 251) < 200) & (np.abs(scene.coords[:, 2] - 256) < 200)
    assert red[mid & (x <= 1)].all() and green[mid & (x >= 508)].all()
    lit = scene.emission.max(axis=1) > 0
    np.testing.assert_allclose(scene.emission[lit] - [17, 12, 4], 0.0)
    assert scene.coords[lit, 1].min() >= 498 and lit.sum() > 0.5 * (0.47 * 0.38) * 252**2


@pytest.mark.parametrize("name, n_tris", [("bunny.obj", 69666), ("dragon.obj", 100000)])
def test_stanford_meshes_voxelize(name, n_tris):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # their MTL files are missing
        mesh = load_mesh(_mesh_file("stanford", name))
    assert len(mesh) == n_tris
    scene = voxelize_mesh(mesh, 128)
    assert scene.extent.max() == 128
    assert len(scene) > 10_000
    # Every triangle's centroid lies in an occupied voxel.
    place = place_mesh(mesh, 128)
    centroid = place.to_voxel(mesh.vertices[mesh.triangles].mean(axis=1))
    cells = np.floor(centroid).astype(np.int64)
    key = lambda c: (c[:, 0] * 1000 + c[:, 1]) * 1000 + c[:, 2]  # noqa: E731
    assert np.isin(key(cells), key(scene.coords)).all()
