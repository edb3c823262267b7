"""Lighting-aware error (EA thesis §6.1): child masks extended with per-child bright flags.

The geometric table knows which children exist; under lighting a node can also be wrong
because the children a ray would see first are lit and the ones it averages in are not.
A configuration adds to the mask the subset of children whose luminance is well above the
parent's, and the table stores its colour error (``kernels.lighting_error``) per direction
as an octahedral map. The 3^8 = 6561 configurations collapse under the 48 cube symmetries;
only configurations with both bright and other children have colour error, and one map per
symmetry class is stored with, per configuration, its class and the symmetry that carries
it onto the class representative: ``e(C, d) = e(R, g·d)`` where ``g·C = R``.
"""

from __future__ import annotations

import functools
import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from voxfield.atomic import atomic_path
from voxfield.error_table.symmetry import cube_symmetries, octant_permutation
from voxfield.error_table.table import (
    LIGHTING_FORMAT,
    ErrorTableError,
    _checksum,
    check_resolution,
    check_table_file,
    read_table_file,
)
from voxfield.errors import VoxfieldError
from voxfield.kernels.error_lookup import colour_error_many
from voxfield.kernels.error_raycast import image_plane_samples
from voxfield.kernels.lighting_error import configuration_colour_errors
from voxfield.kernels.octahedral import add_border, texel_directions
from voxfield.progress import progress_bar

FORMAT = LIGHTING_FORMAT
FORMAT_VERSION = 1
DEFAULT_LIGHTING_TABLE = Path(__file__).parent / "data" / "lighting_error_table.npz"
REBUILD_COMMAND = ("voxfield errors build-lighting --out "
                   "src/voxfield/error_table/data/lighting_error_table.npz")
#: Configuration index: ``mask | bright << 8`` with ``bright ⊆ mask``.
N_INDICES = 1 << 16
NO_COLOUR_ERROR = -1


def configuration_index(mask, bright):
    return np.asarray(mask, np.int64) | (np.asarray(bright, np.int64) << 8)


def _transform_bits(perm: np.ndarray, bits: np.ndarray) -> np.ndarray:
    out = np.zeros_like(bits)
    for c in range(8):
        out |= ((bits >> c) & 1) << perm[c]
    return out


def configuration_classes() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(class_of, symmetry_of, representatives)`` over all 2^16 configuration indices.

    ``class_of[i]`` is the map index of configuration ``i`` (``NO_COLOUR_ERROR`` where the
    index is not a configuration or it has no colour error: no bright child, or all bright);
    ``symmetry_of[i]`` the cube symmetry ``g`` with ``g·C = R``; ``representatives`` the
    class representatives' indices, in map order.
    """
    index = np.arange(N_INDICES, dtype=np.int64)
    mask, bright = index & 0xFF, index >> 8
    valid = ((bright & ~mask) == 0) & (bright != 0) & (bright != mask)
    symmetries = cube_symmetries()
    images = np.stack([
        configuration_index(_transform_bits(p, mask), _transform_bits(p, bright))
        for p in (octant_permutation(g) for g in symmetries)
    ])  # (48, N)
    symmetry_of = np.argmin(images, axis=0).astype(np.int8)
    rep = images[symmetry_of, index]
    representatives = np.unique(rep[valid])
    class_of = np.full(N_INDICES, NO_COLOUR_ERROR, np.int16)
    class_of[valid] = np.searchsorted(representatives, rep[valid])
    return class_of, symmetry_of, representatives


@dataclass(frozen=True)
class LightingErrorTable:
    """Colour error per (mask, bright) configuration and direction; ``colour_error`` is the
    one interface, the arrays are what kernels read."""

    oct_map: np.ndarray  # (classes, R + 2, R + 2) float32
    class_of: np.ndarray  # (65536,) int16
    symmetry_of: np.ndarray  # (65536,) int8
    symmetries: np.ndarray  # (48, 3, 3) float64
    params: dict = field(default_factory=dict)

    @property
    def class_count(self) -> int:
        return self.oct_map.shape[0]

    def colour_error(self, mask, bright, direction) -> np.ndarray:
        """Colour error for masks, bright subsets (ints or arrays) and directions (…×3)."""
        masks = np.asarray(mask, np.int64)
        brights = np.asarray(bright, np.int64)
        dirs = np.asarray(direction, np.float64)
        if dirs.shape[-1] != 3 or not np.all(np.isfinite(dirs)):
            raise VoxfieldError("directions must be finite and end in 3 components")
        if np.any((masks < 0) | (masks > 255)) or np.any(brights & ~masks):
            raise VoxfieldError("masks are 0..255 and bright flags a subset of the mask")
        norms = np.linalg.norm(dirs, axis=-1, keepdims=True)
        if np.any(norms == 0):
            raise VoxfieldError("directions must be non-zero")
        masks, brights, dx, dy, dz = np.broadcast_arrays(
            masks, brights, *np.moveaxis(dirs / norms, -1, 0))
        out = colour_error_many(
            self.oct_map, self.class_of, self.symmetry_of, self.symmetries,
            np.array(masks.ravel()), np.array(brights.ravel()),
            np.array(dx.ravel()), np.array(dy.ravel()), np.array(dz.ravel()))
        return out.reshape(masks.shape)


def raycast_colour_errors(masks, brights, directions, resolution: int = 512,
                          seed: int = 0) -> np.ndarray:
    """(n_configurations, n_directions) ray-cast colour errors (the table's ground truth)."""
    resolution = check_resolution(resolution)
    dirs = np.ascontiguousarray(directions, np.float64)
    dirs = dirs / np.linalg.norm(dirs, axis=1, keepdims=True)
    samples = image_plane_samples(resolution, int(seed))
    return configuration_colour_errors(dirs, samples, np.asarray(masks, np.int64),
                                       np.asarray(brights, np.int64))


def build_lighting_error_table(
    resolution: int = 512, oct_resolution: int = 32, seed: int = 0, progress: bool = False,
) -> LightingErrorTable:
    """Ray-cast one octahedral map per symmetry class at the texel-centre directions."""

    if not 2 <= oct_resolution <= 256:
        raise VoxfieldError(f"octahedral map resolution must be in 2..256, got {oct_resolution}")
    class_of, symmetry_of, reps = configuration_classes()
    texels = texel_directions(oct_resolution)
    chunk = 64
    parts = []
    with progress_bar(total=len(texels), desc="lighting table", unit="dir",
                      enabled=progress) as bar:
        for i in range(0, len(texels), chunk):
            parts.append(raycast_colour_errors(reps & 0xFF, reps >> 8, texels[i : i + chunk],
                                               resolution, seed))
            bar.update(min(chunk, len(texels) - i))
    interior = np.concatenate(parts, axis=1).reshape(len(reps), oct_resolution, oct_resolution)
    params = {
        "resolution": int(resolution), "oct_resolution": int(oct_resolution), "seed": int(seed),
        "classes": int(len(reps)), "configurations": int(np.count_nonzero(class_of >= 0)),
    }
    return LightingErrorTable(
        oct_map=add_border(interior).astype(np.float32), class_of=class_of,
        symmetry_of=symmetry_of, symmetries=cube_symmetries().astype(np.float64), params=params,
    )


def save_lighting_error_table(table: LightingErrorTable, path: str | Path) -> Path:
    """Write the table with its parameters and a SHA-256 of its arrays (atomically)."""
    arrays = {"oct_map": table.oct_map, "class_of": table.class_of,
              "symmetry_of": table.symmetry_of, "symmetries": table.symmetries}
    header = {"format": FORMAT, "version": FORMAT_VERSION, "params": table.params,
              "sha256": _checksum(arrays)}
    path = Path(path)
    with atomic_path(path) as tmp, open(tmp, "wb") as f:
        np.savez_compressed(f, header=np.frombuffer(json.dumps(header).encode(), np.uint8),
                            **arrays)
    _packaged_lighting_table.cache_clear()  # a rebuilt packaged table is read afresh
    return path


def load_lighting_error_table(path: str | Path | None = None) -> LightingErrorTable:
    """Read a lighting table (the packaged one by default, read once per process),
    verifying its checksum."""
    if path is None:
        return _packaged_lighting_table()
    return _read_lighting_table(Path(path))


@functools.lru_cache(maxsize=1)
def _packaged_lighting_table() -> LightingErrorTable:
    return _read_lighting_table(DEFAULT_LIGHTING_TABLE)


def _read_lighting_table(path: Path) -> LightingErrorTable:
    hint = f"rebuild it with `{REBUILD_COMMAND}`" if path == DEFAULT_LIGHTING_TABLE else (
        f"rebuild it with `voxfield errors build-lighting --out {path}`")
    check_table_file(path, "lighting error table", hint)
    header, arrays = read_table_file(
        path, ("oct_map", "class_of", "symmetry_of", "symmetries"), FORMAT, FORMAT_VERSION,
        "lighting error table", hint, "voxfield errors build-lighting")
    classes = arrays["oct_map"].shape[0] if arrays["oct_map"].ndim == 3 else -1
    if (arrays["class_of"].shape != (N_INDICES,) or arrays["symmetries"].shape != (48, 3, 3)
            or arrays["symmetry_of"].shape != (N_INDICES,) or classes < 1
            or int(arrays["class_of"].max()) >= classes):
        raise ErrorTableError(f"lighting error table {path} has inconsistent arrays; {hint}")
    return LightingErrorTable(**arrays, params=header.get("params", {}))
