"""Voxel scenes as ``.npz`` (coords, color, optional emission and channels), written atomically."""

from __future__ import annotations

import os
import warnings
from pathlib import Path

import numpy as np

from voxfield.array_files import load_arrays
from voxfield.atomic import atomic_path, named_for
from voxfield.errors import SceneFormatError, VoxfieldError
from voxfield.scene.voxel_scene import VoxelScene


def save_scene(scene: VoxelScene, path: str | os.PathLike) -> Path:
    path = named_for(path, ".npz", "save_scene")
    arrays = {"coords": scene.coords.astype(np.int32), "color": scene.color}
    if scene.emission is not None:
        arrays["emission"] = scene.emission
    for name, values in scene.channels.items():
        arrays[f"channel_{name}"] = values
    with atomic_path(path) as tmp, open(tmp, "wb") as f:
        np.savez_compressed(f, **arrays)
    return path


def load_scene_npz(path: str | os.PathLike) -> VoxelScene:
    path = Path(path)
    try:
        with load_arrays(path) as data:
            if "coords" not in data or "color" not in data:
                raise SceneFormatError(f"{path}: a voxel-scene .npz needs 'coords' and 'color'")
            emission = data["emission"] if "emission" in data else None
            prefix = "channel_"
            channels = {k[len(prefix):]: data[k] for k in data.files if k.startswith(prefix)}
            scene = VoxelScene(data["coords"], data["color"], emission, channels, path.stem)
    except SceneFormatError:
        raise
    except VoxfieldError as exc:  # the arrays' own checks: say which file they came from
        raise SceneFormatError(f"{path}: {exc}") from exc
    except Exception as exc:  # noqa: BLE001 - zip/zlib fail in many ways on a bad file
        raise SceneFormatError(f"{path}: unreadable voxel-scene file ({exc})") from exc
    return _one_voxel_per_position(scene, path)


def _one_voxel_per_position(scene: VoxelScene, path: Path) -> VoxelScene:
    """The scene with repeated positions merged, the last listed kept, as the other readers
    resolve overlaps (``.vox``, ``compose``); with a note, as ``save_scene`` never writes a
    repeat: the file came from elsewhere and may not mean what it shows."""
    unique = scene.dedupe()
    repeats = len(scene) - len(unique)
    if repeats:
        repeat = "repeats a position" if repeats == 1 else "repeat positions"
        warnings.warn(f"{path}: {repeats:,} of its {len(scene):,} voxels {repeat} listed "
                      "earlier in the file; the last listed at each position was kept",
                      stacklevel=3)
    return unique
