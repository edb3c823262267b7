"""VoxelScene: the one in-memory form every reader produces and the octree builder consumes."""

from __future__ import annotations

import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from voxfield.errors import VoxfieldError
from voxfield.fingerprint import array_fingerprint

#: Largest coordinate extent a scene may span (21 bits per axis fit a 63-bit Morton code).
MAX_EXTENT = 1 << 21
#: Largest voxel coordinate either way: differences and extents of coordinates this far
#: from the origin still fit int64 (beyond it they wrapped round and built a wrong octree).
MAX_COORDINATE = 1 << 61


#: Channel names become ``attr_NAME`` keys in octree files and file-name parts of previews.
_CHANNEL_NAME = re.compile(r"[A-Za-z0-9_-]{1,64}")
#: Names the octree gives its own colours: a channel so named would replace them.
_RESERVED = {"color": "the albedo", "albedo": "the albedo", "emission": "the emission"}


def check_channel_name(name: str) -> str:
    """``name`` if it can name a channel, of a scene or an octree; VoxfieldError otherwise.
    A scene checks its channels' names when made, so a scene file's bad name is met, and
    named, as the file is read (``scene.npz_io``), not at the octree build."""
    if not isinstance(name, str) or not _CHANNEL_NAME.fullmatch(name):
        raise VoxfieldError(
            f"channel name {name!r} must be 1-64 letters, digits, '_' or '-'"
        )
    if name in _RESERVED:
        raise VoxfieldError(f"channel {name!r} is {_RESERVED[name]}; choose another name")
    return name


@dataclass(frozen=True)
class VoxelScene:
    """A set of occupied voxels with linear colours.

    ``coords`` are integer voxel positions (N×3, x, y, z with +y up); ``color`` is linear RGB
    in [0, 1] (N×3 float32); ``emission`` is optional linear emitted radiance (N×3 float32);
    ``channels`` holds extra per-voxel RGB channels (e.g. lit colours per time of day).
    Each voxel appears once: readers resolve overlaps before construction (see ``dedupe``).
    """

    coords: np.ndarray
    color: np.ndarray
    emission: np.ndarray | None = None
    channels: Mapping[str, np.ndarray] = field(default_factory=dict)
    name: str = "scene"

    def __repr__(self) -> str:  # the default printed every array in full
        extra = sorted(self.channels) + (["emission"] if self.emission is not None else [])
        return (f"VoxelScene({self.name!r}: {len(self.coords):,} voxels"
                f"{', also ' + ', '.join(extra) if extra else ''})")

    def __post_init__(self) -> None:
        coords = np.asarray(self.coords)
        if coords.ndim != 2 or coords.shape[1] != 3:
            raise VoxfieldError(f"voxel coords must be N×3, got shape {coords.shape}")
        if coords.size and not np.issubdtype(coords.dtype, np.integer):
            raise VoxfieldError(f"voxel coords must be integers, got {coords.dtype}")
        # Compared in the array's own type, before int64 could wrap a uint64 round.
        if coords.size and (coords.max() > MAX_COORDINATE or coords.min() < -MAX_COORDINATE):
            raise VoxfieldError(f"voxel coords must lie within ±2^61 of the origin, got "
                                f"{coords.min()}..{coords.max()}")
        object.__setattr__(self, "coords", coords.astype(np.int64, copy=False))
        n = len(coords)
        object.__setattr__(self, "color", _checked_albedo(_checked_rgb(self.color, n, "color")))
        if self.emission is not None:
            object.__setattr__(self, "emission",
                               _checked_light(_checked_rgb(self.emission, n, "emission"),
                                              "emission"))
        if not isinstance(self.channels, Mapping):
            raise VoxfieldError(f"channels must map names to N×3 colours, got "
                                f"{type(self.channels).__name__}")
        checked = {check_channel_name(k): _checked_light(_checked_rgb(v, n, f"channel {k!r}"),
                                                         f"channel {k!r}")
                   for k, v in self.channels.items()}
        object.__setattr__(self, "channels", checked)

    def __len__(self) -> int:
        return len(self.coords)

    def fingerprint(self) -> str:
        """Names the voxels and every colour channel: equal scenes give equal fingerprints."""
        arrays = [self.coords, self.color]
        if self.emission is not None:
            arrays.append(self.emission)
        arrays += [self.channels[k] for k in sorted(self.channels)]
        return array_fingerprint(*arrays)

    @property
    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Inclusive min and exclusive max voxel corner (each a length-3 int array)."""
        if len(self) == 0:
            zero = np.zeros(3, dtype=np.int64)
            return zero, zero
        return self.coords.min(axis=0), self.coords.max(axis=0) + 1

    @property
    def extent(self) -> np.ndarray:
        lo, hi = self.bounds
        return hi - lo

    def translated(self, offset: Sequence[int]) -> VoxelScene:
        """The same voxels moved by a whole-voxel offset (a fraction is refused: casting
        it to integers moved -1.7 by -1 without a word)."""
        return self._with(coords=self.coords + whole_offset(offset))

    def normalized(self) -> VoxelScene:
        """Moved so that the minimum corner is at the origin (what the octree expects)."""
        lo, _ = self.bounds
        return self.translated(-lo)

    def subset(self, keep: np.ndarray) -> VoxelScene:
        """The voxels selected by a boolean mask or index array."""
        return self._with(
            coords=self.coords[keep],
            color=self.color[keep],
            emission=None if self.emission is None else self.emission[keep],
            channels={k: v[keep] for k, v in self.channels.items()},
        )

    def dedupe(self) -> VoxelScene:
        """One voxel per position; where several share one, the last given wins."""
        if len(self) == 0:
            return self
        lo = self.coords.min(axis=0)
        span = self.coords.max(axis=0) - lo + 1
        if int(span[0]) * int(span[1]) * int(span[2]) < 2**62:
            key = np.ravel_multi_index((self.coords - lo).T, tuple(int(s) for s in span))
        else:  # too wide for one int64 key: compare whole rows instead
            key = self.coords
        # Reverse so np.unique's first occurrence is the last given voxel.
        _, first_rev = np.unique(key[::-1], return_index=True, axis=0 if key.ndim == 2 else None)
        keep = np.sort(len(key) - 1 - first_rev)
        if len(keep) == len(self):
            return self
        return self.subset(keep)

    def _with(self, **changes) -> VoxelScene:
        fields = {
            "coords": self.coords,
            "color": self.color,
            "emission": self.emission,
            "channels": self.channels,
            "name": self.name,
        }
        fields.update(changes)
        return VoxelScene(**fields)


def _checked_rgb(values, n: int, what: str) -> np.ndarray:
    kind = np.asarray(values).dtype.kind
    if kind not in "fiu":
        raise VoxfieldError(f"{what} must hold real numbers, got {np.asarray(values).dtype}")
    with np.errstate(over="ignore"):  # past float32's range: infinite, refused just below
        arr = np.asarray(values, dtype=np.float32)
    if arr.shape != (n, 3):
        raise VoxfieldError(f"{what} must be {n}×3 to match the voxel coords, got {arr.shape}")
    if n and not np.isfinite(arr).all():
        raise VoxfieldError(f"{what} holds NaN or infinite values")
    return arr


def _checked_albedo(color: np.ndarray) -> np.ndarray:
    """``color`` refused outside [0, 1]: a build kept 8-bit colours (0..255) as white without
    a word. Light and emission may exceed 1; albedo reflects at most what arrives."""
    if color.size and (color.max() > 1.0 or color.min() < 0.0):
        low, high = float(color.min()), float(color.max())
        hint = (" (8-bit sRGB? give voxfield.scene.srgb_to_linear(values / 255))"
                if high <= 255.0 and low >= 0.0 and np.all(color == np.round(color)) else "")
        raise VoxfieldError(f"color is linear albedo in [0, 1], got values {low:g}..{high:g}"
                            f"{hint}")
    return color


def _checked_light(values: np.ndarray, what: str) -> np.ndarray:
    """Light (emission, a lit channel) refused below zero: such a scene built and saved, and
    its octree file was then refused on load (``svo.io``), where no light is negative."""
    if values.size and values.min() < 0.0:
        raise VoxfieldError(f"{what} is light, never negative, got values down to "
                            f"{float(values.min()):g}")
    return values


def compose(
    parts: Sequence[tuple[VoxelScene, Sequence[int]]], name: str = "composite"
) -> VoxelScene:
    """Place several scenes into one world, each at an integer offset; later parts win overlaps.

    Extra channels are kept only when every part has them; emission is zero where a part has none.
    """
    if not parts:
        raise VoxfieldError("compose needs at least one scene")
    for index, part in enumerate(parts):  # a bare scene failed to unpack, a TypeError
        if not (isinstance(part, tuple | list) and len(part) == 2
                and isinstance(part[0], VoxelScene)):
            raise VoxfieldError(f"compose takes (scene, offset) pairs; part {index} is "
                                f"{type(part).__name__}")
    moved = [scene.translated(offset) for scene, offset in parts]
    any_emission = any(s.emission is not None for s in moved)
    shared_channels = set(moved[0].channels)
    for s in moved[1:]:
        shared_channels &= set(s.channels)
    coords = np.concatenate([s.coords for s in moved])
    color = np.concatenate([s.color for s in moved])
    emission = None
    if any_emission:
        emission = np.concatenate(
            [s.emission if s.emission is not None else np.zeros_like(s.color) for s in moved]
        )
    channels = {k: np.concatenate([s.channels[k] for s in moved]) for k in sorted(shared_channels)}
    return VoxelScene(coords, color, emission, channels, name).dedupe()


def srgb_to_linear(srgb: np.ndarray) -> np.ndarray:
    """Decode sRGB-encoded values in [0, 1] (any shape) to linear [0, 1]."""
    c = np.asarray(srgb, dtype=np.float32)
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4).astype(np.float32)


def linear_to_srgb(linear: np.ndarray) -> np.ndarray:
    """Encode linear values in [0, 1] (any shape) as sRGB in [0, 1]."""
    c = np.clip(np.asarray(linear, dtype=np.float32), 0.0, 1.0)
    return np.where(c <= 0.0031308, c * 12.92, 1.055 * c ** (1 / 2.4) - 0.055).astype(np.float32)


def whole_offset(offset) -> np.ndarray:
    """``offset`` as three int64 voxel counts within ±2^61, or a VoxfieldError saying why."""
    try:
        values = np.asarray(offset)
        if values.dtype.kind not in "iuf" or values.size != 3:
            raise ValueError
        values = values.reshape(3)
    except ValueError:
        raise VoxfieldError(f"an offset must be three whole numbers, got {offset!r}") from None
    if not (np.all(np.isfinite(values)) and np.all(np.abs(values) <= MAX_COORDINATE)):
        raise VoxfieldError(f"an offset must be finite and within ±2^61 voxels, got "
                            f"{values.tolist()}")
    if values.dtype.kind == "f" and not np.array_equal(values, np.round(values)):
        raise VoxfieldError(f"an offset moves whole voxels, got {values.tolist()}")
    return values.astype(np.int64)
