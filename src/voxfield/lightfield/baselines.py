"""The analytic probe lookups the light-field trace is measured against (probe thesis §5.1).

Both approximate the radiance along a ray (X, ω) by one lookup in a probe P's radiance map,
``L_o(X, ω) ≈ L_P(φ(P, X, ω))``, with no marching and no use of the probe's depth:

- **environment map** (Blinn and Newell 1976): ``φ = ω``. The probe is treated as seeing an
  infinitely distant scene, so the answer is the same from every X: exact only at X = P and
  wrong by the parallax of every finite surface elsewhere. Its distance is ``inf``.
- **parallax-corrected box proxy** (Bjorke 2004): the scene is assumed to be an axis-aligned
  box; the ray is intersected with that box at H and the probe is read in the direction
  ``H - P``. Exact wherever the geometry really is the box (a rectangular room whose walls are
  the proxy), wrong by the parallax of anything that is not. Its distance is ``|H - X|``.

Lookups are bilinear on the one-texel-bordered octahedral map (``kernels.octahedral``:
``add_border``, ``oct_bilinear``), the filtering an engine gets from a texture unit with the
border; ``filter="nearest"`` reads the one texel containing the direction instead (what a
point-sampled fetch returns, and bit-exact with the baked texels). Inputs need only
``positions`` (N, 3), ``radiance`` (N, R, R, 3) and optionally ``enabled`` (N,), so a
``ProbeSet`` works, as does anything shaped like one.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit, prange

from voxfield.errors import VoxfieldError
from voxfield.kernels.octahedral import add_border, oct_bilinear, oct_encode, texel_of_direction

FILTERS = ("bilinear", "nearest")
#: Texel reads per lookup for each filter (one RGB texel counts once): the cost counter.
FETCHES = {"bilinear": 4, "nearest": 1}


def nearest_probe(probe_set, points) -> np.ndarray:
    """(M,) index of the enabled probe nearest to each point (ties: the lower index).

    The baselines read one probe per ray; the natural choice is the one closest to where the
    ray starts, since that probe's view is the least parallax away from the ray's.
    """
    positions = np.asarray(probe_set.positions, np.float64).reshape(-1, 3)
    enabled = _enabled(probe_set, len(positions))
    candidates = np.flatnonzero(enabled)
    if not len(candidates):
        raise VoxfieldError("the probe set has no enabled probes to look up")
    p = _points(points, "points")
    best = np.zeros(len(p), np.int64)
    best_d2 = np.full(len(p), np.inf)
    for index in candidates:  # probe counts are small; memory stays O(M)
        d2 = ((p - positions[index]) ** 2).sum(axis=1)
        closer = d2 < best_d2
        best[closer] = index
        best_d2[closer] = d2[closer]
    return best


def environment_lookup(probe_set, probe, dirs, *, filter: str = "bilinear", maps=None):
    """Radiance of ``probe`` in each direction ω (φ = ω): ``(radiance (M, 3) float32,
    distance (M,) float32 all inf)``.

    ``probe`` is one index or (M,) indices (e.g. ``nearest_probe`` of the ray origins);
    ``dirs`` (M, 3) need not be unit length. The ray origin plays no part: that is the point
    of this baseline. ``maps``: the probes' ``LookupMaps``, when a caller reads them again.
    """
    d = _points(dirs, "directions")
    indices = _probe_indices(probe_set, probe, len(d))
    radiance = _lookup(probe_set, indices, d, filter, maps)
    return radiance, np.full(len(d), np.inf, np.float32)


def box_proxy_lookup(probe_set, probe, origins, dirs, box_lo, box_hi, *,
                     filter: str = "bilinear", return_normal: bool = False, maps=None):
    """Parallax-corrected lookup against the proxy box ``[box_lo, box_hi]`` (Bjorke 2004):
    ``(radiance (M, 3) float32, distance (M,) float32)`` and, with ``return_normal``, the
    proxy face's normal facing the ray (M, 3) float32 (zero where the box was missed).

    The proxy stands for the inside of a room, so the ray is read where it leaves the box:
    from inside that is the one wall ahead, from outside the far wall seen through the near
    one (the near face is culled as a back face, as the probe cannot see the walls' outsides).
    H = X + tω at that exit; the probe is read towards ``H - P``; the distance is t along
    the unit ray. A ray that misses the box, or whose exit lies behind it, gets the
    environment lookup (φ = ω) and distance ``inf``; so does a ray whose exit point is the
    probe centre itself, where ``H - P`` has no direction. ``maps`` as for
    ``environment_lookup``.
    """
    o = _points(origins, "origins")
    d = _points(dirs, "directions")
    if len(o) != len(d):
        raise VoxfieldError(f"{len(o)} origins for {len(d)} directions")
    lo, hi = check_box(box_lo, box_hi)
    indices = _probe_indices(probe_set, probe, len(d))
    positions = np.asarray(probe_set.positions, np.float64).reshape(-1, 3)

    unit = d / np.linalg.norm(d, axis=1, keepdims=True)
    t, axis = _box_exit(o, unit, lo, hi)
    hit = np.isfinite(t)
    lookup = unit.copy()
    towards = o[hit] + t[hit, None] * unit[hit] - positions[indices[hit]]
    length = np.linalg.norm(towards, axis=1)
    usable = length > 0.0
    rows = np.flatnonzero(hit)[usable]
    lookup[rows] = towards[usable] / length[usable, None]
    hit[np.flatnonzero(hit)[~usable]] = False

    radiance = _lookup(probe_set, indices, lookup, filter, maps)
    distance = np.where(hit, t, np.inf).astype(np.float32)
    if not return_normal:
        return radiance, distance
    normal = np.zeros((len(d), 3), np.float32)
    rows = np.flatnonzero(hit)
    # The exit face's outward normal has the ray's sign on its axis; the wall faces the ray.
    normal[rows, axis[rows]] = -np.sign(unit[rows, axis[rows]])
    return radiance, distance, normal


def _box_exit(o: np.ndarray, d: np.ndarray, lo: np.ndarray, hi: np.ndarray):
    """Slab test: distance t to where each unit ray leaves the box (inf: it misses the box or
    the box lies behind it) and the axis of the face it leaves through."""
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = 1.0 / d
        t0 = (lo - o) * inv
        t1 = (hi - o) * inv
    # A ray parallel to a slab is inside it for all t, or never.
    parallel = d == 0.0
    inside = (o >= lo) & (o <= hi)
    near = np.where(parallel, np.where(inside, -np.inf, np.inf), np.minimum(t0, t1))
    far = np.where(parallel, np.where(inside, np.inf, -np.inf), np.maximum(t0, t1))
    t_enter = near.max(axis=1)
    t_exit = far.min(axis=1)
    axis = far.argmin(axis=1)
    hit = (t_exit >= t_enter) & (t_exit > 0.0) & np.isfinite(t_exit)
    return np.where(hit, t_exit, np.inf), axis


@dataclass(frozen=True)
class LookupMaps:
    """Some probes' radiance maps as the lookups read them: float32 and, for the bilinear
    filter, channels first with a one-texel border. Converting a map touches every texel,
    more than a whole image reads (a 1024² map holds 16 times a 256² view's pixels), so a
    render converts the probes it reads once, not once per band of rows."""

    probes: np.ndarray  #: (K,) sorted indices of the probes held
    maps: np.ndarray  #: (K, R, R, 3), or (K, 3, R + 2, R + 2) bordered
    filter: str

    def local(self, indices: np.ndarray) -> np.ndarray:
        """Positions in ``maps`` of the probes ``indices``, or a VoxfieldError for one not
        held."""
        where = np.searchsorted(self.probes, indices)
        held = where < len(self.probes)
        held[held] = self.probes[where[held]] == indices[held]
        if not held.all():
            raise VoxfieldError(f"probe {int(indices[~held][0])} is not among the lookup "
                                "maps' probes; make them with every probe the rays read")
        return np.ascontiguousarray(where, np.int64)


def lookup_maps(probe_set, probes, filter: str = "bilinear") -> LookupMaps:
    """``LookupMaps`` of ``probes`` (indices into the set) for ``filter``."""
    if filter not in FILTERS:
        raise VoxfieldError(f"unknown lookup filter {filter!r}; choose one of "
                            f"{', '.join(FILTERS)}")
    radiance = np.asarray(probe_set.radiance)
    if radiance.ndim != 4 or radiance.shape[1] != radiance.shape[2] or radiance.shape[3] != 3:
        raise VoxfieldError(f"probe radiance must be (N, R, R, 3), got {radiance.shape}")
    used = np.unique(np.asarray(probes, np.int64).reshape(-1))
    # Only the probes in use are converted and bordered: a grid may hold thousands.
    maps = radiance[used].astype(np.float32)
    if filter == "bilinear":
        maps = add_border(np.moveaxis(maps, 3, 1))
    return LookupMaps(used, np.ascontiguousarray(maps), filter)


def _lookup(probe_set, indices: np.ndarray, directions: np.ndarray, filter: str,
            maps: LookupMaps | None = None) -> np.ndarray:
    """Radiance of probe ``indices[i]`` in ``directions[i]``, (M, 3) float32."""
    if maps is None:
        maps = lookup_maps(probe_set, indices, filter)
    elif not isinstance(maps, LookupMaps) or maps.filter != filter:
        raise VoxfieldError(f"the lookup maps must be LookupMaps made for the {filter} "
                            "filter (lookup_maps)")
    out = np.empty((len(directions), 3), np.float32)
    if not len(directions):
        return out
    d = np.ascontiguousarray(directions, np.float64)
    local = maps.local(np.asarray(indices, np.int64).reshape(-1))
    if filter == "nearest":
        _nearest_rows(maps.maps, local, d, out)
    else:
        _bilinear_rows(maps.maps, local, d, out)
    return out


@njit(cache=True, nogil=True, parallel=True)
def _bilinear_rows(bordered: np.ndarray, probe: np.ndarray, dirs: np.ndarray,
                   out: np.ndarray) -> None:
    """``out[i]`` = bordered map ``probe[i]`` (channels first) read bilinearly at ``dirs[i]``."""
    for i in prange(dirs.shape[0]):
        x, y, z = dirs[i, 0], dirs[i, 1], dirs[i, 2]
        if abs(x) + abs(y) + abs(z) == 0.0:
            x = 1.0  # a zero vector has no direction; never produced by the callers
        u, v = oct_encode(x, y, z)
        for c in range(3):
            out[i, c] = oct_bilinear(bordered[probe[i], c], u, v)


@njit(cache=True, nogil=True, parallel=True)
def _nearest_rows(maps: np.ndarray, probe: np.ndarray, dirs: np.ndarray,
                  out: np.ndarray) -> None:
    """``out[i]`` = the texel of map ``probe[i]`` containing ``dirs[i]``."""
    r = maps.shape[1]
    for i in prange(dirs.shape[0]):
        x, y, z = dirs[i, 0], dirs[i, 1], dirs[i, 2]
        if abs(x) + abs(y) + abs(z) == 0.0:
            x = 1.0
        row, col = texel_of_direction(x, y, z, r)
        for c in range(3):
            out[i, c] = maps[probe[i], row, col, c]


def _enabled(probe_set, n: int) -> np.ndarray:
    enabled = getattr(probe_set, "enabled", None)
    return np.ones(n, bool) if enabled is None else np.asarray(enabled, bool).reshape(-1)


def _points(values, what: str) -> np.ndarray:
    a = np.asarray(values, np.float64)
    if a.ndim != 2 or a.shape[1] != 3:
        raise VoxfieldError(f"{what} must be an M×3 array, got shape {a.shape}")
    if not np.isfinite(a).all():
        raise VoxfieldError(f"{what} hold NaN or infinity")
    if what == "directions" and len(a) and not np.abs(a).sum(axis=1).all():
        raise VoxfieldError("a ray direction is the zero vector")
    return a


def _probe_indices(probe_set, probe, m: int) -> np.ndarray:
    """``probe`` (one index or M indices) checked against the set: in range and enabled."""
    n = len(np.asarray(probe_set.positions).reshape(-1, 3))
    p = np.asarray(probe)
    if p.size and not np.issubdtype(p.dtype, np.integer):
        raise VoxfieldError(f"probe indices must be integers, got {p.dtype}")
    p = np.broadcast_to(p.astype(np.int64), (m,)) if p.ndim == 0 else p.astype(np.int64)
    if p.shape != (m,):
        raise VoxfieldError(f"{p.shape[0]} probe indices for {m} rays")
    if m and (p.min() < 0 or p.max() >= n):
        raise VoxfieldError(f"probe index outside 0..{n - 1}")
    disabled = ~_enabled(probe_set, n)[p]
    if disabled.any():
        raise VoxfieldError(f"probe {int(p[disabled][0])} is disabled (it was not baked); "
                            "look up an enabled probe")
    return p


def check_box(box_lo, box_hi) -> tuple[np.ndarray, np.ndarray]:
    """The proxy box's corners as float64 (3,) arrays, or a VoxfieldError."""
    lo = np.asarray(box_lo, np.float64).reshape(-1)
    hi = np.asarray(box_hi, np.float64).reshape(-1)
    if lo.shape != (3,) or hi.shape != (3,):
        raise VoxfieldError("the proxy box corners must be three numbers each")
    if not (np.isfinite(lo).all() and np.isfinite(hi).all()) or np.any(hi <= lo):
        raise VoxfieldError(f"the proxy box {lo.tolist()} .. {hi.tolist()} is empty or not "
                            "finite; give a minimum corner below the maximum on every axis")
    return lo, hi
