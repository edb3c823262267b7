"""Conservative surface voxelization of triangle meshes (Numba), with per-voxel surface colour.

A voxel ``(i, j, k)`` is the closed box ``[i, i+1] × [j, j+1] × [k, k+1]`` in voxel units; it is
occupied when it overlaps any triangle, decided exactly by the separating-axis test of
Akenine-Möller (2001): 3 box axes, the triangle normal, 9 edge × axis cross products. Closed
boxes make the shell of a closed mesh leak-free under 6- and 26-connectivity; a surface lying
exactly on a voxel face occupies both neighbours (``place_mesh`` insets the mesh by a
millionth of its size and centres it, so its outer faces never sit exactly on a grid plane).

Speed: candidates are not the triangle's whole bounding box but, for each column of the
dominant normal axis, only the 1–3 voxels the triangle's plane slab crosses, so a wall-sized
triangle costs its area, not its volume. Two parallel passes over triangles (count, then fill at
prefix-summed offsets) make the output independent of the thread count.

Colour choice: each voxel takes the colour of the triangle whose surface passes closest to the
voxel centre, sampled at that closest point (vertex colours interpolated, textures bilinearly
filtered there); ties go to the lower triangle index. Averaging the overlapping triangles
instead would invent colours no surface has where materials meet (a pink voxel between the
red wall and the white ceiling); the closest surface is what a ray through the voxel centre
would most plausibly see.
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np
from numba import njit, prange

from voxfield.checks import integer_in
from voxfield.errors import SceneTooLargeError, VoxfieldError
from voxfield.scene.mesh import TriangleMesh
from voxfield.scene.voxel_scene import MAX_EXTENT, VoxelScene

#: Relative inset of the mesh inside its voxel range (keeps outer faces off grid planes).
INSET = 1e-6

#: Refuse jobs whose (voxel, triangle) pair buffers would exceed this many bytes.
PAIR_BUDGET_BYTES = 8 << 30
_PAIR_BYTES = 8 + 8 + 4 + 8  # key, distance², triangle, barycentrics (2 × float32)


@dataclass(frozen=True)
class GridPlacement:
    """Where a mesh lands in voxel space: ``voxel = world * scale + offset``.

    ``shape`` is the voxel grid (padding included) the mesh's voxels lie in.
    """

    scale: float
    offset: np.ndarray
    shape: tuple[int, int, int]

    def to_voxel(self, points: np.ndarray) -> np.ndarray:
        """World points (…×3, mesh units) in continuous voxel coordinates."""
        return np.asarray(points, dtype=np.float64) * self.scale + self.offset


def place_mesh(mesh: TriangleMesh, resolution: int = 512, *, padding: int = 0) -> GridPlacement:
    """Uniform scale and offset that make the mesh's longest side span ``resolution`` voxels.

    Axes are kept (+y stays up); each axis is centred in the whole voxels it needs (the longest
    side in exactly ``resolution``). ``padding`` empty voxels are added before the mesh on every
    axis and after it in ``shape``.
    """
    resolution = integer_in(resolution, "resolution", 1)
    padding = integer_in(padding, "padding", 0)
    if resolution + 2 * padding > min(MAX_EXTENT, 1 << 20):
        raise SceneTooLargeError(
            f"resolution {resolution} with padding {padding} exceeds the largest grid "
            f"({min(MAX_EXTENT, 1 << 20)} voxels per axis); choose a smaller resolution"
        )
    lo, hi = mesh.bounds
    longest = float((hi - lo).max())
    if not np.isfinite(longest) or longest <= 0.0:
        raise VoxfieldError(f"mesh {mesh.name!r} has no extent to voxelize")
    scale = resolution * (1.0 - 2.0 * INSET) / longest
    if not np.isfinite(scale):  # a side of a few denormals: its reciprocal overflows
        raise VoxfieldError(f"mesh {mesh.name!r} is too small to voxelize (its longest side "
                            f"is {longest:g})")
    span = (hi - lo) * scale
    # Each axis gets the fewest whole voxels that hold it, with the mesh centred in them, so
    # no outer face sits on a grid plane (which would occupy one extra layer).
    count = np.maximum(np.ceil(span), 1.0)
    slack = count - span
    tight = slack < 1e-9 * resolution
    count[tight] += 1.0
    slack[tight] += 1.0
    offset = padding + 0.5 * slack - lo * scale
    shape = tuple(int(n) + 2 * padding for n in count)
    return GridPlacement(scale=scale, offset=offset, shape=shape)


def voxelize_mesh(mesh: TriangleMesh, resolution: int = 512, *, padding: int = 0) -> VoxelScene:
    """Voxelize the mesh surface: every voxel a triangle touches, coloured by the closest one.

    See the module docstring for the overlap rule and the colour choice. Emission (MTL ``Ke``)
    is carried into ``VoxelScene.emission`` when the mesh has any.
    """
    place = place_mesh(mesh, resolution, padding=padding)
    verts = place.to_voxel(mesh.vertices)
    coords, tri, bary = surface_voxels(verts, mesh.triangles, place.shape)
    color = surface_color(mesh, tri, bary)
    emission = None
    if mesh.face_emission is not None:
        emission = mesh.face_emission[tri]
    return VoxelScene(coords=coords, color=color, emission=emission, name=mesh.name)


def surface_voxels(
    vertices: np.ndarray, triangles: np.ndarray, shape: tuple[int, int, int]
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Unique voxels overlapping the triangles, in voxel coordinates, clipped to ``shape``.

    Returns ``coords`` (N×3 int64, sorted x-major), the closest triangle per voxel (N int64)
    and the barycentric weights (N×3 float32) of the point on it closest to the voxel centre.
    """
    v = np.ascontiguousarray(vertices, dtype=np.float64)
    t = np.ascontiguousarray(triangles, dtype=np.int64)
    dims = np.asarray(shape, dtype=np.int64)
    if v.ndim != 2 or v.shape[1] != 3 or t.ndim != 2 or t.shape[1] != 3 or dims.shape != (3,):
        raise VoxfieldError("surface_voxels needs V×3 vertices, T×3 triangles and a 3-axis shape")
    if len(t) and (t.min() < 0 or t.max() >= len(v)):
        raise VoxfieldError("triangle indices out of range")
    if not np.isfinite(v).all():
        raise VoxfieldError("vertex coordinates contain NaN or infinite values")
    if (dims < 1).any():
        raise VoxfieldError(f"grid shape must be positive, got {tuple(shape)}")
    if len(t) == 0:
        empty = np.zeros((0, 3), np.int64)
        return empty, np.zeros(0, np.int64), np.zeros((0, 3), np.float32)
    n_chunks = _chunk_count(len(t))
    counts = np.zeros(len(t), dtype=np.int64)
    offsets = np.zeros(len(t) + 1, dtype=np.int64)
    keys = np.empty(0, dtype=np.int64)
    dist2 = np.empty(0, dtype=np.float64)
    tri = np.empty(0, dtype=np.int32)
    bary = np.empty((0, 2), dtype=np.float32)
    _walk_pass(v, t, dims, n_chunks, False, offsets, counts, keys, dist2, tri, bary)
    np.cumsum(counts, out=offsets[1:])
    total = int(offsets[-1])
    if total * _PAIR_BYTES > PAIR_BUDGET_BYTES:
        raise SceneTooLargeError(
            f"voxelizing {len(t)} triangles at grid {tuple(shape)} needs {total:,} "
            f"voxel-triangle pairs (~{total * _PAIR_BYTES / 2**30:.1f} GiB); "
            "choose a smaller resolution"
        )
    keys = np.empty(total, dtype=np.int64)
    dist2 = np.empty(total, dtype=np.float64)
    tri = np.empty(total, dtype=np.int32)
    bary = np.empty((total, 2), dtype=np.float32)
    _walk_pass(v, t, dims, n_chunks, True, offsets, counts, keys, dist2, tri, bary)
    order = np.argsort(keys, kind="stable")
    win = _pick_closest(keys, dist2, tri, order)
    k = keys[win]
    coords = np.stack(np.unravel_index(k, tuple(int(d) for d in dims)), axis=1).astype(np.int64)
    b = np.empty((len(win), 3), dtype=np.float32)
    b[:, 1:] = bary[win]
    b[:, 0] = 1.0 - b[:, 1] - b[:, 2]
    return coords, tri[win].astype(np.int64), b


def surface_color(mesh: TriangleMesh, tri: np.ndarray, bary: np.ndarray) -> np.ndarray:
    """Linear colour of the mesh surface at barycentric points ``bary`` of triangles ``tri``."""
    color = mesh.face_color[tri].astype(np.float32)
    if mesh.vertex_color is not None:
        corners = mesh.vertex_color[mesh.triangles[tri]]  # N×3 corners×3 rgb
        color *= np.einsum("nc,ncr->nr", bary, corners).astype(np.float32)
    if mesh.textures:
        ft = mesh.face_texture[tri]
        uv = np.einsum("nc,ncu->nu", bary, mesh.uv[tri])
        for i, image in enumerate(mesh.textures):
            sel = ft == i
            if sel.any():
                color[sel] *= sample_bilinear(image, uv[sel])
    return np.clip(color, 0.0, 1.0)


def sample_bilinear(image: np.ndarray, uv: np.ndarray) -> np.ndarray:
    """Bilinear, repeat-wrapped texture lookup; ``v = 0`` is the image's bottom row."""
    h, w = image.shape[:2]
    x = uv[:, 0].astype(np.float64) * w - 0.5
    y = (1.0 - uv[:, 1].astype(np.float64)) * h - 0.5
    x0 = np.floor(x)
    y0 = np.floor(y)
    fx = (x - x0)[:, None].astype(np.float32)
    fy = (y - y0)[:, None].astype(np.float32)
    x0 = x0.astype(np.int64)
    y0 = y0.astype(np.int64)
    xa, xb = x0 % w, (x0 + 1) % w
    ya, yb = y0 % h, (y0 + 1) % h
    top = image[ya, xa] * (1 - fx) + image[ya, xb] * fx
    bottom = image[yb, xa] * (1 - fx) + image[yb, xb] * fx
    return (top * (1 - fy) + bottom * fy).astype(np.float32)


def _chunk_count(n_tris: int) -> int:
    """Enough chunks that the threads' static shares balance big and small triangles."""
    return max(1, min(n_tris, 64 * numba.get_num_threads()))


# --------------------------------------------------------------------------------------------
# Numba kernels. Per triangle: 13 candidate separating axes with the triangle's projected
# interval precomputed, so each candidate voxel costs 13 dot products with its centre.


@njit(cache=True, nogil=True)
def _setup_axes(v, t, tri, axes):
    """Fill ``axes`` (13×6: ax, ay, az, lo, hi, radius) for triangle ``tri``."""
    i0, i1, i2 = t[tri, 0], t[tri, 1], t[tri, 2]
    p0x, p0y, p0z = v[i0, 0], v[i0, 1], v[i0, 2]
    p1x, p1y, p1z = v[i1, 0], v[i1, 1], v[i1, 2]
    p2x, p2y, p2z = v[i2, 0], v[i2, 1], v[i2, 2]
    e0x, e0y, e0z = p1x - p0x, p1y - p0y, p1z - p0z
    e1x, e1y, e1z = p2x - p1x, p2y - p1y, p2z - p1z
    e2x, e2y, e2z = p0x - p2x, p0y - p2y, p0z - p2z
    # Box face normals.
    axes[0, 0], axes[0, 1], axes[0, 2] = 1.0, 0.0, 0.0
    axes[1, 0], axes[1, 1], axes[1, 2] = 0.0, 1.0, 0.0
    axes[2, 0], axes[2, 1], axes[2, 2] = 0.0, 0.0, 1.0
    # Triangle normal.
    axes[3, 0] = e0y * e1z - e0z * e1y
    axes[3, 1] = e0z * e1x - e0x * e1z
    axes[3, 2] = e0x * e1y - e0y * e1x
    # Unit box axis × edge, for the three edges.
    row = 4
    for k in range(3):
        if k == 0:
            ex, ey, ez = e0x, e0y, e0z
        elif k == 1:
            ex, ey, ez = e1x, e1y, e1z
        else:
            ex, ey, ez = e2x, e2y, e2z
        axes[row, 0], axes[row, 1], axes[row, 2] = 0.0, -ez, ey  # x × e
        axes[row + 1, 0], axes[row + 1, 1], axes[row + 1, 2] = ez, 0.0, -ex  # y × e
        axes[row + 2, 0], axes[row + 2, 1], axes[row + 2, 2] = -ey, ex, 0.0  # z × e
        row += 3
    for a in range(13):
        ax, ay, az = axes[a, 0], axes[a, 1], axes[a, 2]
        d0 = ax * p0x + ay * p0y + az * p0z
        d1 = ax * p1x + ay * p1y + az * p1z
        d2 = ax * p2x + ay * p2y + az * p2z
        axes[a, 3] = min(d0, min(d1, d2))
        axes[a, 4] = max(d0, max(d1, d2))
        axes[a, 5] = 0.5 * (abs(ax) + abs(ay) + abs(az))


@njit(cache=True, nogil=True)
def _overlaps(axes, cx, cy, cz):
    """Separating-axis test of the prepared triangle against the unit box centred at c."""
    for a in range(13):
        c = axes[a, 0] * cx + axes[a, 1] * cy + axes[a, 2] * cz
        r = axes[a, 5]
        if axes[a, 3] - c > r or axes[a, 4] - c < -r:
            return False
    return True


@njit(cache=True, nogil=True)
def _closest_point(px, py, pz, ax, ay, az, bx, by, bz, cx, cy, cz):
    """Barycentric (v, w) and squared distance of the point of triangle abc closest to p.

    Ericson, Real-Time Collision Detection §5.1.5, with a guard for degenerate triangles.
    """
    abx, aby, abz = bx - ax, by - ay, bz - az
    acx, acy, acz = cx - ax, cy - ay, cz - az
    apx, apy, apz = px - ax, py - ay, pz - az
    d1 = abx * apx + aby * apy + abz * apz
    d2 = acx * apx + acy * apy + acz * apz
    v = 0.0
    w = 0.0
    done = False
    if d1 <= 0.0 and d2 <= 0.0:
        done = True  # vertex a
    if not done:
        bpx, bpy, bpz = px - bx, py - by, pz - bz
        d3 = abx * bpx + aby * bpy + abz * bpz
        d4 = acx * bpx + acy * bpy + acz * bpz
        cpx, cpy, cpz = px - cx, py - cy, pz - cz
        d5 = abx * cpx + aby * cpy + abz * cpz
        d6 = acx * cpx + acy * cpy + acz * cpz
        vc = d1 * d4 - d3 * d2
        vb = d5 * d2 - d1 * d6
        va = d3 * d6 - d5 * d4
        if d3 >= 0.0 and d4 <= d3:
            v = 1.0  # vertex b
        elif d6 >= 0.0 and d5 <= d6:
            w = 1.0  # vertex c
        # Each edge case divides by the edge's squared length; an edge whose two vertices
        # coincide (a degenerate triangle) has none, and its one point is the answer.
        elif vc <= 0.0 and d1 >= 0.0 and d3 <= 0.0:
            v = d1 / (d1 - d3) if d1 != d3 else 0.0  # edge ab
        elif vb <= 0.0 and d2 >= 0.0 and d6 <= 0.0:
            w = d2 / (d2 - d6) if d2 != d6 else 0.0  # edge ac
        elif va <= 0.0 and (d4 - d3) >= 0.0 and (d5 - d6) >= 0.0:
            span = (d4 - d3) + (d5 - d6)
            w = (d4 - d3) / span if span != 0.0 else 0.0  # edge bc
            v = 1.0 - w
        else:
            denom = va + vb + vc
            if denom > 0.0:
                v = vb / denom
                w = vc / denom
            else:  # degenerate triangle: nearest of the three edges
                v, w = _closest_on_edges(px, py, pz, ax, ay, az, bx, by, bz, cx, cy, cz)
    qx = ax + abx * v + acx * w
    qy = ay + aby * v + acy * w
    qz = az + abz * v + acz * w
    dist2 = (px - qx) ** 2 + (py - qy) ** 2 + (pz - qz) ** 2
    return v, w, dist2


@njit(cache=True, nogil=True)
def _segment_param(px, py, pz, ax, ay, az, bx, by, bz):
    dx, dy, dz = bx - ax, by - ay, bz - az
    den = dx * dx + dy * dy + dz * dz
    if den <= 0.0:
        return 0.0
    s = ((px - ax) * dx + (py - ay) * dy + (pz - az) * dz) / den
    return min(1.0, max(0.0, s))


@njit(cache=True, nogil=True)
def _closest_on_edges(px, py, pz, ax, ay, az, bx, by, bz, cx, cy, cz):
    best_v = 0.0
    best_w = 0.0
    best = np.inf
    for e in range(3):
        if e == 0:  # a → b
            s = _segment_param(px, py, pz, ax, ay, az, bx, by, bz)
            v, w = s, 0.0
        elif e == 1:  # a → c
            s = _segment_param(px, py, pz, ax, ay, az, cx, cy, cz)
            v, w = 0.0, s
        else:  # b → c
            s = _segment_param(px, py, pz, bx, by, bz, cx, cy, cz)
            v, w = 1.0 - s, s
        u = 1.0 - v - w
        qx = u * ax + v * bx + w * cx
        qy = u * ay + v * by + w * cy
        qz = u * az + v * bz + w * cz
        d = (px - qx) ** 2 + (py - qy) ** 2 + (pz - qz) ** 2
        if d < best:
            best, best_v, best_w = d, v, w
    return best_v, best_w


@njit(cache=True, nogil=True)
def _walk_triangle(v, t, tri, dims, axes, cells, write, start, keys, dist2, tris, bary):
    """Count (or, with ``write``, record from ``start``) the voxels triangle ``tri`` overlaps.

    ``axes`` (13×6 float) and ``cells`` (3×3 int: low, high, current voxel) are scratch.
    """
    _setup_axes(v, t, tri, axes)
    lo = cells[0]
    hi = cells[1]
    cell = cells[2]
    for d in range(3):
        # Closed boxes: voxel i meets [min, max] iff min - 1 <= i <= max.
        lo[d] = max(np.int64(np.ceil(axes[d, 3])) - 1, 0)
        hi[d] = min(np.int64(np.floor(axes[d, 4])), dims[d] - 1)
        if lo[d] > hi[d]:
            return 0
    # Slab normal: the triangle normal, or for a degenerate (collinear) triangle any normal
    # of a plane through its longest edge. Every vertex lies within [plo, phi] along it.
    nx, ny, nz = axes[3, 0], axes[3, 1], axes[3, 2]
    if nx == 0.0 and ny == 0.0 and nz == 0.0:
        best = -1.0
        bx = by = bz = 0.0
        for a in range(3):
            i = t[tri, a]
            j = t[tri, (a + 1) % 3]
            ex, ey, ez = v[j, 0] - v[i, 0], v[j, 1] - v[i, 1], v[j, 2] - v[i, 2]
            ln = ex * ex + ey * ey + ez * ez
            if ln > best:
                best, bx, by, bz = ln, ex, ey, ez
        if abs(bx) <= abs(by) and abs(bx) <= abs(bz):
            nx, ny, nz = 0.0, -bz, by  # x × e
        elif abs(by) <= abs(bz):
            nx, ny, nz = bz, 0.0, -bx  # y × e
        else:
            nx, ny, nz = -by, bx, 0.0  # z × e
        if nx == 0.0 and ny == 0.0 and nz == 0.0:
            nx = 1.0  # all three vertices coincide: any plane through them
    plo = np.inf
    phi = -np.inf
    for a in range(3):
        i = t[tri, a]
        d = nx * v[i, 0] + ny * v[i, 1] + nz * v[i, 2]
        plo = min(plo, d)
        phi = max(phi, d)
    # Dominant axis w of the slab normal; (u, v) span the columns.
    anx, any_, anz = abs(nx), abs(ny), abs(nz)
    if anx >= any_ and anx >= anz:
        w, u, vv, nw, nu, nv = 0, 1, 2, nx, ny, nz
    elif any_ >= anz:
        w, u, vv, nw, nu, nv = 1, 2, 0, ny, nz, nx
    else:
        w, u, vv, nw, nu, nv = 2, 0, 1, nz, nx, ny
    gu = -nu / nw
    gv = -nv / nw
    # Plane offsets plo/phi, divided by nw, bound w over the column; widen by a margin far
    # above rounding error (the exact test below decides).
    elo = min(plo / nw, phi / nw) - 1e-6 * (1.0 + abs(plo / nw) + abs(phi / nw))
    ehi = max(plo / nw, phi / nw) + 1e-6 * (1.0 + abs(plo / nw) + abs(phi / nw))
    gu_lo, gu_hi = min(gu, 0.0), max(gu, 0.0)
    gv_lo, gv_hi = min(gv, 0.0), max(gv, 0.0)
    count = 0
    for iu in range(lo[u], hi[u] + 1):
        for iv in range(lo[vv], hi[vv] + 1):
            base = gu * iu + gv * iv
            wmin = elo + base + gu_lo + gv_lo
            wmax = ehi + base + gu_hi + gv_hi
            w0 = max(np.int64(np.ceil(wmin)) - 1, lo[w])
            w1 = min(np.int64(np.floor(wmax)), hi[w])
            cell[u] = iu
            cell[vv] = iv
            for iw in range(w0, w1 + 1):
                cell[w] = iw
                cx = cell[0] + 0.5
                cy = cell[1] + 0.5
                cz = cell[2] + 0.5
                if not _overlaps(axes, cx, cy, cz):
                    continue
                if write:
                    o = start + count
                    keys[o] = (cell[0] * dims[1] + cell[1]) * dims[2] + cell[2]
                    i0, i1, i2 = t[tri, 0], t[tri, 1], t[tri, 2]
                    bv, bw, d2 = _closest_point(
                        cx, cy, cz,
                        v[i0, 0], v[i0, 1], v[i0, 2],
                        v[i1, 0], v[i1, 1], v[i1, 2],
                        v[i2, 0], v[i2, 1], v[i2, 2],
                    )  # fmt: skip
                    dist2[o] = d2
                    tris[o] = tri
                    bary[o, 0] = bv
                    bary[o, 1] = bw
                count += 1
    return count


@njit(cache=True, nogil=True, parallel=True)
def _walk_pass(v, t, dims, n_chunks, write, offsets, counts, keys, dist2, tris, bary):
    """Count every triangle's voxels into ``counts`` or (``write``) record them at ``offsets``.

    One kernel for both passes: a parallel kernel is slow to compile, so compile it once.
    """
    n = t.shape[0]
    for c in prange(n_chunks):
        axes = np.empty((13, 6), np.float64)
        cells = np.empty((3, 3), np.int64)
        # Strided triangles per chunk: neighbouring (similar-sized) triangles spread over chunks.
        for tri in range(c, n, n_chunks):
            start = offsets[tri] if write else 0
            got = _walk_triangle(
                v, t, tri, dims, axes, cells, write, start, keys, dist2, tris, bary
            )
            if not write:
                counts[tri] = got


@njit(cache=True, nogil=True)
def _pick_closest(keys, dist2, tris, order):
    """Per distinct key (visited in ``order``), the pair with the least (distance, triangle)."""
    n = order.shape[0]
    out = np.empty(n, np.int64)
    m = 0
    i = 0
    while i < n:
        best = order[i]
        j = i + 1
        while j < n and keys[order[j]] == keys[order[i]]:
            o = order[j]
            if dist2[o] < dist2[best] or (dist2[o] == dist2[best] and tris[o] < tris[best]):
                best = o
            j += 1
        out[m] = best
        m += 1
        i = j
    return out[:m]
