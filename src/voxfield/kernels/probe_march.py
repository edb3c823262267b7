"""Single-probe ray marching against a light probe's radial distance map (probe thesis ch. 4-7).

A probe at ``P`` stores, per octahedral texel, the radial distance ``D`` to the first surface
along the texel-centre direction. A ray ``X + t·ω`` (``ω`` unit) is tested against it by
comparing the ray's radial distance ``ρ(t) = |X - P + t·ω|`` with ``D`` of the texel its
direction falls in:

- ``ρ < D - ε`` all through: the probe sees empty space there; march on.
- ``ρ`` reaches ``D`` (within ε) in a texel entered in front of the surface: ``HIT``.
- the ray enters a texel already behind its surface (``ρ > D + ε``): the probe cannot see that
  part of the ray, so it cannot tell what happens there: ``UNKNOWN``, with the ``t`` reached
  (the start of that texel, or of the last point known to be visible) so another probe can
  continue from it (Algorithm 5).
- the segment ends in front of everything: ``MISS`` — this probe proves there is no surface on
  ``[tmin, tmax)`` (up to its texel resolution and ε).

Three marchers share that test (``MARCH3D``, ``DDA``, ``HIERARCHICAL``):

1. ``MARCH3D`` — the thesis's baseline (§4.2, Algorithm 3): fixed world steps ``step``, one
   texel fetch per step, up to ``max_steps`` points (then ``UNKNOWN``). Once the ray is
   farther from the probe than every surface it stores and moving away, no point can meet one
   (``farthest_surface``): the rest of the ray can only stay in empty texels (a miss) or pass
   behind a surface (unknown), and the ``DDA`` walks it to say which. Without that bound an
   escaping ray marched its whole point budget and ended unknown, and the fallback answered
   it.
2. ``DDA`` — McGuire et al. 2017's 2D trace: the ray is split where it crosses the probe's
   three axis planes; each piece stays in one octant, where the octahedral map is a projective
   map of the direction, so the piece is a straight segment in texture space. Its texels are
   walked in order (exact grid traversal); each texel's ray-parameter range is recovered in
   closed form (``piece_t``), and ``ρ`` over it is bounded by its end values (``ρ`` is convex).
3. ``HIERARCHICAL`` — the same walk over the conservative min-distance mip chain, coarse to
   fine: a block whose minimum distance lies beyond the ray's largest ``ρ`` over the block
   (the larger end value, by convexity) is skipped whole; only blocks where a hit or a loss
   of visibility is possible are descended. It reports the same first event as ``DDA``.

Hit acceptance (``EPS_*``, thesis §7.1) and backface rejection (§7.2) are shared too; see
``texel_event``. Every function here is a scalar device function over flat arrays, so it also
compiles for CUDA.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from voxfield.kernels.octahedral import oct_decode, sign_not_zero, texel_of_direction

#: Result kinds (``FALLBACK`` is only produced by the multi-probe trace).
MISS = 0
HIT = 1
UNKNOWN = 2
FALLBACK = 3

#: Marchers.
MARCH3D = 0
DDA = 1
HIERARCHICAL = 2

#: Hit acceptance: constant ε (world units), the thesis's adaptive ε (§7.1), or the angular
#: criterion ``acos(α·ω) < kθ``.
EPS_CONSTANT = 0
EPS_ADAPTIVE = 1
EPS_ANGULAR = 2
#: Constant ε plus half the depth a texel's stored surface spans across the texel, from its
#: stored normal: a sloped wall is as thick as it is deep within one texel.
EPS_SLOPE = 3
#: The slope term's tangent limit (76°): at grazing angles a texel's depth span is unbounded.
SLOPE_TAN_MAX = 4.0
#: The thesis's adaptive ε in the form its text derives, ``(1 - α·ν)`` (the printed formula,
#: ``EPS_ADAPTIVE``, has ``(1 - β·ν)``, near zero on walls facing the camera).
EPS_ADAPTIVE_TEXT = 4
#: The default: the depth one texel spans where the ray crosses it, behind the surface. In
#: front the constant ε, at most ``params[P_FRONT]`` texel widths; behind it, that plus the
#: slope term of ``EPS_SLOPE`` plus half the radial range a ray covers while it crosses a
#: texel's cone, ``d · angle / 2 · cot φ`` (φ between the ray and the probe's direction,
#: capped): it grows as ray and probe align, as McGuire et al. 2017's minimum thickness does,
#: and stops rays slipping through surfaces.
EPS_FOOTPRINT = 5
#: The crossing term's cotangent limit (45°): larger caps let rays aligned with a probe take
#: surfaces behind the true one (measured on the Cornell box: 1 beats 2 and 4 at 27 and 64
#: probes, and ties at 8).
CROSSING_COT_MAX = 1.0

#: Below this |cos| between ray and stored normal a hit keeps the texel sphere's depth.
PLANE_MIN_COSINE = 0.1

#: Layout of the float64 ``params`` array every trace takes.
P_EPSILON = 0  # constant ε, world units
P_K = 1  # k of the adaptive ε and of the angular criterion
P_THETA = 2  # θ: the angle one camera pixel subtends (radians)
P_STEP = 3  # MARCH3D step, world units
P_MAX_STEPS = 4  # MARCH3D step limit
P_BACKFACE = 5  # 1.0: reject hits on surfaces facing away from the ray
P_CONSENSUS = 6  # 1.0: a hit another probe sees through is not taken (``probe_multi``)
P_BILINEAR = 7  # 1.0: a hit's radiance is read bilinearly (``probe_multi``), else nearest
P_COLOUR_PROBE = 8  # which probe answers a hit's colour (``probe_multi.COLOUR_*``)
P_FRONT = 9  # footprint ε in front of a surface: at most this many texel widths there
P_REFINE = 10  # a hit is re-traced against its colour probe within ± this many texel widths
P_RING = 11  # 1.0: when a cage loses the ray, the probes one step outside it try (``probe_multi``)
N_PARAMS = 12

#: ``march_3d``'s answer when the ray has gone past every stored surface, moving away.
_PAST_SURFACES = -1

#: Events of one texel (or one march step): nothing yet, a hit, a loss of visibility.
_GO = 0
_HIT = 1
_LOST = 2

#: A piece of a ray shorter than this in texels is one point of the map.
_DEGENERATE = 1e-9
_END = 1e-12


@njit(cache=True, nogil=True)
def radial(ax: float, ay: float, az: float, dx: float, dy: float, dz: float, t: float) -> float:
    """``|A + t·ω|``; inf for ``t = inf``."""
    if t == math.inf:
        return math.inf
    x = ax + t * dx
    y = ay + t * dy
    z = az + t * dz
    return math.sqrt(x * x + y * y + z * z)


@njit(cache=True, nogil=True)
def encode_in_octant(qx: float, qy: float, qz: float, sx: float, sy: float,
                     sz: float) -> tuple[float, float]:
    """Octahedral (u, v) of ``q`` computed as if it lay in the octant of signs ``s``.

    On a fold plane (a component 0) ``oct_encode`` must pick a side; a piece that ends on the
    plane needs the side it lies on, so the signs are given rather than read from ``q``."""
    l1 = sx * qx + sy * qy + sz * qz
    px = qx / l1
    pz = qz / l1
    if sy < 0.0:
        fx = (1.0 - sz * pz) * sx
        fz = (1.0 - sx * px) * sz
        px = fx
        pz = fz
    return px * 0.5 + 0.5, pz * 0.5 + 0.5


@njit(cache=True, nogil=True)
def texel_direction(row: int, col: int, resolution: int) -> tuple[float, float, float]:
    """Unit direction through texel (row, col)'s centre."""
    return oct_decode((col + 0.5) / resolution, (row + 0.5) / resolution)


@njit(cache=True, nogil=True)
def piece_setup(ax: float, ay: float, az: float, dx: float, dy: float, dz: float, t0: float,
                t1: float, resolution: int):
    """One octant piece ``[t0, t1]`` of the ray ``A + t·ω`` (``A = X - P``) in texel units.

    Returns ``(xa, ya, ex, ey, a0, b, scale)``: the segment starts at texel coordinates
    ``(xa, ya)`` (x = column, y = row) and moves by ``(ex, ey)`` over its length; ``a0``,
    ``b`` and ``scale`` parameterise ``piece_t``.

    In the octant of signs ``σ`` the map is affine in ``p = Q / (σ·Q)``, ``Q(t) = A + t·ω``;
    with ``τ = t - t0``, ``p(τ) - p(0) = τ / ((a0 + bτ) a0) · (a0 ω - b Q0)`` where
    ``a0 = σ·Q0 = |Q0|₁`` and ``b = σ·ω``: every point moves along one fixed vector, so the
    piece is straight, and its fraction λ of the way is ``μ(τ)/μ(τ1)``,
    ``μ(τ) = τ / ((a0 + bτ) a0)``."""
    qx = ax + t0 * dx
    qy = ay + t0 * dy
    qz = az + t0 * dz
    if t1 == math.inf:
        tm = t0 + 1.0 + abs(qx) + abs(qy) + abs(qz)
    else:
        tm = 0.5 * (t0 + t1)
    sx = sign_not_zero(ax + tm * dx)
    sy = sign_not_zero(ay + tm * dy)
    sz = sign_not_zero(az + tm * dz)
    a0 = sx * qx + sy * qy + sz * qz
    b = sx * dx + sy * dy + sz * dz
    if a0 > 0.0:
        u0, v0 = encode_in_octant(qx, qy, qz, sx, sy, sz)
    else:  # the piece starts at the probe centre: its first direction is ω
        u0, v0 = encode_in_octant(dx, dy, dz, sx, sy, sz)
    if t1 == math.inf:
        u1, v1 = encode_in_octant(dx, dy, dz, sx, sy, sz)
        scale = 1.0 / b
    else:
        rx = ax + t1 * dx
        ry = ay + t1 * dy
        rz = az + t1 * dz
        if sx * rx + sy * ry + sz * rz > 0.0:
            u1, v1 = encode_in_octant(rx, ry, rz, sx, sy, sz)
        else:  # the piece ends at the probe centre, arriving along -ω
            u1, v1 = encode_in_octant(-dx, -dy, -dz, sx, sy, sz)
        tau1 = t1 - t0
        # 0 where the ray runs through the probe centre: every point of the piece lies
        # along -ω, one texel, and ``walk_piece`` takes the degenerate segment without
        # ``piece_t``.
        end_l1 = a0 + tau1 * b
        scale = tau1 / end_l1 if end_l1 != 0.0 else math.inf
    xa = u0 * resolution
    ya = v0 * resolution
    return xa, ya, u1 * resolution - xa, v1 * resolution - ya, a0, b, scale


@njit(cache=True, nogil=True)
def piece_t(lam: float, t0: float, t1: float, a0: float, b: float, scale: float) -> float:
    """The ray parameter ``t`` at fraction ``lam`` of a piece's texture-space segment: the
    inverse of ``λ = μ(τ)/μ(τ1)`` (see ``piece_setup``), ``τ = κ a0 / (1 - κ b)`` with
    ``κ = λ τ1 / (a0 + b τ1)`` (``λ / b`` for an unbounded piece)."""
    if lam >= 1.0:
        return t1
    if lam <= 0.0:
        return t0
    k = lam * scale
    den = 1.0 - k * b
    if den <= 0.0:
        return t1
    return min(t0 + k * a0 / den, t1)


@njit(cache=True, nogil=True)
def _cell(pos: float, direction: float, lo: int, hi: int) -> int:
    """Texel index of a coordinate on a segment, taking the side the segment moves into
    when it sits on a boundary; clamped to ``lo..hi``."""
    if direction < 0.0:
        c = int(math.ceil(pos)) - 1
    else:
        c = int(math.floor(pos))
    return min(max(c, lo), hi)


@njit(cache=True, nogil=True)
def epsilon_at(eps_mode: int, params: np.ndarray, ox: float, oy: float, oz: float,
               px: float, py: float, pz: float, yx: float, yy: float, yz: float,
               nx: float, ny: float, nz: float) -> float:
    """The hit thickness ε for a candidate surface point ``Y`` with stored normal ``ν``.

    ``EPS_CONSTANT``: ``params[P_EPSILON]``. ``EPS_ADAPTIVE``: the thesis's §7.1 formula as it
    is printed, ``ε = k · tan θ · d(X, Y) · |α·β| · (1 - β·ν)``, with ``X`` the ray origin (the
    camera), ``α = S²(X - Y)``, ``β = S²(X - P)``, ``ν`` the stored unit normal at ``Y`` (zero
    where the probe stored none), ``θ = params[P_THETA]`` the angle of one camera pixel and
    ``k = params[P_K]``. (The thesis's derivation before it reads ``(1 - α·ν)``; the printed
    formula with ``β·ν`` is used.) When ``X = P``, ``β`` is taken as ``α``: that probe sees
    along the camera's own rays. Not used by ``EPS_ANGULAR`` (0 there)."""
    if eps_mode == EPS_CONSTANT or eps_mode == EPS_SLOPE or eps_mode == EPS_FOOTPRINT:
        return params[P_EPSILON]
    if eps_mode != EPS_ADAPTIVE and eps_mode != EPS_ADAPTIVE_TEXT:
        return 0.0
    axx = ox - yx
    axy = oy - yy
    axz = oz - yz
    dxy = math.sqrt(axx * axx + axy * axy + axz * axz)
    if dxy == 0.0:
        return 0.0
    axx /= dxy
    axy /= dxy
    axz /= dxy
    bx = ox - px
    by = oy - py
    bz = oz - pz
    dxp = math.sqrt(bx * bx + by * by + bz * bz)
    if dxp > 0.0:
        bx /= dxp
        by /= dxp
        bz /= dxp
    else:
        bx = axx
        by = axy
        bz = axz
    ab = abs(axx * bx + axy * by + axz * bz)
    if eps_mode == EPS_ADAPTIVE_TEXT:
        facing = axx * nx + axy * ny + axz * nz
    else:
        facing = bx * nx + by * ny + bz * nz
    return params[P_K] * math.tan(params[P_THETA]) * dxy * ab * (1.0 - facing)


@njit(cache=True, nogil=True)
def texel_angle(resolution: int) -> float:
    """The mean angle one texel of an R×R octahedral map subtends: sqrt(4π) / R."""
    return math.sqrt(4.0 * math.pi) / resolution


@njit(cache=True, nogil=True)
def slope_thickness(d: float, cx: float, cy: float, cz: float, nx: float, ny: float,
                    nz: float, resolution: int) -> float:
    """Half the range of depth a surface at distance ``d`` with normal ``ν`` covers across
    one texel seen along ``c``: ``d · angle / 2 · tan(ν, c)``, the tangent capped; texels
    without a stored normal get the cap."""
    cosine = abs(cx * nx + cy * ny + cz * nz)
    tangent = SLOPE_TAN_MAX
    if cosine > 0.0:
        tangent = min(math.sqrt(max(1.0 - cosine * cosine, 0.0)) / cosine, SLOPE_TAN_MAX)
    return 0.5 * d * texel_angle(resolution) * tangent


@njit(cache=True, nogil=True, inline="always")
def steepest_slope_thickness(d: float, resolution: int) -> float:
    """``slope_thickness`` at the capped tangent: no normal gives more, and as the two
    products round alike up to their last factor, none gives more in floating point either,
    so a test against this bound may skip reading the normal."""
    return 0.5 * d * texel_angle(resolution) * SLOPE_TAN_MAX


@njit(cache=True, nogil=True)
def crossing_thickness(d: float, cx: float, cy: float, cz: float, dx: float, dy: float,
                       dz: float, resolution: int) -> float:
    """Half the radial range a ray of direction ``ω`` covers while it crosses one texel's
    cone (direction ``c``) at distance ``d``: ``d · angle / 2 · cot φ``, ``cos φ = |ω·c|``,
    the cotangent capped at ``CROSSING_COT_MAX``."""
    cosine = min(abs(cx * dx + cy * dy + cz * dz), 1.0)
    sine = math.sqrt(max(1.0 - cosine * cosine, 0.0))
    cotangent = CROSSING_COT_MAX if sine * CROSSING_COT_MAX <= cosine else cosine / sine
    return 0.5 * d * texel_angle(resolution) * cotangent


@njit(cache=True, nogil=True)
def front_epsilon(params: np.ndarray, d: float, resolution: int) -> float:
    """The footprint ε in front of a surface at distance ``d``: the constant ε, at most
    ``params[P_FRONT]`` texel widths there."""
    capped = params[P_FRONT] * d * texel_angle(resolution)
    return capped if capped < params[P_EPSILON] else params[P_EPSILON]


@njit(cache=True, nogil=True)
def skip_bound(eps_mode: int, params: np.ndarray, dmin: float, dxp: float,
               resolution: int) -> float:
    """A lower bound of ``D - ε`` over every stored ``D >= dmin``: a block whose largest ray
    radial distance is below it holds no texel where a hit or a loss of visibility is
    possible. For the adaptive ε, ``ε <= c (|X - P| + D)`` with ``c = 2 k tan θ``; for the
    slope ε, ``ε <= ε0 + D · angle / 2 · tan_max``."""
    if eps_mode == EPS_CONSTANT:
        return dmin - params[P_EPSILON]
    if eps_mode == EPS_FOOTPRINT:
        # Its thickness lies behind the surface. In front, D - ε grows with D while the cap
        # grows slower than D (under one texel's width per unit distance).
        if params[P_FRONT] * texel_angle(resolution) < 1.0:
            return dmin - front_epsilon(params, dmin, resolution)
        return dmin - params[P_EPSILON]
    if eps_mode == EPS_SLOPE:
        c = 0.5 * texel_angle(resolution) * SLOPE_TAN_MAX
        if c >= 1.0:
            return -math.inf
        return dmin * (1.0 - c) - params[P_EPSILON]
    if eps_mode == EPS_ADAPTIVE or eps_mode == EPS_ADAPTIVE_TEXT:
        c = 2.0 * params[P_K] * math.tan(params[P_THETA])
        if c >= 1.0:
            return -math.inf
        return dmin * (1.0 - c) - c * dxp
    return dmin


@njit(cache=True, nogil=True)
def texel_event(eps_mode: int, params: np.ndarray, normals: np.ndarray, probe: int,
                resolution: int, row: int, col: int, d: float, rho_a: float, rho_b: float,
                ta: float, tb: float, t_floor: float, ox: float, oy: float, oz: float,
                dx: float, dy: float, dz: float, px: float, py: float,
                pz: float) -> tuple[int, float]:
    """What the ray does in texel (row, col) storing distance ``d``, over ``t`` in [ta, tb]
    with radial distances ``rho_a`` at ``ta`` and ``rho_b`` at ``tb``.

    Returns ``(_GO, tb)``, ``(_HIT, t)`` with ``t`` where ``ρ(t) = d`` (clamped to the texel's
    range: ``d`` is sampled at the texel centre), or ``(_LOST, t)`` with the ``t`` from which
    another probe should continue. Constant and adaptive ε: lost when the ray enters behind
    the surface by more than ε, a hit when its largest ``ρ`` comes within ε of ``d``.
    Angular (§7.1): a candidate is any texel where ``ρ`` reaches ``d``; it is a hit when the
    stored point ``Y`` is within ``kθ`` of the ray direction seen from ``X``, else lost.
    Backface rejection (§7.2): a hit whose stored normal faces along ω is lost instead, from
    ε before the texel (the true front face was within ε of where the probe saw empty space).
    Footprint ε: a ray that meets the plane of a front-facing stored surface more than ε
    after it leaves the texel's cone goes on (it passed in front of the surface)."""
    if not d < math.inf:
        return _GO, tb
    ax = ox - px
    ay = oy - py
    az = oz - pz
    cx, cy, cz = texel_direction(row, col, resolution)
    yx = px + d * cx
    yy = py + d * cy
    yz = pz + d * cz
    nx = np.float64(normals[probe, row, col, 0])
    ny = np.float64(normals[probe, row, col, 1])
    nz = np.float64(normals[probe, row, col, 2])
    rho_max = max(rho_a, rho_b)
    eps = epsilon_at(eps_mode, params, ox, oy, oz, px, py, pz, yx, yy, yz, nx, ny, nz)
    behind = eps  # how far behind the stored surface a ray may enter and still hit it
    if eps_mode == EPS_SLOPE:
        eps += slope_thickness(d, cx, cy, cz, nx, ny, nz, resolution)
        behind = eps
    elif eps_mode == EPS_FOOTPRINT:
        # Thick behind the surface, so a ray cannot slip through between two texels; thin
        # in front, so a hit is not taken before the ray reaches the surface.
        behind = eps + slope_thickness(d, cx, cy, cz, nx, ny, nz, resolution) + \
            crossing_thickness(d, cx, cy, cz, dx, dy, dz, resolution)
        # In front, at most a share of the texel's width: a ray passing beside a silhouette
        # within ε of the edge texel's surface takes it, so an ε wider than the texels
        # would widen every silhouette the map resolves more finely.
        eps = front_epsilon(params, d, resolution)
    if eps_mode == EPS_ANGULAR:
        if rho_max < d:
            return _GO, tb
    else:
        if rho_a > d + behind:
            return _LOST, ta
        if rho_max < d - eps:
            return _GO, tb
    # Where along [ta, tb] the ray meets the sphere of radius d (from inside).
    if rho_a >= d:
        t_hit = ta
    elif rho_b >= d:
        adot = ax * dx + ay * dy + az * dz
        disc = adot * adot - (ax * ax + ay * ay + az * az) + d * d
        t_hit = -adot + math.sqrt(max(disc, 0.0))
        t_hit = min(max(t_hit, ta), tb)
    else:
        t_hit = tb if rho_b >= rho_a else ta
    # The surface the texel stored is the plane through its point with its normal: where the
    # ray meets that plane is a better depth than the texel's sphere (kept when the ray runs
    # nearly along the plane, or the texel has no normal).
    facing = nx * dx + ny * dy + nz * dz
    if abs(facing) > PLANE_MIN_COSINE:
        t_plane = ((yx - ox) * nx + (yy - oy) * ny + (yz - oz) * nz) / facing
        if eps_mode == EPS_FOOTPRINT and facing < 0.0 and t_plane > tb + eps:
            # The ray leaves the texel's cone before it reaches the stored surface: it
            # passes in front of it (beside an edge, at a grazing angle). If the surface
            # goes on, the next texel along the ray meets it.
            return _GO, tb
        t_hit = min(max(t_plane, ta), tb)
    if eps_mode == EPS_ANGULAR:
        vx = yx - ox
        vy = yy - oy
        vz = yz - oz
        length = math.sqrt(vx * vx + vy * vy + vz * vz)
        if length > 0.0:
            cosine = (vx * dx + vy * dy + vz * dz) / length
            if math.acos(min(max(cosine, -1.0), 1.0)) >= params[P_K] * params[P_THETA]:
                return _LOST, ta
    if params[P_BACKFACE] != 0.0 and nx * dx + ny * dy + nz * dz > 0.0:
        return _LOST, max(t_floor, ta - eps)
    return _HIT, t_hit


@njit(cache=True, nogil=True)
def walk_piece(top: int, eps_mode: int, params: np.ndarray, mips: np.ndarray,
               mip_offsets: np.ndarray, mip_sizes: np.ndarray, normals: np.ndarray,
               resolution: int, probe: int, ox: float, oy: float, oz: float, dx: float,
               dy: float, dz: float, px: float, py: float, pz: float, t0: float, t1: float,
               t_floor: float):
    """Walk one octant piece's texels in order, from mip level ``top`` down (``top = 0``:
    the plain DDA). Returns ``(event, t, row, col, fetches, steps)``."""
    r = resolution
    ax = ox - px
    ay = oy - py
    az = oz - pz
    dxp = math.sqrt(ax * ax + ay * ay + az * az)
    xa, ya, ex, ey, a0, b, scale = piece_setup(ax, ay, az, dx, dy, dz, t0, t1, r)
    if abs(ex) + abs(ey) < _DEGENERATE:
        col = _cell(xa + 0.5 * ex, 0.0, 0, r - 1)
        row = _cell(ya + 0.5 * ey, 0.0, 0, r - 1)
        d = np.float64(mips[probe, row * r + col])
        event, t = texel_event(eps_mode, params, normals, probe, r, row, col, d,
                               radial(ax, ay, az, dx, dy, dz, t0),
                               radial(ax, ay, az, dx, dy, dz, t1), t0, t1, t_floor,
                               ox, oy, oz, dx, dy, dz, px, py, pz)
        return event, t, row, col, 1, 1
    ix = _cell(xa, ex, 0, r - 1)
    iy = _cell(ya, ey, 0, r - 1)
    # A segment ℓ texels long starts at the level whose blocks are about ℓ wide: coarser
    # blocks would cost fetches without covering more of it.
    span = max(abs(ex), abs(ey))
    level = 0
    while level < top and (1 << level) < span:
        level += 1
    ta = t0
    rho_a = radial(ax, ay, az, dx, dy, dz, t0)
    fetches = 0
    limit = 4 * (top + 1) * (2 * r + 4)
    while fetches < limit:
        n = mip_sizes[level]
        bx = ix >> level
        by = iy >> level
        x_lo = bx << level
        x_hi = min((bx + 1) << level, r)
        y_lo = by << level
        y_hi = min((by + 1) << level, r)
        if ex > 0.0:
            lx = (x_hi - xa) / ex
        elif ex < 0.0:
            lx = (x_lo - xa) / ex
        else:
            lx = math.inf
        if ey > 0.0:
            ly = (y_hi - ya) / ey
        elif ey < 0.0:
            ly = (y_lo - ya) / ey
        else:
            ly = math.inf
        lam_exit = min(lx, ly)
        end = lam_exit >= 1.0 - _END
        if end:
            lam_exit = 1.0
        tb = piece_t(lam_exit, t0, t1, a0, b, scale)
        rho_b = radial(ax, ay, az, dx, dy, dz, tb)
        value = np.float64(mips[probe, mip_offsets[level] + by * n + bx])
        fetches += 1
        if level > 0:
            if value < math.inf and not max(rho_a, rho_b) < skip_bound(eps_mode, params,
                                                                       value, dxp, r):
                level -= 1
                continue
        else:
            event, t = texel_event(eps_mode, params, normals, probe, r, iy, ix, value, rho_a,
                                   rho_b, ta, tb, t_floor, ox, oy, oz, dx, dy, dz, px, py, pz)
            if event != _GO:
                return event, t, iy, ix, fetches, fetches
        if end:
            break
        if lx <= ly:
            nx = x_hi if ex > 0.0 else x_lo - 1
        else:
            nx = _cell(xa + lam_exit * ex, ex, x_lo, x_hi - 1)
        if ly <= lx:
            ny = y_hi if ey > 0.0 else y_lo - 1
        else:
            ny = _cell(ya + lam_exit * ey, ey, y_lo, y_hi - 1)
        if nx < 0 or nx >= r or ny < 0 or ny >= r:
            break
        # Go up only into a parent block not yet tested: staying in the same parent means
        # we came down from it because it could not be skipped.
        up = level < top and ((nx >> (level + 1)) != (ix >> (level + 1))
                              or (ny >> (level + 1)) != (iy >> (level + 1)))
        ix = nx
        iy = ny
        ta = tb
        rho_a = rho_b
        if up:
            level += 1
    return _GO, t1, -1, -1, fetches, fetches


@njit(cache=True, nogil=True, inline="always")
def farthest_surface(mips: np.ndarray, probe: int) -> float:
    """The largest finite distance ``probe`` stores (0 where it stores none): the last
    column of ``PackedProbes.mips``."""
    return np.float64(mips[probe, mips.shape[1] - 1])


@njit(cache=True, nogil=True)
def march_3d(eps_mode: int, params: np.ndarray, mips: np.ndarray, normals: np.ndarray,
             resolution: int, probe: int, ox: float, oy: float, oz: float, dx: float,
             dy: float, dz: float, px: float, py: float, pz: float, tmin: float,
             tmax: float):
    """The thesis's 3D march (Algorithm 3): test points ``tmin + k·step`` against the texel
    of their direction from the probe. Returns ``(kind, t, row, col, fetches, steps)``;
    ``UNKNOWN`` carries the last point known visible, and also ends a march that used up
    ``max_steps`` before ``tmax``; ``_PAST_SURFACES`` the point from which the ray, moving
    away, is farther than every stored surface (``trace_probe`` walks the rest)."""
    r = resolution
    step = params[P_STEP]
    max_steps = int(params[P_MAX_STEPS])
    far = farthest_surface(mips, probe)
    ax = ox - px
    ay = oy - py
    az = oz - pz
    t = tmin
    t_prev = tmin
    steps = 0
    while t < tmax:
        qx = ax + t * dx
        qy = ay + t * dy
        qz = az + t * dz
        rho = math.sqrt(qx * qx + qy * qy + qz * qz)
        if rho > far and qx * dx + qy * dy + qz * dz >= 0.0:
            return _PAST_SURFACES, t, -1, -1, steps, steps
        if steps >= max_steps:
            return UNKNOWN, t_prev, -1, -1, steps, steps
        if rho == 0.0:
            qx = dx
            qy = dy
            qz = dz
        row, col = texel_of_direction(qx, qy, qz, r)
        d = np.float64(mips[probe, row * r + col])
        steps += 1
        event, t_event = texel_event(eps_mode, params, normals, probe, r, row, col, d, rho,
                                     rho, t, t, tmin, ox, oy, oz, dx, dy, dz, px, py, pz)
        if event == _HIT:
            return HIT, t_event, row, col, steps, steps
        if event == _LOST:
            return UNKNOWN, min(t_prev, t_event), row, col, steps, steps
        t_prev = t
        t = tmin + steps * step
    return MISS, tmax, -1, -1, steps, steps


@njit(cache=True, nogil=True)
def trace_probe(marcher: int, eps_mode: int, params: np.ndarray, positions: np.ndarray,
                mips: np.ndarray, mip_offsets: np.ndarray, mip_sizes: np.ndarray,
                normals: np.ndarray, resolution: int, probe: int, ox: float, oy: float,
                oz: float, dx: float, dy: float, dz: float, tmin: float, tmax: float):
    """Trace ``X + t·ω`` (``ω`` unit, ``t`` in [tmin, tmax)) against one probe.

    Returns ``(kind, t, row, col, fetches, steps)``: ``kind`` is ``HIT`` (``t`` the hit,
    (row, col) the texel whose radiance/normal/distance answer it), ``MISS`` (no surface on
    the segment; ``t = tmax``) or ``UNKNOWN`` (``t`` is how far the probe could vouch for the
    ray). ``fetches`` counts distance-texel reads (mip texels included), ``steps`` march
    iterations (cells visited at any level for the 2D marchers, points for ``MARCH3D``, plus
    the cells of the DDA that finishes its ray past the farthest surface)."""
    px = positions[probe, 0]
    py = positions[probe, 1]
    pz = positions[probe, 2]
    if not tmin < tmax:
        return MISS, tmax, -1, -1, 0, 0
    if marcher == MARCH3D:
        kind, t, row, col, points, _ = march_3d(eps_mode, params, mips, normals, resolution,
                                                probe, ox, oy, oz, dx, dy, dz, px, py, pz,
                                                tmin, tmax)
        if kind != _PAST_SURFACES:
            return kind, t, row, col, points, points
        kind, t, row, col, cells = walk_segment(0, eps_mode, params, mips, mip_offsets,
                                                mip_sizes, normals, resolution, probe, ox,
                                                oy, oz, dx, dy, dz, px, py, pz, t, tmax, tmin)
        return kind, t, row, col, points + cells, points + cells
    top = len(mip_sizes) - 1 if marcher == HIERARCHICAL else 0
    kind, t, row, col, fetches = walk_segment(top, eps_mode, params, mips, mip_offsets,
                                              mip_sizes, normals, resolution, probe, ox, oy,
                                              oz, dx, dy, dz, px, py, pz, tmin, tmax, tmin)
    return kind, t, row, col, fetches, fetches


@njit(cache=True, nogil=True)
def walk_segment(top: int, eps_mode: int, params: np.ndarray, mips: np.ndarray,
                 mip_offsets: np.ndarray, mip_sizes: np.ndarray, normals: np.ndarray,
                 resolution: int, probe: int, ox: float, oy: float, oz: float, dx: float,
                 dy: float, dz: float, px: float, py: float, pz: float, t_start: float,
                 tmax: float, t_floor: float):
    """The 2D walk (``top = 0``: ``DDA``; the mip chain's top: ``HIERARCHICAL``) of the ray
    over ``[t_start, tmax)``, one octant piece after another. Returns ``(kind, t, row, col,
    fetches)``; ``t_floor`` is the segment's own start, before which no loss is placed."""
    ax = ox - px
    ay = oy - py
    az = oz - pz
    # Where the ray crosses the probe's axis planes, in order: the octant pieces' ends.
    s0 = math.inf
    s1 = math.inf
    s2 = math.inf
    if dx != 0.0:
        s0 = -ax / dx
    if dy != 0.0:
        s1 = -ay / dy
    if dz != 0.0:
        s2 = -az / dz
    if s0 > s1:
        s0, s1 = s1, s0
    if s1 > s2:
        s1, s2 = s2, s1
    if s0 > s1:
        s0, s1 = s1, s0
    fetches = 0
    t0 = t_start
    for i in range(4):
        if i == 0:
            t1 = s0
        elif i == 1:
            t1 = s1
        elif i == 2:
            t1 = s2
        else:
            t1 = tmax
        t1 = min(t1, tmax)
        if t1 <= t0:
            continue
        event, t, row, col, f, _ = walk_piece(top, eps_mode, params, mips, mip_offsets,
                                              mip_sizes, normals, resolution, probe, ox, oy,
                                              oz, dx, dy, dz, px, py, pz, t0, t1, t_floor)
        fetches += f
        if event == _HIT:
            return HIT, t, row, col, fetches
        if event == _LOST:
            return UNKNOWN, t, row, col, fetches
        t0 = t1
    return MISS, tmax, -1, -1, fetches
