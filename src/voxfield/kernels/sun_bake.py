"""Sun and sky visibility of surface voxels: shadow rays and cosine-weighted sky rays.

A voxel is a unit cube whose exposed faces (no neighbour voxel behind them) are its surface.
Each exposed face ``f`` (codes 0..5 = −x, +x, −y, +y, −z, +z, the traversal's normal codes)
is treated as a small Lambertian square and gets

* sky visibility ``S_f``: the fraction of cosine-weighted hemisphere rays about its normal,
  started at stratified points of the face, that leave the octree *upwards* (a ray leaving
  downwards sees the ground, not the sky), so an open upward face has 1, an open wall 1/2
  and a face looking down 0;
* sun visibility ``V_f`` per sun: the fraction of shadow rays towards the sun, started at
  stratified points of the face, that hit nothing at LOD 0; only faces turned to the sun
  (``n_f · l > LIT_COSINE``: by more than rounding) of a sun above the horizon cast them.

A voxel has one colour, so its faces are averaged, each weighted by how much of the sky it
sees, ``w_f = S_f`` (by reciprocity, how much of it a viewer above sees). The bottom face of a
one-voxel-thick terrain shell or a cave floor's underside thus does not dim the voxel's
top. ``sky_rays = 0`` turns sky light off and weights faces as if nothing occluded them,
``w_f = (1 + n_f.y) / 2``. Where no face sees the sky the faces weigh equally. Per voxel::

    direct[s] = Σ_f w_f · max(0, n_f · l_s) · V_f / Σ_f w_f      sky = Σ_f w_f · S_f / Σ_f w_f

and ``Σ_f w_f`` is returned as the voxel's weight in coarse-level averages.

Rays start exactly on the face plane with ``tmin = 0``: under the traversal's half-open slab
contract the voxel's own interval ends at exactly ``t = 0``, so a ray leaving a face never
hits its own voxel and needs no offset, while a neighbour touching the start point still
blocks it. Rays stop where they rise above the highest voxel (``y_top``): nothing can block
them there. A face looking down and a sky ray heading down cannot see the sky, so they are
counted without being traced. All sampling is hashed from the voxel's index and the seed:
results are the same for any thread count and any chunking.

Every traced ray rises, so it first walks the column-top pyramid (``kernels.upward_rays``):
over open ground that settles most rays (clear above the terrain, or blocked by the run of
voxels they dip into) in a few 2D cells; the rest go on through the octree from where the
walk left them, with the answer the octree alone gives. A ray's steps are the pyramid cells
it visits plus the octree nodes it enters. A block's sky rays are drawn voxel by voxel and
then walk together (``kernels.rising_lanes``: in SIMD lanes where those pay), where each
used to walk as soon as it was drawn: on the 2048² desert the kernel took 0.84× the time
with the same answers and steps.

A sky ray that starts at or above its column's top and rises more steeply than the
column's horizon slope for its heading (``svo.horizons``; ``upward_rays.clears_horizon``) is
clear without a walk: one read, one step. So are all of a face's shadow rays towards one sun
when its rear corner (below) is: they all start in that corner's column, none lower. On a
2048² desert the two took the bake from 1.59G to 1.23G steps.

The other faces' shadow rays towards one sun are parallel and start less than a column
apart: one walk from the face's rear corner over the tops ahead of each cell
(``upward_rays.parallel_rays_clear``) settles all of them when it finds the corner clear,
which on open ground most lit faces are (a 2048² desert's bake took 0.78× the steps).
Its cells are counted once, for the face; a face it does not settle has its rays walked one
by one after it, each from where the corner's walk stopped: up to there every ray was
above everything it passed (1.23G to 1.14G steps on the desert). The visibility is the same
either way.

Blocks of voxels are dealt out to the threads in turn (``kernels.scheduling``): a terrain's
halves rarely cost the same.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from voxfield.kernels.borrowing import borrowing
from voxfield.kernels.colour import node_rgb
from voxfield.kernels.packet_traversal import PACKET_RAYS, new_packet_scratch, trace_packet
from voxfield.kernels.rising_lanes import new_rising_walks, walk_rising_rays
from voxfield.kernels.sampling import (
    cmj_sample_in,
    cmj_strata,
    hash_u32,
    new_cmj_strata,
    pixel_pattern,
)
from voxfield.kernels.scheduling import claim_items, new_run_queue
from voxfield.kernels.traversal import MISS, new_scratch, occluded
from voxfield.kernels.upward_rays import (
    BLOCKED,
    UNDECIDED,
    clears_horizon,
    parallel_rays_clear,
    rising_ray_query,
)

_GOLDEN = 0x9E3779B9
_POSITION_SALT = 0x68E31DA4
_SHADOW_SALT = 0xB5297A4D
#: Code of the face looking down (−y).
FACE_DOWN = 2
#: Surface voxels per parallel task; their shadow rays towards one sun share packets, and
#: their sky rays walk the pyramid together (``trace_sky_queue``). On the 2048² desert the
#: bake's kernel took 0.95× the time with 128 as with 32, 0.93× with 256 (longer queues
#: keep the lanes busier; before the sky rays were queued, 32 and 128 read the same).
BAKE_BLOCK = 128
#: Sky rays a block queues before it walks them (more when one voxel casts more).
SKY_QUEUE_RAYS = 2048
#: The cosine between a face's normal and the sun above which the sun lights the face. A
#: sun's direction comes from degrees through float64 sines and cosines, so a component
#: that is zero in exact arithmetic comes out as up to about 1e-16 (cos 90° is 6.1e-17):
#: with ``> 0`` a sun at the zenith grazed the walls on one side and not the other, by its
#: azimuth. 1e-9 is millions of times that rounding, and the light it leaves out is none a
#: channel keeps: at most a billionth of the sun's, below float32's resolution (1.2e-7) of
#: what the face gets square to the sun, from a sun within 6e-8° of the face's plane.
LIT_COSINE = 1e-9


@njit(cache=True, nogil=True)
def face_axis_sign(face: int) -> tuple[int, float]:
    """Axis (0 x, 1 y, 2 z) and outward sign of face code ``face``."""
    return face // 2, (1.0 if face % 2 == 1 else -1.0)


@njit(cache=True, nogil=True)
def face_point(
    x: int, y: int, z: int, face: int, u: float, v: float
) -> tuple[float, float, float]:
    """The point ``(u, v)`` in ``[0, 1)²`` of face ``face`` of voxel ``(x, y, z)``: exactly
    on the face's plane, ``u`` and ``v`` along the next two axes in cyclic order."""
    axis, sign = face_axis_sign(face)
    c0 = float(x)
    c1 = float(y)
    c2 = float(z)
    plane = 1.0 if sign > 0.0 else 0.0
    if axis == 0:
        return c0 + plane, c1 + u, c2 + v
    if axis == 1:
        return c0 + v, c1 + plane, c2 + u
    return c0 + u, c1 + v, c2 + plane


# Taylor coefficients of sin and cos about 0 to the 15th and 16th power: on [-π/4, π/4]
# the first term left out is below 5e-17, under half an ulp of the results.
_S3, _S5, _S7, _S9 = -1.0 / 6.0, 1.0 / 120.0, -1.0 / 5040.0, 1.0 / 362880.0
_S11, _S13, _S15 = -1.0 / 39916800.0, 1.0 / 6227020800.0, -1.0 / 1307674368000.0
_C2, _C4, _C6, _C8 = -0.5, 1.0 / 24.0, -1.0 / 720.0, 1.0 / 40320.0
_C10, _C12, _C14 = -1.0 / 3628800.0, 1.0 / 479001600.0, -1.0 / 87178291200.0
_C16 = 1.0 / 20922789888000.0
#: ``cos`` and ``sin`` of ``q`` quarter turns.
_QUARTER_COS = np.array([1.0, 0.0, -1.0, 0.0, 1.0])
_QUARTER_SIN = np.array([0.0, 1.0, 0.0, -1.0, 0.0])


@njit(cache=True, nogil=True, inline="always")
def cos_sin_turns(u: float) -> tuple[float, float]:
    """``(cos 2πu, sin 2πu)`` for ``0 <= u <= 1``, within a few ulps of ``math``'s. The
    nearest quarter turn ``q`` is split off exactly (``u - q/4`` is exact: Sterbenz), the
    rest, at most an eighth of a turn, goes through two short polynomials, and the quarter
    turn is a rotation by table. Every sky ray needs both: the library's ``sincos`` took
    about a tenth of a sun bake's kernel time."""
    q = int(u * 4.0 + 0.5)
    a = (u - 0.25 * q) * (2.0 * math.pi)
    a2 = a * a
    s = a + a * a2 * (_S3 + a2 * (_S5 + a2 * (_S7 + a2 * (_S9 + a2 * (
        _S11 + a2 * (_S13 + a2 * _S15))))))
    c = 1.0 + a2 * (_C2 + a2 * (_C4 + a2 * (_C6 + a2 * (_C8 + a2 * (_C10 + a2 * (
        _C12 + a2 * (_C14 + a2 * _C16)))))))
    return c * _QUARTER_COS[q] - s * _QUARTER_SIN[q], s * _QUARTER_COS[q] + c * _QUARTER_SIN[q]


@njit(cache=True, nogil=True)
def cosine_direction(face: int, u1: float, u2: float) -> tuple[float, float, float]:
    """A cosine-weighted direction about face ``face``'s outward normal (Malley's method:
    uniform on the disk, lifted to the hemisphere)."""
    axis, sign = face_axis_sign(face)
    r = math.sqrt(u1)
    cos_phi, sin_phi = cos_sin_turns(u2)
    a = r * cos_phi
    b = r * sin_phi
    n = sign * math.sqrt(max(0.0, 1.0 - u1))
    if axis == 0:
        return n, a, b
    if axis == 1:
        return b, n, a
    return a, b, n


@njit(cache=True, nogil=True)
def pattern_shape(count: int) -> tuple[int, int]:
    """An m×n CMJ grid with at least ``count`` cells, as square as possible."""
    m = max(1, int(math.sqrt(count)))
    while m * m > count and m > 1:
        m -= 1
    return m, (count + m - 1) // m


@njit(cache=True, nogil=True, inline="always")
def face_sample(s: int, i: int, j: int, count: int, m: int, n: int, pattern: int,
                column: np.ndarray, row: np.ndarray) -> tuple[float, float]:
    """Sample ``s`` (column ``i``, row ``j``) of ``count`` stratified points in ``[0, 1)²``
    drawn from ``pattern``'s strata (``sampling.cmj_strata``); one sample is the centre."""
    if count == 1:
        return 0.5, 0.5
    return cmj_sample_in(s, i, j, m, n, pattern, column, row)


@njit(cache=True, nogil=True, inline="always")
def next_stratum(i: int, j: int, m: int) -> tuple[int, int]:
    """Column and row of the sample after column ``i``, row ``j`` of an ``m``-column
    pattern (start from ``(-1, 0)``): samples fill a pattern row by row."""
    i += 1
    if i == m:
        return 0, j + 1
    return i, j


@njit(cache=True, nogil=True)
def new_strata(count: int):
    """Stratum tables (``sampling.cmj_strata``) for two patterns of up to ``count``
    samples: columns and rows of the first, then of the second."""
    return new_cmj_strata(count + 1) + new_cmj_strata(count + 1)


@njit(cache=True, nogil=True, inline="always")
def most_sky_rays(sky_rays: int) -> int:
    """The most sky rays one voxel casts: ``sky_rays``, or one for each of up to five faces
    that can see up when that is more."""
    return max(sky_rays, 5)


@njit(cache=True, nogil=True)
def new_sky_queue(sky_rays: int):
    """A block's queued sky rays and their walks (``rising_lanes.new_rising_walks``), the
    (block voxel, face) each belongs to, and per block voxel and face the rays drawn and
    those that escaped."""
    n = max(SKY_QUEUE_RAYS, most_sky_rays(sky_rays))
    return (new_rising_walks(n), np.empty(n, np.int64), np.empty(n, np.int64),
            np.zeros((BAKE_BLOCK, 6), np.int64), np.zeros((BAKE_BLOCK, 6), np.int64))


@borrowing
def draw_sky_rays(
    x: int, y: int, z: int, voxel_pattern: int, faces: int, sky_rays: int, y_top: float,
    columns, horizons: np.ndarray, strata, queue, queued: int, j: int,
) -> tuple[int, int, int]:
    """Draw the sky rays of block voxel ``j`` at ``(x, y, z)`` (``faces``: bit ``f`` set for
    exposed face ``f``): per face, how many it gets and how many its horizon clears, in
    ``queue``'s counts; the others are queued from row ``queued`` on, to be walked with the
    block's. ``(next free row, rays cast, steps)``. ``horizons`` are ``columns``' horizon
    slopes (``svo.horizons``; empty: none), ``strata`` is ``new_strata(sky_rays)``."""
    walks, ray_voxel, ray_face, face_rays, face_escaped = queue
    rays = walks[0]
    # A face looking down (−y) sees no sky and no sun above the horizon: it gets no rays.
    open_faces = 0
    for f in range(6):
        face_rays[j, f] = 0
        face_escaped[j, f] = 0
        if (faces >> f) & 1 and f != FACE_DOWN:
            open_faces += 1
    steps = 0
    sky_cast = 0
    if sky_rays == 0:
        return queued, sky_cast, steps
    # ``sky_rays`` per voxel shared among its faces that can see up, at least one each.
    k = 0
    for f in range(6):
        if not (faces >> f) & 1 or f == FACE_DOWN:
            continue
        count = max(1, sky_rays // open_faces + (1 if k < sky_rays % open_faces else 0))
        face_rays[j, f] = count
        k += 1
        face_pattern = hash_u32(voxel_pattern ^ ((f + 1) * _GOLDEN))
        position_pattern = hash_u32(face_pattern + _POSITION_SALT)
        m, n = pattern_shape(count)
        cmj_strata(m, n, face_pattern, strata[0], strata[1])
        cmj_strata(m, n, position_pattern, strata[2], strata[3])
        i = -1  # sample s is column i, row ``row`` of the m×n patterns
        row = 0
        for s in range(count):
            i, row = next_stratum(i, row, m)
            u1, u2 = cmj_sample_in(s, i, row, m, n, face_pattern, strata[0], strata[1])
            dx, dy, dz = cosine_direction(f, u1, u2)
            if dy <= 0.0:
                continue  # it would see the ground at best: no sky, no need to trace
            pu, pv = face_sample(s, i, row, count, m, n, position_pattern, strata[2],
                                 strata[3])
            ox, oy, oz = face_point(x, y, z, f, pu, pv)
            sky_cast += 1
            if clears_horizon(ox, oy, oz, dx, dy, dz, columns, horizons):
                steps += 1  # the horizon slope read
                face_escaped[j, f] += 1
                continue
            rays[queued, 0], rays[queued, 1], rays[queued, 2] = ox, oy, oz
            rays[queued, 3], rays[queued, 4], rays[queued, 5] = dx, dy, dz
            rays[queued, 6] = (y_top - oy) / dy
            ray_voxel[queued] = j
            ray_face[queued] = f
            queued += 1
    return queued, sky_cast, steps


@borrowing
def trace_sky_queue(count: int, queue, columns, inner_nodes: np.ndarray, depth: int,
                    scratch, first: int, out_steps: np.ndarray) -> None:
    """Trace a block's ``count`` queued sky rays: all walk the pyramid together
    (``rising_lanes.walk_rising_rays``), those it leaves undecided go on through the octree;
    each escaped ray counts for its face, its steps for its voxel (row ``first + voxel`` of
    ``out_steps``)."""
    (rays, verdicts, times, walk_steps), ray_voxel, ray_face, _, face_escaped = queue
    walk_rising_rays(rays, count, columns, verdicts, times, walk_steps)
    for r in range(count):
        blocked = verdicts[r] == BLOCKED
        steps = walk_steps[r]
        if verdicts[r] == UNDECIDED:
            blocked, octree_steps = occluded(rays[r, 0], rays[r, 1], rays[r, 2], rays[r, 3],
                                             rays[r, 4], rays[r, 5], times[r], rays[r, 6],
                                             inner_nodes, depth, scratch)
            steps += octree_steps
        out_steps[first + ray_voxel[r]] += steps
        if not blocked:
            face_escaped[ray_voxel[r], ray_face[r]] += 1


@njit(cache=True, nogil=True, inline="always")
def sky_terms(faces: int, sky_rays: int, face_rays: np.ndarray, face_escaped: np.ndarray,
              face_sky: np.ndarray, face_weight: np.ndarray) -> tuple[float, float, float]:
    """One voxel's sky visibility from its faces' rays drawn and escaped: fills its per-face
    sky visibility and weights and returns ``(sky, weight seen, weight total)``; a voxel
    none of whose faces sees the sky gets equal face weights, which its total then sums
    (module docstring)."""
    exposed = 0
    total_weight = 0.0
    for f in range(6):
        face_sky[f] = 0.0
        face_weight[f] = 0.0
        if not (faces >> f) & 1:
            continue
        exposed += 1
        if f == FACE_DOWN:
            continue
        if sky_rays == 0:
            axis, sign = face_axis_sign(f)
            face_weight[f] = 0.5 * (1.0 + (sign if axis == 1 else 0.0))
        else:
            face_sky[f] = face_escaped[f] / face_rays[f]
            face_weight[f] = face_sky[f]
        total_weight += face_weight[f]
    seen_weight = total_weight
    if total_weight == 0.0:
        # No face sees the sky (a cave, an underside): its faces count equally.
        for f in range(6):
            face_weight[f] = 1.0 if (faces >> f) & 1 else 0.0
        total_weight = float(exposed)
    sky = 0.0
    for f in range(6):
        sky += face_weight[f] * face_sky[f]
    return sky / total_weight, seen_weight, total_weight


@njit(cache=True, nogil=True, inline="always")
def face_cosine(face: int, lx: float, ly: float, lz: float) -> float:
    """Cosine between face ``face``'s outward normal and the unit direction ``l``."""
    axis, sign = face_axis_sign(face)
    return sign * (lx if axis == 0 else (ly if axis == 1 else lz))


@njit(cache=True, nogil=True, inline="always")
def rear_corner(x: int, y: int, z: int, face: int, lx: float, lz: float
                ) -> tuple[float, float, float]:
    """The corner of face ``face`` of voxel ``(x, y, z)`` that every point of the face is
    ahead of (or level with) along ``x`` and ``z`` when travelling along ``l``, and at the
    face's bottom: where ``upward_rays.parallel_rays_clear`` starts for its shadow rays."""
    cx = float(x) if lx >= 0.0 else float(x + 1)
    cy = float(y)
    cz = float(z) if lz >= 0.0 else float(z + 1)
    axis, sign = face_axis_sign(face)
    plane = 1.0 if sign > 0.0 else 0.0
    if axis == 0:
        cx = x + plane
    elif axis == 1:
        cy = y + plane
    else:
        cz = z + plane
    return cx, cy, cz


@njit(cache=True, nogil=True)
def new_shadow_queue():
    """One packet of queued shadow rays: origins, directions, ``tmin`` (0), ``tmax``, the
    (block voxel, face) each belongs to, and the packet's result buffers (node, level,
    ``t``, normal, steps)."""
    return (np.empty((PACKET_RAYS, 3)), np.empty((PACKET_RAYS, 3)), np.zeros(PACKET_RAYS),
            np.empty(PACKET_RAYS), np.empty(PACKET_RAYS, np.int64),
            np.empty(PACKET_RAYS, np.int64), np.empty(PACKET_RAYS, np.int64),
            np.empty(PACKET_RAYS, np.int64), np.empty(PACKET_RAYS),
            np.empty(PACKET_RAYS, np.int64), np.empty(PACKET_RAYS, np.int64))


@borrowing
def trace_shadow_queue(count: int, queue, inner_nodes: np.ndarray, depth: int,
                       packet_scratch, unblocked: np.ndarray, first: int,
                       out_steps: np.ndarray) -> None:
    """Trace the first ``count`` queued shadow rays as one any-hit packet: each ray that
    reaches the sky adds one to ``unblocked[voxel, face]``, and its steps go to its voxel's
    row ``first + voxel`` of ``out_steps``."""
    origins, directions, tmins, tmaxs, voxel, face, node, level, t, normal, ray_steps = queue
    trace_packet(count, origins, directions, tmins, tmaxs, inner_nodes, depth, depth,
                 packet_scratch, node, level, t, normal, ray_steps, True)
    for k in range(count):
        out_steps[first + voxel[k]] += ray_steps[k]
        if node[k] == MISS:
            unblocked[voxel[k], face[k]] += 1


@njit(cache=True, nogil=True)
def new_block_scratch(depth: int, sky_rays: int, shadow_rays: int):
    """What ``bake_block`` works in: traversal and packet scratch, the shadow-ray queue, the
    sampling strata, per-voxel face terms, the shadow rays' start points and the sky-ray
    queue."""
    return (new_scratch(depth), new_packet_scratch(depth), new_shadow_queue(), np.empty(6),
            new_strata(max(sky_rays, shadow_rays)), np.empty((BAKE_BLOCK, 6)),
            np.empty(BAKE_BLOCK), np.empty((BAKE_BLOCK, 6), np.int64),
            np.empty((BAKE_BLOCK, 6, shadow_rays, 2)), new_sky_queue(sky_rays))


@borrowing
def bake_block(
    first: int, last: int, coords: np.ndarray, voxel_ids: np.ndarray, faces: np.ndarray,
    sun_dirs: np.ndarray, sky_rays: int, shadow_rays: int, seed: int,
    inner_nodes: np.ndarray, depth: int, y_top: float, columns, sun_tops: np.ndarray,
    horizons: np.ndarray, out_rows: np.ndarray, out_direct: np.ndarray, out_sky: np.ndarray,
    out_weight: np.ndarray, out_sky_rays: np.ndarray, out_shadow_rays: np.ndarray,
    out_steps: np.ndarray, work,
) -> None:
    """Bake voxels ``first..last-1`` (at most ``BAKE_BLOCK``): the block's sky rays, drawn
    voxel by voxel and walked together (``trace_sky_queue``), then per sun the block's
    shadow rays (from the faces turned to it); those the column walk leaves undecided are
    queued and traced as any-hit packets: parallel rays from neighbouring voxels walk almost
    the same nodes, and a packet loads each node once for all of them. ``columns`` is a
    ``svo.column_tops.ColumnTops`` (empty: octree only); ``work`` is
    ``new_block_scratch``'s."""
    (scratch, packet_scratch, queue, face_sky, strata, face_weight, total_weight, unblocked,
     shadow_points, sky_queue) = work
    origins, directions, tmins, tmaxs, ray_voxel, ray_face = queue[:6]
    face_rays, face_escaped = sky_queue[3:]
    # The queue is walked whenever the next voxel's rays might not fit, and at the end, from
    # one call of ``trace_sky_queue``: LLVM copies a linked helper into its caller at every
    # call site, and a second one made a first bake compile for 81 s instead of 62.
    i = first
    while i < last:
        sky_queued = 0
        while i < last and sky_queued + most_sky_rays(sky_rays) <= sky_queue[0][0].shape[0]:
            sky_queued, out_sky_rays[i], out_steps[i] = draw_sky_rays(
                coords[i, 0], coords[i, 1], coords[i, 2], pixel_pattern(voxel_ids[i], seed),
                faces[i], sky_rays, y_top, columns, horizons, strata, sky_queue, sky_queued,
                i - first)
            out_shadow_rays[i] = 0
            i += 1
        trace_sky_queue(sky_queued, sky_queue, columns, inner_nodes, depth, scratch, first,
                        out_steps)
    for i in range(first, last):
        j = i - first
        out_sky[out_rows[i]], out_weight[out_rows[i]], total_weight[j] = sky_terms(
            faces[i], sky_rays, face_rays[j], face_escaped[j], face_sky, face_weight[j])
    # Each face's shadow-ray start points serve every sun: drawn once.
    m, n = pattern_shape(shadow_rays)
    for i in range(first, last):
        j = i - first
        voxel_pattern = pixel_pattern(voxel_ids[i], seed)
        for f in range(6):
            if face_weight[j, f] == 0.0 or f == FACE_DOWN:
                continue  # no shadow rays (a face looking down never faces a risen sun)
            shadow_pattern = hash_u32(hash_u32(voxel_pattern ^ ((f + 1) * _GOLDEN))
                                      + _SHADOW_SALT)
            cmj_strata(m, n, shadow_pattern, strata[0], strata[1])
            column = -1
            row = 0
            for s in range(shadow_rays):
                column, row = next_stratum(column, row, m)
                pu, pv = face_sample(s, column, row, shadow_rays, m, n, shadow_pattern,
                                     strata[0], strata[1])
                shadow_points[j, f, s, 0] = pu
                shadow_points[j, f, s, 1] = pv
    for sun in range(sun_dirs.shape[0]):
        lx = sun_dirs[sun, 0]
        ly = sun_dirs[sun, 1]
        lz = sun_dirs[sun, 2]
        unblocked[:, :] = 0
        queued = 0
        if ly > 0.0:  # a sun below the horizon lights nothing
            for i in range(first, last):
                j = i - first
                for f in range(6):
                    if face_weight[j, f] == 0.0 or face_cosine(f, lx, ly, lz) <= LIT_COSINE:
                        continue
                    out_shadow_rays[i] += shadow_rays
                    # Every ray of the face starts in the rear corner's column, none lower:
                    # the corner clearing that column's horizon clears them all.
                    px, py, pz = rear_corner(coords[i, 0], coords[i, 1], coords[i, 2], f,
                                             lx, lz)
                    if clears_horizon(px, py, pz, lx, ly, lz, columns, horizons):
                        out_steps[i] += 1
                        unblocked[j, f] += shadow_rays
                        continue
                    t_clear = 0.0
                    if sun_tops.shape[1] > 0:
                        # All the face's rays at once, when the walk from its rear corner
                        # settles them (most lit faces): their verdicts, fewer steps. When
                        # it does not, each ray is still clear until where it stopped.
                        clear, beam_steps, t_clear = parallel_rays_clear(
                            px, py, pz, lx, ly, lz, (y_top - py) / ly, columns,
                            sun_tops[sun])
                        out_steps[i] += beam_steps
                        if clear:
                            unblocked[j, f] += shadow_rays
                            continue
                    for s in range(shadow_rays):
                        ox, oy, oz = face_point(coords[i, 0], coords[i, 1], coords[i, 2], f,
                                                shadow_points[j, f, s, 0],
                                                shadow_points[j, f, s, 1])
                        tmax = (y_top - oy) / ly
                        verdict, t_on, ray_steps = rising_ray_query(ox, oy, oz, lx, ly, lz,
                                                                    tmax, columns, t_clear)
                        out_steps[i] += ray_steps
                        if verdict != UNDECIDED:
                            if verdict != BLOCKED:
                                unblocked[j, f] += 1
                            continue
                        origins[queued, 0] = ox
                        origins[queued, 1] = oy
                        origins[queued, 2] = oz
                        directions[queued, 0] = lx
                        directions[queued, 1] = ly
                        directions[queued, 2] = lz
                        tmins[queued] = t_on
                        tmaxs[queued] = tmax
                        ray_voxel[queued] = j
                        ray_face[queued] = f
                        queued += 1
                        if queued == PACKET_RAYS:
                            trace_shadow_queue(queued, queue, inner_nodes, depth,
                                               packet_scratch, unblocked, first, out_steps)
                            queued = 0
            if queued > 0:
                trace_shadow_queue(queued, queue, inner_nodes, depth, packet_scratch,
                                   unblocked, first, out_steps)
        for i in range(first, last):
            j = i - first
            direct = 0.0
            for f in range(6):
                cos_theta = face_cosine(f, lx, ly, lz)
                if ly > 0.0 and face_weight[j, f] != 0.0 and cos_theta > LIT_COSINE:
                    direct += face_weight[j, f] * cos_theta * (unblocked[j, f] / shadow_rays)
            out_direct[sun, out_rows[i]] = direct / total_weight[j]


@njit(parallel=True, cache=True, nogil=True)
def bake_sun_visibility(
    coords: np.ndarray, voxel_ids: np.ndarray, faces: np.ndarray,
    sun_dirs: np.ndarray, sky_rays: int, shadow_rays: int, seed: int,
    inner_nodes: np.ndarray, depth: int, y_top: float, columns, sun_tops: np.ndarray,
    horizons: np.ndarray, out_rows: np.ndarray, out_direct: np.ndarray, out_sky: np.ndarray,
    out_weight: np.ndarray, out_sky_rays: np.ndarray, out_shadow_rays: np.ndarray,
    out_steps: np.ndarray, threads: int = 1,
) -> None:
    """Bake the listed surface voxels: ``coords[k]`` (octree voxel units), their leaf index
    ``voxel_ids[k]`` (seeds the sampling) and exposed-face bits ``faces[k]``. Voxel ``k``'s
    visibility terms go to row ``out_rows[k]`` of ``out_sky`` and ``out_weight`` (column of
    ``out_direct``, one row per sun; float32 arrays of all voxels take them in place), its
    ray and step counts to row ``k`` of the counters. ``sun_tops[s]`` is
    ``svo.column_tops.tops_ahead`` of ``columns`` for sun ``s``'s direction (``(suns, 0)``:
    every shadow ray walked on its own, with the same visibility); ``horizons`` are their
    horizon slopes (``svo.horizons``; ``(0, 4)``: every sky ray walked). Blocks of voxels
    are claimed by ``threads`` workers as they are free (``kernels.scheduling.claim_run``):
    pass ``numba.get_num_threads()``, as one worker keeps one thread."""
    queue = new_run_queue()
    for _ in prange(threads):
        bake_blocks(queue, coords, voxel_ids, faces, sun_dirs, sky_rays, shadow_rays, seed,
                    inner_nodes, depth, y_top, columns, sun_tops, horizons, out_rows,
                    out_direct, out_sky, out_weight, out_sky_rays, out_shadow_rays, out_steps)


@njit(cache=True, nogil=True)
def bake_blocks(
    queue: np.ndarray, coords: np.ndarray, voxel_ids: np.ndarray, faces: np.ndarray,
    sun_dirs: np.ndarray, sky_rays: int, shadow_rays: int, seed: int,
    inner_nodes: np.ndarray, depth: int, y_top: float, columns, sun_tops: np.ndarray,
    horizons: np.ndarray, out_rows: np.ndarray, out_direct: np.ndarray, out_sky: np.ndarray,
    out_weight: np.ndarray, out_sky_rays: np.ndarray, out_shadow_rays: np.ndarray,
    out_steps: np.ndarray,
) -> None:
    """One thread's share of ``bake_sun_visibility``: blocks claimed from ``queue`` until none
    is left, baked in the thread's own scratch."""
    work = new_block_scratch(depth, sky_rays, shadow_rays)
    n = coords.shape[0]
    while True:
        first, last = claim_items(queue, n, BAKE_BLOCK)
        if first == last:
            return
        bake_block(first, last, coords, voxel_ids, faces, sun_dirs, sky_rays, shadow_rays,
                   seed, inner_nodes, depth, y_top, columns, sun_tops, horizons, out_rows,
                   out_direct, out_sky, out_weight, out_sky_rays, out_shadow_rays, out_steps,
                   work)


@njit(parallel=True, cache=True, nogil=True)
def lit_colours(
    albedo: np.ndarray, direct: np.ndarray, sky: np.ndarray, irradiance: np.ndarray,
    sky_colour: np.ndarray, out: np.ndarray,
) -> None:
    """Per voxel ``i`` and sun ``k``, ``albedo × (irradiance_k × direct[k, i] + sky_colour_k ×
    sky[i])`` worked out in float64 and stored as float32 in ``out[k, i]``: every sun's lit
    leaf colours in one pass. ``albedo`` is the voxels' stored albedo (8-bit sRGB or float32,
    ``kernels.colour``), decoded here; ``out`` may be the voxel rows of a channel block."""
    for i in prange(albedo.shape[0]):
        s = np.float64(sky[i])
        r, g, b = node_rgb(albedo, i)
        for k in range(direct.shape[0]):
            d = np.float64(direct[k, i])
            out[k, i, 0] = r * (d * irradiance[k, 0] + s * sky_colour[k, 0])
            out[k, i, 1] = g * (d * irradiance[k, 1] + s * sky_colour[k, 1])
            out[k, i, 2] = b * (d * irradiance[k, 2] + s * sky_colour[k, 2])
