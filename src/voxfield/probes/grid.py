"""Probe placement: a regular, possibly anisotropic lattice of probes (probe thesis §4.4),
per-probe offsets, and DDGI-style relocation of probes that sit in or against geometry.

Probe order is x fastest, then y, then z: probe ``(i, j, k)`` has index
``i + nx * (j + ny * k)``. Every per-probe array (offsets, enabled, baked maps) uses this order.
Positions are in octree space (finest-voxel units, the octree's min corner at the origin).
"""

from __future__ import annotations

import math
import re
import warnings
from dataclasses import dataclass, replace

import numpy as np

from voxfield.checks import is_integer, seed_value
from voxfield.errors import VoxfieldError
from voxfield.render.ray_query import trace
from voxfield.svo.octree import Octree, check_octree

#: A probe may move at most this fraction of a cell from its lattice point on each axis: then
#: probes never pass each other, so a point's cell of eight probes stays well defined.
MAX_OFFSET_FRACTION = 0.5
#: Default relocation clearance, as a fraction of the smallest spacing.
DEFAULT_CLEARANCE_FRACTION = 0.2
#: Refuse grids larger than this: every probe gets several maps, so more is surely a typo.
MAX_PROBES = 1 << 24
#: A spacing must be at least this fraction of the grid's largest coordinate on its axis:
#: probes closer than that, relative to their distance from the world's origin, are a few
#: float64 steps apart (1e-310 apart, or 16 apart at 1e300), and the cage and march
#: arithmetic that divides by the spacing or subtracts positions answers from rounding alone.
MIN_RELATIVE_SPACING = 1e-9
#: Probe positions lie within this many voxels of the world's origin (2^50): float64 still
#: resolves an eighth of a voxel there, and the box around the grid, its cameras and the
#: differences between positions stay finite.
MAX_COORDINATE = 2.0**50
#: Extra distance (in voxels) added to every move so a probe never ends exactly on a face.
_NUDGE = 1e-4
#: Bits per axis of a voxel key (scenes span at most 2**21 voxels per axis).
_KEY_BITS = 21


def counts_text(counts) -> str:
    """Probe counts as a grid is written (``0x2x2``), not as the floats they were read as."""
    return "x".join(f"{float(c):g}" for c in counts)


def _whole_counts(counts) -> np.ndarray:
    """Probe counts per axis as floats, refused unless whole numbers >= 1."""
    values = _vector(counts, "counts")
    if np.any(values != np.round(values)) or np.any(values < 1):
        raise VoxfieldError(f"probe counts must be whole numbers >= 1, got {counts_text(values)}")
    return values


def _vector(value, name: str, dtype=np.float64) -> np.ndarray:
    try:
        v = np.array(value, dtype=dtype).reshape(-1)
    except (TypeError, ValueError) as exc:
        raise VoxfieldError(f"probe grid {name} must be three numbers, got {value!r}") from exc
    if v.shape != (3,):
        raise VoxfieldError(f"probe grid {name} must be three numbers, got {value!r}")
    if not np.isfinite(v).all():
        raise VoxfieldError(f"probe grid {name} holds NaN or infinity: {v.tolist()}")
    return v


def _frozen(array: np.ndarray) -> np.ndarray:
    array.flags.writeable = False
    return array


@dataclass(frozen=True, eq=False)
class ProbeGrid:
    """Probes at ``origin + (i, j, k) * spacing + offsets[index]`` (index order: see module).

    ``enabled[index]`` is False for probes left out of bakes and lookups (e.g. stuck in a
    wall). Arrays are copied and made read-only, so a grid never changes after construction.
    """

    origin: np.ndarray
    spacing: np.ndarray
    counts: np.ndarray
    offsets: np.ndarray | None = None
    enabled: np.ndarray | None = None

    def __repr__(self) -> str:  # the default printed every offset in full
        counts = "x".join(str(int(c)) for c in self.counts)
        enabled = "" if self.enabled is None else f", {int(np.count_nonzero(self.enabled))} enabled"
        return (f"ProbeGrid({counts} at {np.round(self.origin, 3).tolist()} spacing "
                f"{np.round(self.spacing, 3).tolist()}{enabled})")

    def __post_init__(self) -> None:
        origin = _vector(self.origin, "origin")
        spacing = _vector(self.spacing, "spacing")
        if np.any(spacing <= 0):
            raise VoxfieldError(f"probe spacing must be positive on every axis, got {spacing}")
        counts = _whole_counts(self.counts).astype(np.int64)
        n = math.prod(int(c) for c in counts)
        if n > MAX_PROBES:
            raise VoxfieldError(f"{n:,} probes ({counts.tolist()}) is more than the "
                                f"{MAX_PROBES:,} allowed; use fewer probes per axis")
        offsets = np.zeros((n, 3)) if self.offsets is None else np.array(self.offsets, np.float64)
        if offsets.shape != (n, 3):
            raise VoxfieldError(f"probe offsets must be {n}×3 (one per probe), got {offsets.shape}")
        if not np.isfinite(offsets).all():
            raise VoxfieldError("probe offsets hold NaN or infinity")
        _check_offset_size(offsets, spacing)
        _check_extent(origin, spacing, counts, offsets)
        enabled = np.ones(n, bool) if self.enabled is None else np.array(self.enabled)
        if enabled.shape != (n,) or enabled.dtype != bool:
            raise VoxfieldError(f"probe enabled flags must be {n} booleans, got "
                                f"{enabled.dtype} of shape {enabled.shape}")
        for name, value in [("origin", origin), ("spacing", spacing), ("counts", counts),
                            ("offsets", offsets), ("enabled", enabled)]:
            object.__setattr__(self, name, _frozen(value))

    # --- construction -------------------------------------------------------------------

    @classmethod
    def fit(cls, lo, hi, counts, margin: float = 0.5) -> ProbeGrid:
        """A grid filling the box ``[lo, hi]`` with ``counts`` probes per axis.

        The first and last probes sit ``margin`` spacings inside the box faces: 0.5 puts
        the probes at the centres of ``counts`` equal cells, 0 on the faces themselves. An
        axis with a single probe gets it at the box centre.
        """
        lo = _vector(lo, "box minimum")
        hi = _vector(hi, "box maximum")
        if np.any(hi <= lo):
            raise VoxfieldError(f"the box to fit probes into is empty: {lo.tolist()} .. "
                                f"{hi.tolist()}")
        if not (math.isfinite(margin) and margin >= 0):
            raise VoxfieldError(f"the grid margin must be >= 0 spacings, got {margin}")
        n = _whole_counts(counts)
        cells = n - 1 + 2 * margin
        single = cells <= 0  # one probe and no margin: centre it
        spacing = (hi - lo) / np.where(single, 1.0, cells)
        origin = np.where(single, (lo + hi) / 2, lo + margin * spacing)
        return cls(origin, spacing, n)

    def with_offsets(self, offsets) -> ProbeGrid:
        """The same grid with hand-set offsets (N×3, at most half a cell per axis)."""
        return replace(self, offsets=offsets)

    def with_enabled(self, enabled) -> ProbeGrid:
        """The same grid with hand-set enabled flags (N booleans)."""
        return replace(self, enabled=enabled)

    # --- geometry -----------------------------------------------------------------------

    @property
    def count(self) -> int:
        return int(np.prod(self.counts))

    def __len__(self) -> int:
        return self.count

    @property
    def lattice_coords(self) -> np.ndarray:
        """(N, 3) int64 ``(i, j, k)`` of every probe, in probe order."""
        nx, ny, nz = (int(c) for c in self.counts)
        k, j, i = np.meshgrid(np.arange(nz), np.arange(ny), np.arange(nx), indexing="ij")
        return np.stack([i.ravel(), j.ravel(), k.ravel()], axis=1)

    @property
    def base_positions(self) -> np.ndarray:
        """(N, 3) lattice points, before offsets."""
        return self.origin + self.lattice_coords * self.spacing

    @property
    def positions(self) -> np.ndarray:
        """(N, 3) probe positions: lattice points plus offsets."""
        return self.base_positions + self.offsets

    def probe_index(self, i, j, k):
        """Index of probe ``(i, j, k)`` (scalars or arrays); out-of-range is an error."""
        ijk = [np.asarray(v) for v in (i, j, k)]
        for axis, (v, n) in enumerate(zip(ijk, self.counts, strict=True)):
            if not np.issubdtype(v.dtype, np.integer):
                raise VoxfieldError(f"probe lattice coordinates must be integers, got {v.dtype}")
            if v.size and (v.min() < 0 or v.max() >= n):
                raise VoxfieldError(f"probe coordinate on axis {'xyz'[axis]} out of range "
                                    f"0..{int(n) - 1}: {v.tolist()}")
        index = ijk[0] + self.counts[0] * (ijk[1] + self.counts[1] * ijk[2])
        return int(index) if index.ndim == 0 else index.astype(np.int64)

    def cell_of(self, points) -> np.ndarray:
        """(M, 3) lattice coordinates of the lower corner probe of each point's cell.

        The cell is that of the lattice points (offsets do not move cells), clamped so that
        its far corner is a probe too: points outside the grid get the nearest border cell.
        An axis with a single probe has cell 0.
        """
        p = np.asarray(points, np.float64)
        if p.ndim != 2 or p.shape[1] != 3:
            raise VoxfieldError(f"points must be an M×3 array, got shape {p.shape}")
        if not np.isfinite(p).all():
            raise VoxfieldError("points hold NaN or infinity")
        cell = np.floor((p - self.origin) / self.spacing)
        top = np.maximum(self.counts - 2, 0)
        return np.clip(cell, 0, top).astype(np.int64)

    # --- serialisation ------------------------------------------------------------------

    def to_dict(self) -> dict:
        """Plain lists and numbers for a JSON header; ``from_dict`` restores it exactly
        (Python's JSON writes floats with enough digits to read back bit for bit)."""
        return {
            "origin": self.origin.tolist(),
            "spacing": self.spacing.tolist(),
            "counts": self.counts.tolist(),
            "offsets": self.offsets.tolist(),
            "enabled": self.enabled.tolist(),
        }

    @classmethod
    def from_dict(cls, data: dict) -> ProbeGrid:
        if not isinstance(data, dict):
            raise VoxfieldError(f"a probe grid description must be a mapping, got {type(data)}")
        missing = [k for k in ("origin", "spacing", "counts") if k not in data]
        if missing:
            raise VoxfieldError(f"the probe grid description lacks {', '.join(missing)}")
        offsets = data.get("offsets")
        enabled = data.get("enabled")
        if enabled is not None and not (
            isinstance(enabled, list) and all(isinstance(e, bool) for e in enabled)
        ):
            raise VoxfieldError("probe enabled flags must be a list of true or false")
        try:
            offsets = None if offsets is None else np.array(offsets, np.float64)
        except (TypeError, ValueError) as exc:
            raise VoxfieldError(f"probe offsets must be N×3 numbers ({exc})") from None
        return cls(data["origin"], data["spacing"], data["counts"], offsets,
                   None if enabled is None else np.array(enabled, bool))

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, ProbeGrid):
            return NotImplemented
        return all(np.array_equal(getattr(self, f), getattr(other, f))
                   for f in ("origin", "spacing", "counts", "offsets", "enabled"))

    __hash__ = None  # arrays inside: equal grids need not hash alike

    def describe(self) -> str:
        nx, ny, nz = self.counts.tolist()
        return (f"{nx}×{ny}×{nz} probes ({self.count}, {int(self.enabled.sum())} enabled), "
                f"origin {np.round(self.origin, 3).tolist()}, "
                f"spacing {np.round(self.spacing, 3).tolist()}")


def _check_offset_size(offsets: np.ndarray, spacing: np.ndarray) -> None:
    # A hair of tolerance: offsets clamped to exactly half a cell must pass.
    limit = MAX_OFFSET_FRACTION * spacing * (1 + 1e-12)
    too_far = np.abs(offsets) > limit
    if too_far.any():
        index = int(np.argwhere(too_far.any(axis=1))[0, 0])
        raise VoxfieldError(
            f"probe {index}'s offset {offsets[index].tolist()} is more than "
            f"{MAX_OFFSET_FRACTION} of a cell ({(MAX_OFFSET_FRACTION * spacing).tolist()}) on "
            f"some axis; move it less or use a denser grid"
        )


def _check_extent(origin: np.ndarray, spacing: np.ndarray, counts: np.ndarray,
                  offsets: np.ndarray) -> None:
    """Every probe position lies within ``MAX_COORDINATE``, and along every axis with more
    than one probe the spacing is not lost in rounding next to the coordinates
    (``MIN_RELATIVE_SPACING``)."""
    with np.errstate(over="ignore", invalid="ignore"):
        far = origin + (counts - 1) * spacing
        reach = np.maximum(np.abs(origin), np.abs(far)) + np.abs(offsets).max(axis=0)
    if not np.all(reach <= MAX_COORDINATE):  # also an overflow to infinity
        raise VoxfieldError(
            f"probe grid positions reach {reach.max():.6g} voxels from the origin (origin "
            f"{origin.tolist()}, spacing {spacing.tolist()}, counts {counts.tolist()}); they "
            f"must lie within {MAX_COORDINATE:.6g}")
    crowded = (spacing < MIN_RELATIVE_SPACING * reach) & (counts > 1)
    if crowded.any():
        axis = int(np.argmax(crowded))
        raise VoxfieldError(
            f"probe spacing {spacing[axis]:g} on axis {'xyz'[axis]} is too small for positions "
            f"reaching {reach[axis]:.6g} there: probes must be at least "
            f"{MIN_RELATIVE_SPACING:g} of that apart")


_DIMS = re.compile(r"^\s*(\d+)\s*[x×]\s*(\d+)\s*[x×]\s*(\d+)\s*$", re.IGNORECASE)
_SURFACE = re.compile(r"^\s*surface\s*:\s*(\d+)\s*[x×]\s*(\d+)\s*@\s*([0-9.eE+-]+)\s*$",
                      re.IGNORECASE)
_GRID_HELP = ('give "NXxNYxNZ" (e.g. 8x4x8, fitted to the scene), "surface:NXxNZ@H" (one '
              'layer H voxels above a terrain\'s surface) or '
              '"origin=x,y,z;spacing=sx,sy,sz;counts=nx,ny,nz"')


def surface_layer(octree, counts_xz, height: float) -> ProbeGrid:
    """One layer of ``NX × NZ`` probes, each ``height`` voxels above the surface below it
    (found by a ray cast straight down): for terrains, whose relief a flat layer would cut
    through or float far above. The lattice is one probe high; each probe's vertical offset
    follows the ground, so the cell spans the whole relief."""
    if not (math.isfinite(height) and 0 < height <= MAX_COORDINATE):
        raise VoxfieldError(f"the layer height must be a distance above 0 and within "
                            f"{MAX_COORDINATE:.6g} voxels, got {height}")
    lo, hi = (np.asarray(b, np.float64) for b in octree.voxel_bounds)
    nx, nz = (int(c) for c in counts_xz)
    flat = ProbeGrid.fit(lo, hi, (nx, 1, nz))
    xz = flat.base_positions[:, [0, 2]]
    origins = np.column_stack([xz[:, 0], np.full(len(xz), hi[1] + 1.0), xz[:, 1]])
    down = np.tile([0.0, -1.0, 0.0], (len(xz), 1))
    hits = trace(octree, origins, down, lod=0)
    ground = np.where(hits.hit, origins[:, 1] - hits.t, lo[1])
    target = ground + height
    if np.all(ground > hi[1] - 0.5):  # every ray stopped on the box's top: a roof, a lid
        warnings.warn(f"every probe of the {nx}x{nz} surface layer lies above the scene's "
                      "box, over its top; probes inside a room or an object need a grid "
                      "NXxNYxNZ", stacklevel=2)
    centre = 0.5 * (target.min() + target.max())
    spacing = flat.spacing.copy()
    spacing[1] = max(2.0 * float(np.abs(target - centre).max()) + 1.0, 1.0)
    origin = flat.origin.copy()
    origin[1] = centre
    offsets = np.zeros((len(xz), 3))
    offsets[:, 1] = target - centre
    return ProbeGrid(origin, spacing, (nx, 1, nz), offsets)


def surface_spec(text: str) -> tuple[tuple[int, int], float] | None:
    """``"surface:8x8@12"`` → ``((8, 8), 12.0)``, the arguments of ``surface_layer``; None
    for any text of another form. A surface form with bad values raises."""
    surface = _SURFACE.match(text)
    if not surface:
        return None
    try:
        height = float(surface.group(3))
    except ValueError:
        raise VoxfieldError(f"the layer height in {text!r} must be a number") from None
    if not (math.isfinite(height) and 0 < height <= MAX_COORDINATE):
        raise VoxfieldError(f"the layer height must be a distance above 0 and within "
                            f"{MAX_COORDINATE:.6g} voxels, got {text!r}")
    counts = (int(surface.group(1)), int(surface.group(2)))
    if min(counts) < 1:
        raise VoxfieldError(f"probe counts must be 1 or more, got {text!r}")
    return counts, height


def parse_grid(text: str, bounds=None, octree=None) -> ProbeGrid:
    """The CLI's ``--grid``: ``"8x4x8"`` fits that many probes to ``bounds`` (lo, hi), e.g. an
    octree's ``voxel_bounds``; ``"surface:8x8@12"`` lays one layer 12 voxels above the
    ``octree``'s surface (``surface_layer``); ``"origin=x,y,z;spacing=s or sx,sy,sz;
    counts=nx,ny,nz"`` gives the lattice explicitly (keys in any order)."""
    if not isinstance(text, str) or not text.strip():
        raise VoxfieldError(f"empty probe grid; {_GRID_HELP}")
    surface = surface_spec(text)
    if surface is not None:
        if octree is None:
            raise VoxfieldError(f"grid {text!r} follows a scene's surface; there is no scene")
        return surface_layer(octree, *surface)
    dims = _DIMS.match(text)
    if dims:
        if bounds is None:
            raise VoxfieldError(f"grid {text!r} gives only counts, and there is no scene box "
                                "to fit it to; give origin, spacing and counts instead")
        counts = [int(g) for g in dims.groups()]
        return ProbeGrid.fit(bounds[0], bounds[1], counts)
    fields: dict[str, list[float]] = {}
    for part in filter(None, (p.strip() for p in text.split(";"))):
        key, eq, value = part.partition("=")
        key = key.strip().lower()
        if not eq or key not in ("origin", "spacing", "counts"):
            raise VoxfieldError(f"cannot read {part!r} in grid {text!r}; {_GRID_HELP}")
        if key in fields:
            raise VoxfieldError(f"grid {text!r} gives {key} twice")
        try:
            fields[key] = [float(v) for v in value.split(",")]
        except ValueError:
            raise VoxfieldError(f"{key} in grid {text!r} must be numbers; {_GRID_HELP}") from None
    missing = [k for k in ("origin", "spacing", "counts") if k not in fields]
    if missing:
        raise VoxfieldError(f"grid {text!r} lacks {', '.join(missing)}; {_GRID_HELP}")
    spacing = fields["spacing"]
    if len(spacing) == 1:
        spacing = spacing * 3
    return ProbeGrid(fields["origin"], spacing, fields["counts"])


# --- relocation -----------------------------------------------------------------------------

#: Per-probe outcome of ``relocate``.
CLEAR = "clear"  # already far enough from geometry: untouched
ESCAPED = "escaped"  # was inside a solid voxel, moved out to free space
PUSHED = "pushed"  # was closer than the clearance to a surface, moved away from it
INSIDE = "disabled: inside geometry"  # no way out within the allowed shift
TOO_CLOSE = "disabled: too close to geometry"  # out of solids, but the clearance is unreachable
SKIPPED = "disabled before relocation"


@dataclass(frozen=True, eq=False)
class RelocationReport:
    """What ``relocate`` did: per-probe offsets and reasons, and the moved / disabled
    probe indices. Disabled probes keep the offsets they had before relocation."""

    offsets: np.ndarray  # (N, 3)
    reasons: tuple[str, ...]  # (N,), one of the reason constants above
    moved: np.ndarray  # indices of probes that were moved and stay enabled
    disabled: np.ndarray  # indices of probes disabled by relocation
    clearance: float
    max_shift: float

    def summary(self) -> str:
        counts = {r: self.reasons.count(r) for r in dict.fromkeys(self.reasons)}
        parts = ", ".join(f"{n} {r}" for r, n in counts.items())
        return (f"relocated probes (clearance {self.clearance:g} voxels, at most "
                f"{self.max_shift:g} of a cell): {parts}")

    def to_dict(self) -> dict:
        return {"offsets": self.offsets.tolist(), "reasons": list(self.reasons),
                "moved": self.moved.tolist(), "disabled": self.disabled.tolist(),
                "clearance": self.clearance, "max_shift": self.max_shift}


class _VoxelOccupancy:
    """Which finest voxels are solid: sorted packed keys and a binary search per query."""

    def __init__(self, octree: Octree) -> None:
        voxels = octree.node_coords(octree.depth)
        self.size = octree.size
        self.keys = np.sort(self._key(voxels))

    @staticmethod
    def _key(voxels: np.ndarray) -> np.ndarray:
        return voxels[..., 0] | (voxels[..., 1] << _KEY_BITS) | (voxels[..., 2] << 2 * _KEY_BITS)

    def solid(self, voxels: np.ndarray) -> np.ndarray:
        """Boolean per integer voxel coordinate (..., 3); outside the root cube is empty."""
        voxels = np.asarray(voxels, np.int64)
        inside_root = np.all((voxels >= 0) & (voxels < self.size), axis=-1)
        keys = self._key(np.where(inside_root[..., None], voxels, 0))
        slot = np.minimum(np.searchsorted(self.keys, keys), len(self.keys) - 1)
        return inside_root & (self.keys[slot] == keys)

    def contains(self, points: np.ndarray) -> np.ndarray:
        """Whether each point lies in a solid voxel (faces belong to the voxel above them)."""
        return self.solid(np.floor(points).astype(np.int64))


def voxel_occupancy(octree: Octree) -> _VoxelOccupancy:
    """The octree's ``_VoxelOccupancy``, sorted once and kept with it: relocation and the
    placement check before a bake both ask (a sort of every voxel, seconds on a 2048²
    terrain)."""
    return octree.derived(("voxel_occupancy",), lambda: _VoxelOccupancy(octree))


def probes_inside(grid: ProbeGrid, octree: Octree) -> np.ndarray:
    """Which enabled probes stand in a solid voxel: every ray they cast starts in geometry,
    so their distance maps are zero and their radiance one voxel's colour."""
    inside = np.zeros(grid.count, bool)
    enabled = np.flatnonzero(grid.enabled)
    inside[enabled] = voxel_occupancy(octree).contains(grid.positions[enabled])
    return inside


def placement_problem(grid: ProbeGrid, octree: Octree, *, relocated: bool = False,
                      relocate_with: str = "--relocate") -> tuple[str | None, bool]:
    """What is wrong with where ``grid`` puts its probes in ``octree``, and whether it
    leaves nothing worth baking; (None, False) for a usable grid. The hint offers
    relocation (asked for by ``relocate_with``) unless the grid had it."""
    hint = ("; " + ("" if relocated else f"{relocate_with} moves probes out of geometry, and ")
            + "on a terrain --grid surface:NXxNZ@H lays them above the ground")
    enabled = int(np.count_nonzero(grid.enabled))
    if enabled == 0:
        return "every probe is disabled (none found free space)" + hint, True
    inside = int(np.count_nonzero(probes_inside(grid, octree)))
    if inside == enabled:
        return (f"{'the probe stands' if inside == 1 else f'all {inside} probes stand'} "
                "inside solid voxels: the maps would hold nothing but that geometry" + hint,
                True)
    problems = []
    if inside:
        problems.append(f"{inside} of {enabled} probes stand inside solid voxels (distance "
                        "maps of zero)" + hint)
    crowded = [f"{axis} ({grid.spacing[i]:.3g} voxels)" for i, axis in enumerate("xyz")
               if grid.counts[i] > 1 and grid.spacing[i] < 1.0]
    if crowded:  # 100000x1x1 on a 96-voxel scene baked for minutes what one voxel shows
        problems.append(f"probes less than a voxel apart along {', '.join(crowded)}: "
                        "neighbours see almost the same maps; fewer probes cost less for the "
                        "same answer")
    lo, hi = (np.asarray(b, np.float64) for b in octree.voxel_bounds)
    positions = grid.positions[grid.enabled]
    gap = np.linalg.norm(np.maximum(np.maximum(lo - positions, positions - hi), 0.0), axis=1)
    if gap.min() > float((hi - lo).max()):  # probes around an object are welcome
        problems.append("every probe lies farther from the scene than its own size (its "
                        f"box: {', '.join(f'{v:g}' for v in lo)} to "
                        f"{', '.join(f'{v:g}' for v in hi)}); they see it from afar")
    return ("; and ".join(problems) or None), False


def check_placement(grid: ProbeGrid, octree: Octree, spec: str, *, relocated: bool,
                    relocate_with: str = "--relocate") -> None:
    """Refuse, before a bake, a grid (given as ``spec``) whose probes all stand in geometry
    or were all disabled (the bake "succeeded" with empty maps); warn of one partly inside
    or wholly far from the scene."""
    problem, nothing_to_bake = placement_problem(grid, octree, relocated=relocated,
                                                 relocate_with=relocate_with)
    if nothing_to_bake:
        raise VoxfieldError(f"{spec}: {problem}")
    if problem is not None:
        warnings.warn(f"{spec}: {problem}", stacklevel=2)


def fibonacci_directions(count: int, seed: int = 0) -> np.ndarray:
    """(count, 3) unit directions spread evenly over the sphere (golden-angle spiral), turned
    by a rotation drawn from ``seed`` so no direction lies exactly along a voxel axis."""
    index = np.arange(count) + 0.5
    z = 1 - 2 * index / count
    radius = np.sqrt(1 - z * z)
    phi = np.pi * (3 - np.sqrt(5)) * index
    dirs = np.stack([radius * np.cos(phi), radius * np.sin(phi), z], axis=1)
    q, r = np.linalg.qr(np.random.default_rng(seed).normal(size=(3, 3)))
    rotation = q * np.sign(np.diag(r))
    if np.linalg.det(rotation) < 0:
        rotation[:, 0] = -rotation[:, 0]
    return dirs @ rotation.T


_AXIS_DIRECTIONS = np.array(
    [[-1, 0, 0], [1, 0, 0], [0, -1, 0], [0, 1, 0], [0, 0, -1], [0, 0, 1]], np.float64
)
#: Outward normal of the voxel face with each ``normal_code`` (0..5 = -x, +x, -y, +y, -z, +z).
_FACE_NORMALS = _AXIS_DIRECTIONS


def _escape_moves(occupancy: _VoxelOccupancy, points: np.ndarray, offsets: np.ndarray,
                  limit: np.ndarray, directions: np.ndarray, clearance: float):
    """For probes inside solid voxels: the shortest way out along any of ``directions``
    (DDGI's "closest backface"), found with a voxel DDA. The move goes to the exit point and
    then ``clearance`` further out along the face it leaves through. Exits beyond the allowed
    offset box ``|offset| <= limit`` do not count. Returns (moves (M, 3), found (M,))."""
    m, k = len(points), len(directions)
    origin = np.repeat(points, k, axis=0)
    start_offset = np.repeat(offsets, k, axis=0)
    d = np.tile(directions, (m, 1))
    with np.errstate(divide="ignore", invalid="ignore"):
        inverse = np.where(d != 0, 1 / d, np.inf)
        # How far each ray may go before its offset leaves the allowed box.
        bound = np.where(d > 0, limit - start_offset, -limit - start_offset)
        reach = np.where(d != 0, bound * inverse, np.inf).min(axis=1)
        voxel = np.floor(origin).astype(np.int64)
        step = np.sign(d).astype(np.int64)
        next_plane = voxel + (step > 0)
        t_next = np.where(d != 0, (next_plane - origin) * inverse, np.inf)
    t_delta = np.abs(inverse)
    exit_t = np.full(len(d), np.inf)
    exit_axis = np.zeros(len(d), np.int64)
    live = np.arange(len(d))
    while live.size:
        axis = np.argmin(t_next[live], axis=1)
        t = t_next[live, axis]
        beyond = t > reach[live]
        voxel[live, axis] += step[live, axis]
        t_next[live, axis] += t_delta[live, axis]
        free = ~beyond & ~occupancy.solid(voxel[live])
        exit_t[live[free]] = t[free]
        exit_axis[live[free]] = axis[free]
        live = live[~beyond & ~free]
    # Each exit's full move: to the exit point, then the clearance out along its face.
    leave_normal = np.zeros((len(d), 3))
    rays = np.arange(len(d))
    leave_normal[rays, exit_axis] = np.sign(d[rays, exit_axis])
    with np.errstate(invalid="ignore"):
        moves = d * exit_t[:, None] + leave_normal * (clearance + _NUDGE)
    fits = np.all(np.abs(start_offset + moves) <= limit, axis=1)
    # Prefer the nearest exit that keeps the clearance inside the box, else the nearest.
    rank = np.where(fits, exit_t, np.inf).reshape(m, k)
    fallback = exit_t.reshape(m, k)
    best = np.where(np.isfinite(rank).any(axis=1), np.argmin(rank, axis=1),
                    np.argmin(fallback, axis=1))
    ray = np.arange(m) * k + best
    found = np.isfinite(exit_t[ray])
    return np.where(found[:, None], moves[ray], 0.0), found


def _touching_faces(occupancy: _VoxelOccupancy, points: np.ndarray) -> np.ndarray:
    """(M, 6) True where a probe in a free voxel lies exactly on the boundary of a solid
    voxel, per outward face direction to move along (code 0..5 = -x, +x, ... +z).

    Rays from such a probe start on the solid and report no entered face, so the contact is
    read from the voxels instead. On each axis where the probe's coordinate is a whole number
    it sits between two voxels, and its own voxel (the upper one on every such axis) is free;
    the solids that touch it lie below it on some set of those axes. The contacts sharing the
    fewest axes are the real ones (a face before an edge before a corner): moving up along
    their axes clears them, and an edge or corner behind a face is cleared with that face.
    """
    voxel = np.floor(points).astype(np.int64)
    on_plane = points == voxel
    faces = np.zeros((len(points), 6), bool)
    settled = np.zeros(len(points), bool)
    for size in (1, 2, 3):
        found = np.zeros(len(points), bool)
        for subset in range(1, 8):
            axes = [a for a in range(3) if subset >> a & 1]
            if len(axes) != size:
                continue
            usable = ~settled & on_plane[:, axes].all(axis=1)
            if not usable.any():
                continue
            neighbour = voxel.copy()
            neighbour[:, axes] -= 1
            touching = usable & occupancy.solid(neighbour)
            for a in axes:
                faces[:, 2 * a + 1] |= touching
            found |= touching
        settled |= found
    return faces


def _clearance_moves(octree: Octree, occupancy: _VoxelOccupancy, points: np.ndarray,
                     directions: np.ndarray, clearance: float):
    """For probes in free space: rays shorter than ``clearance`` find the surfaces too close
    (DDGI's closest frontface). Voxel faces are axis-aligned, so each hit's face normal gives
    the exact distance to its plane; the move pushes the probe out to ``clearance`` from every
    such plane (the largest push per face direction, summed over the six, so a corner pushes
    on two axes at once). Returns (moves (M, 3), close (M,))."""
    m, k = len(points), len(directions)
    if clearance <= 0 or m == 0:
        return np.zeros((m, 3)), np.zeros(m, bool)
    d = np.tile(directions, (m, 1))
    hits = trace(octree, np.repeat(points, k, axis=0), d, lod=0, tmax=clearance)
    hit = hits.hit.reshape(m, k)
    code = hits.normal_code.reshape(m, k)
    t = hits.t.reshape(m, k)
    dirs = d.reshape(m, k, 3)
    # Plane distance of each face hit: t times the direction's component along the normal.
    axis = np.maximum(code, 0) // 2
    along_normal = np.abs(np.take_along_axis(dirs, axis[..., None], axis=2)[..., 0])
    need = np.where(hit & (code >= 0), clearance - t * along_normal + _NUDGE, 0.0)
    per_face = np.zeros((m, 6))
    for face in range(6):
        per_face[:, face] = np.where(code == face, need, 0.0).max(axis=1)
    touching = (hit & (code < 0)).any(axis=1)
    if touching.any():
        faces = _touching_faces(occupancy, points[touching])
        per_face[touching] = np.where(faces, clearance + _NUDGE, per_face[touching])
    return per_face @ _FACE_NORMALS, hit.any(axis=1)


#: Most directions ``relocate`` casts from a probe: DDGI uses tens to a few hundred; ten
#: million held every probe's rays at once and was killed for memory.
MAX_RELOCATION_RAYS = 4096


def relocate(
    grid: ProbeGrid, octree: Octree, *, max_shift: float = 0.45, clearance: float | None = None,
    rays: int = 64, iterations: int = 6, seed: int = 0,
) -> tuple[ProbeGrid, RelocationReport]:
    """Move probes out of and away from geometry, as DDGI's probe relocation does.

    Each round, a probe inside a solid voxel moves along the shortest way out among ``rays``
    directions (plus the six axes); a probe in free space traces ``rays`` short rays and, if a
    surface is nearer than ``clearance`` (default ``DEFAULT_CLEARANCE_FRACTION`` of the
    smallest spacing), moves away from it. Offsets stay within ``max_shift`` of a cell per
    axis. After ``iterations`` rounds, a probe still inside or too close is disabled and keeps
    its old offset. Voxels are solid cubes, so "inside" is exact (the probe's own voxel is
    solid) rather than DDGI's count of backface hits. A probe enclosed in a sealed hollow is
    in free space and is not detected. Deterministic for a given ``seed`` (which turns the ray
    directions). Probes already disabled are left alone.
    """
    if not isinstance(grid, ProbeGrid):
        raise VoxfieldError(f"relocate needs a ProbeGrid, got {type(grid).__name__}")
    check_octree(octree, "relocate")  # None failed on its first attribute
    if not (math.isfinite(max_shift) and 0 <= max_shift <= MAX_OFFSET_FRACTION):
        raise VoxfieldError(f"max_shift must be between 0 and {MAX_OFFSET_FRACTION} of a "
                            f"cell, got {max_shift}")
    if clearance is None:
        clearance = DEFAULT_CLEARANCE_FRACTION * float(grid.spacing.min())
    if not (math.isfinite(clearance) and clearance >= 0):
        raise VoxfieldError(f"clearance must be a distance >= 0 in voxels, got {clearance}")
    if not is_integer(rays) or not 6 <= rays <= MAX_RELOCATION_RAYS:
        raise VoxfieldError(f"relocation takes 6..{MAX_RELOCATION_RAYS} rays per probe, got "
                            f"{rays!r}")
    if int(iterations) != iterations or iterations < 1:
        raise VoxfieldError(f"relocation needs at least one iteration, got {iterations}")
    occupancy = voxel_occupancy(octree)
    directions = fibonacci_directions(int(rays), seed_value(seed))
    escape_directions = np.concatenate([directions, _AXIS_DIRECTIONS])
    limit = max_shift * grid.spacing
    base = grid.base_positions
    offsets = grid.offsets.copy()
    started_inside = np.zeros(grid.count, bool)
    inside = np.zeros(grid.count, bool)  # as of each probe's latest look
    blocked = np.zeros(grid.count, bool)  # inside or too close, as of the latest look
    moved = np.zeros(grid.count, bool)
    pending = np.flatnonzero(grid.enabled)  # probes whose latest position is unchecked
    for round_ in range(int(iterations) + 1):
        if not pending.size:
            break
        points = base[pending] + offsets[pending]
        now_inside = occupancy.contains(points)
        moves = np.zeros((len(pending), 3))
        close = np.zeros(len(pending), bool)
        if now_inside.any():
            moves[now_inside], _ = _escape_moves(
                occupancy, points[now_inside], offsets[pending[now_inside]], limit,
                escape_directions, clearance)
        if not now_inside.all():
            moves[~now_inside], close[~now_inside] = _clearance_moves(
                octree, occupancy, points[~now_inside], directions, clearance)
        if round_ == 0:
            started_inside[pending] = now_inside
        inside[pending] = now_inside
        blocked[pending] = now_inside | close
        if round_ == iterations:
            break  # the last look only checks the last moves
        target = np.clip(offsets[pending] + moves, -limit, limit)
        # A free probe is done; a blocked one that cannot move any more is stuck.
        changed = blocked[pending] & np.any(target != offsets[pending], axis=1)
        offsets[pending[changed]] = target[changed]
        moved[pending[changed]] = True
        pending = pending[changed]
    failed = grid.enabled & blocked
    offsets[failed] = grid.offsets[failed]
    reasons = np.full(grid.count, CLEAR, dtype=object)
    reasons[moved] = np.where(started_inside[moved], ESCAPED, PUSHED)
    reasons[failed] = np.where(inside[failed], INSIDE, TOO_CLOSE)
    reasons[~grid.enabled] = SKIPPED
    report = RelocationReport(
        offsets=_frozen(offsets.copy()), reasons=tuple(str(r) for r in reasons),
        moved=_frozen(np.flatnonzero(moved & ~failed)), disabled=_frozen(np.flatnonzero(failed)),
        clearance=float(clearance), max_shift=float(max_shift),
    )
    return replace(grid, offsets=offsets, enabled=grid.enabled & ~failed), report
