"""Assets scattered on the terrain: seeded Poisson-disk sites kept by slope, water, height band
and density (``place_assets``), the placed models' voxels above the ground (``scatter_assets``),
and ``downsample_scene``, which fits a model to the footprint.

Scattering only reads the columns (``TerrainColumns``); the ground always wins where a model
would be buried, and where models overlap the first placed wins.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from voxfield.errors import VoxfieldError
from voxfield.scene.terrain.columns import TerrainColumns
from voxfield.scene.terrain.resample import resample
from voxfield.scene.voxel_scene import VoxelScene


@dataclass(frozen=True)
class AssetGroup:
    """Models scattered together under one set of placement rules.

    ``density`` is the fraction (0..1) of a packed Poisson-disk set of sites kept; ``spacing``
    the minimum distance between sites in voxels (default: the widest model's footprint, so
    models do not intersect). Sites need slope ≤ ``max_slope`` (rise per run), dry land and a
    height fraction within ``height_range``. ``clumping`` > 0 gathers sites into groves (a
    smooth seeded density field); ``rotate`` turns each model by a random multiple of 90°
    about y; ``embed`` sinks models that many voxels into the ground (0: base at top + 1).
    """

    models: Sequence[VoxelScene]
    density: float = 0.3
    spacing: float | None = None
    max_slope: float = 1.0
    height_range: tuple[float, float] = (0.0, 1.0)
    clumping: float = 0.0
    rotate: bool = True
    embed: int = 0

    def __post_init__(self) -> None:
        models = tuple(self.models)
        if not models or not all(isinstance(m, VoxelScene) and len(m) for m in models):
            raise VoxfieldError("an asset group needs at least one non-empty VoxelScene model")
        object.__setattr__(self, "models", models)
        if not 0.0 <= self.density <= 1.0:
            raise VoxfieldError(f"asset density must be in [0, 1], got {self.density}")
        if self.spacing is not None and not self.spacing >= 1:
            raise VoxfieldError(f"asset spacing must be at least 1 voxel, got {self.spacing}")
        if self.embed < 0:
            raise VoxfieldError(f"embed must be >= 0 voxels, got {self.embed}")

    @property
    def height(self) -> int:
        """Tallest model height in voxels (headroom the terrain must leave)."""
        return max(int(m.extent[1]) for m in self.models) - int(self.embed)

    @property
    def width(self) -> int:
        return max(int(max(m.extent[0], m.extent[2])) for m in self.models)


@dataclass(frozen=True)
class Placements:
    """Where assets stand: anchor column ``(x, z)``, base height ``y`` (lowest model voxel),
    model index and quarter turns about y; one entry per placed asset."""

    x: np.ndarray
    z: np.ndarray
    y: np.ndarray
    model: np.ndarray
    turns: np.ndarray

    def __len__(self) -> int:
        return len(self.x)


def poisson_disk(size: int, spacing: float, rng: np.random.Generator, tries: int = 8) -> np.ndarray:
    """Points (n×2, x then z) in ``[0, size)²`` at least ``spacing`` apart, nearly packed.

    Parallel dart throwing on a grid of cells ``spacing/√2`` wide (one point per cell): cells
    are processed in 9 phase groups whose members are 3 cells apart, so a group's candidates
    cannot conflict and each group is one vectorised test against the 5×5 cells around it.
    """
    r = float(spacing)
    cell = r / math.sqrt(2)
    g = int(math.ceil(size / cell))
    pts = np.full((g + 4, g + 4, 2), np.nan)  # padded by 2 cells each side
    for phase in rng.permutation(9):
        ci, cj = np.meshgrid(np.arange(phase // 3, g, 3), np.arange(phase % 3, g, 3), indexing="ij")
        ci, cj = ci.ravel(), cj.ravel()
        for _ in range(tries):
            empty = np.isnan(pts[ci + 2, cj + 2, 0])
            if not empty.any():
                break
            ei, ej = ci[empty], cj[empty]
            cand = (np.stack([ei, ej], axis=1) + rng.random((len(ei), 2))) * cell  # (z, x)
            ok = (cand < size).all(axis=1)
            for di in range(-2, 3):
                for dj in range(-2, 3):
                    if di == 0 and dj == 0:
                        continue
                    nb = pts[ei + 2 + di, ej + 2 + dj]
                    d2 = ((nb - cand) ** 2).sum(axis=1)
                    ok &= ~(d2 < r * r)  # NaN (empty cell) compares False: no conflict
            pts[ei[ok] + 2, ej[ok] + 2] = cand[ok]
    inner = pts[2:-2, 2:-2].reshape(-1, 2)
    inner = inner[~np.isnan(inner[:, 0])]
    return inner[:, ::-1].copy()  # (x, z)


def _rotated(model: VoxelScene, turns: int) -> tuple[np.ndarray, np.ndarray]:
    """Model voxels turned ``turns`` × 90° about y, relative to its anchor (base layer's centre,
    base at y = 0), and the (x, z) bounds of that relative box."""
    c = model.coords.copy()
    for _ in range(turns % 4):
        c[:, 0], c[:, 2] = c[:, 2].copy(), -c[:, 0]
    base = c[:, 1] == c[:, 1].min()
    anchor = np.array(
        [np.floor(c[base, 0].mean() + 0.5), c[:, 1].min(), np.floor(c[base, 2].mean() + 0.5)],
        dtype=np.int64,
    )
    rel = c - anchor
    return rel, np.array([rel[:, 0].min(), rel[:, 0].max(), rel[:, 2].min(), rel[:, 2].max()])


def place_assets(cols: TerrainColumns, group: AssetGroup, rng: np.random.Generator) -> Placements:
    """Seeded sites for one asset group: Poisson-disk, filtered by slope, water and height band,
    thinned to ``density`` (modulated by clumping), each model fully inside the map."""
    f = cols.footprint
    spacing = group.spacing if group.spacing is not None else max(group.width, 1)
    pts = poisson_disk(f, spacing, rng)
    n_models = len(group.models)
    model = rng.integers(n_models, size=len(pts))
    turns = rng.integers(4, size=len(pts)) if group.rotate else np.zeros(len(pts), np.int64)
    keep_u = rng.random(len(pts))
    if group.clumping > 0:
        # Deferred: SciPy's ndimage adds 0.1 s to every command's start; terrains use it.
        from scipy import ndimage

        noise = rng.standard_normal((max(f // 16, 2),) * 2)
        noise = ndimage.gaussian_filter(noise, sigma=max(f // 16, 2) / 12, mode="wrap")
        noise = (noise - noise.mean()) / (noise.std() + 1e-12)
        field_ = np.exp(3.0 * group.clumping * noise)
        field_ /= field_.mean()
        field_ = resample(field_, (f, f), "linear")
    x = np.floor(pts[:, 0]).astype(np.int64)
    z = np.floor(pts[:, 1]).astype(np.int64)
    hfrac = cols.height_fraction[z, x]
    ok = (cols.slope[z, x] <= group.max_slope) & ~cols.water[z, x]
    ok &= (hfrac >= group.height_range[0]) & (hfrac <= group.height_range[1])
    p = np.full(len(pts), group.density)
    if group.clumping > 0:
        p = np.minimum(1.0, group.density * field_[z, x])
    ok &= keep_u < p
    boxes = np.array([[_rotated(mod, t)[1] for t in range(4)] for mod in group.models])
    box = boxes[model, turns].reshape(-1, 4)
    ok &= (x + box[:, 0] >= 0) & (x + box[:, 1] < f) & (z + box[:, 2] >= 0) & (z + box[:, 3] < f)
    x, z, model, turns = x[ok], z[ok], model[ok], turns[ok]
    y = cols.top[z, x].astype(np.int64) + 1 - int(group.embed)
    return Placements(x=x, z=z, y=y, model=model, turns=turns)


@dataclass
class AssetVoxels:
    """Asset voxels as flat arrays (int32 x, y, z; float32 colours), before they join the ground."""

    x: np.ndarray
    y: np.ndarray
    z: np.ndarray
    color: np.ndarray
    emission: np.ndarray | None

    def __len__(self) -> int:
        return len(self.x)

    def take(self, idx: np.ndarray) -> AssetVoxels:
        em = None if self.emission is None else self.emission[idx]
        return AssetVoxels(self.x[idx], self.y[idx], self.z[idx], self.color[idx], em)

    @staticmethod
    def join(parts: Sequence[AssetVoxels]) -> AssetVoxels:
        if not parts:
            z = np.zeros(0, np.int32)
            return AssetVoxels(z, z, z, np.zeros((0, 3), np.float32), None)
        emission = None
        if any(p.emission is not None for p in parts):
            emission = np.concatenate(
                [p.emission if p.emission is not None else np.zeros_like(p.color) for p in parts]
            )
        return AssetVoxels(
            np.concatenate([p.x for p in parts]),
            np.concatenate([p.y for p in parts]),
            np.concatenate([p.z for p in parts]),
            np.concatenate([p.color for p in parts]),
            emission,
        )


def _instantiate(cols: TerrainColumns, group: AssetGroup, placed: Placements) -> AssetVoxels:
    """Voxels of the placed models, minus those buried in the ground (the ground wins)."""
    f = cols.footprint
    any_emission = any(m.emission is not None for m in group.models)
    top = cols.top.ravel()
    parts = []
    for m, model in enumerate(group.models):
        for t in range(4):
            sel = (placed.model == m) & (placed.turns == t)
            if not sel.any():
                continue
            rel, _ = _rotated(model, t)
            rel = rel.astype(np.int32)
            # int32 and one axis at a time: this is the hot loop of a dense forest (~10M voxels).
            x = (placed.x[sel].astype(np.int32)[:, None] + rel[None, :, 0]).ravel()
            z = (placed.z[sel].astype(np.int32)[:, None] + rel[None, :, 2]).ravel()
            y = (placed.y[sel].astype(np.int32)[:, None] + rel[None, :, 1]).ravel()
            keep = (y < f) & (y > np.take(top, z.astype(np.int64) * f + x))
            keep_inst = keep.reshape(int(sel.sum()), -1)
            color = np.broadcast_to(model.color, keep_inst.shape + (3,))[keep_inst]
            emission = None
            if any_emission:
                em = model.emission if model.emission is not None else np.zeros_like(model.color)
                emission = np.broadcast_to(em, keep_inst.shape + (3,))[keep_inst]
            parts.append(AssetVoxels(x[keep], y[keep], z[keep], color, emission))
    return AssetVoxels.join(parts)


def _first_occurrences(keys: np.ndarray) -> np.ndarray:
    """Sorted indices of the first occurrence of each distinct non-negative key.

    Sorts ``key * n + index`` values rather than arg-sorting keys (about 2× faster for the
    millions of voxels of a forest) when that fits in int64.
    """
    n = len(keys)
    if n == 0:
        return np.zeros(0, np.int64)
    if int(keys.max()) < (2**62) // max(n, 1):
        packed = keys.astype(np.int64) * n + np.arange(n, dtype=np.int64)
        packed.sort()
        k = packed // n
        first = np.ones(n, dtype=bool)
        first[1:] = k[1:] != k[:-1]
        idx = packed[first] % n
    else:
        order = np.argsort(keys, kind="stable")
        k = keys[order]
        first = np.ones(n, dtype=bool)
        first[1:] = k[1:] != k[:-1]
        idx = order[first]
    idx.sort()
    return idx


def scatter_assets(cols: TerrainColumns, groups: Sequence[AssetGroup], seed: int) -> AssetVoxels:
    """All asset voxels of all groups, none in the ground; where models overlap, the first
    placed wins (groups in order)."""
    parts = []
    for k, group in enumerate(groups):
        placed = place_assets(cols, group, np.random.default_rng([seed, 1, k]))
        parts.append(_instantiate(cols, group, placed))
    voxels = AssetVoxels.join(parts)
    if len(voxels) == 0:
        return voxels
    f = np.int64(cols.footprint)
    keys = (voxels.y.astype(np.int64) * f + voxels.z) * f + voxels.x
    keep = _first_occurrences(keys)
    return voxels if len(keep) == len(voxels) else voxels.take(keep)


def downsample_scene(scene: VoxelScene, factor: int) -> VoxelScene:
    """A coarser copy: each ``factor``³ block with any voxel becomes one voxel of the mean colour.

    Fits a model to a footprint (a 128-voxel pine is a 64-voxel pine at factor 2); thin parts
    survive because any occupied voxel keeps its block.
    """
    factor = int(factor)
    if factor < 1:
        raise VoxfieldError(f"downsampling factor must be >= 1, got {factor}")
    if factor == 1 or len(scene) == 0:
        return scene
    lo = scene.coords.min(axis=0)
    q = (scene.coords - lo) // factor
    keys, inv = np.unique(q, axis=0, return_inverse=True)
    inv = inv.ravel()
    count = np.bincount(inv, minlength=len(keys)).astype(np.float64)[:, None]

    def mean(values):
        return (
            np.stack(
                [np.bincount(inv, weights=values[:, k], minlength=len(keys)) for k in range(3)],
                axis=1,
            )
            / count
        )

    emission = None if scene.emission is None else mean(scene.emission)
    channels = {k: mean(v) for k, v in scene.channels.items()}
    return VoxelScene(keys, mean(scene.color), emission, channels, scene.name)
