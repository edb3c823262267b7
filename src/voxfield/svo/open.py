"""One door to an octree: a saved octree file is loaded, any other scene description is read
and built (terrains streamed in column blocks, so their build stays in bounded memory)."""

from __future__ import annotations

import os
from pathlib import Path

from voxfield.errors import VoxfieldError
from voxfield.scene.loaders import SceneOptions, block_source, load_scene, npz_kind
from voxfield.svo.build import build_octree
from voxfield.svo.io import load_octree
from voxfield.svo.lod_colours import DEFAULT_LOD_COLOUR, apply_lod_colour
from voxfield.svo.octree import Octree
from voxfield.svo.streamed_build import build_octree_streamed


def open_octree(spec: str | os.PathLike, options: SceneOptions | None = None, *,
                progress: bool = False, lod_colour: str = DEFAULT_LOD_COLOUR,
                colour_storage: str = "srgb8") -> Octree:
    """An octree from a saved octree file, or built from any scene description (a path, or
    ``builtin:NAME`` and the like; inner-node colours by ``lod_colour``, see
    ``svo.lod_colours``, albedo kept as ``colour_storage``; a saved octree keeps its own)."""
    if not isinstance(spec, (str, os.PathLike)):
        raise VoxfieldError(f"a scene is a path or a name such as builtin:sphere, got "
                            f"{type(spec).__name__}")
    spec = os.fspath(spec)
    path = Path(spec)
    if path.suffix.lower() == ".npz" and path.is_file() and npz_kind(path) == "octree":
        return load_octree(path)
    # Terrains arrive in column blocks: built streamed, in bounded memory (same octree).
    source = block_source(spec, options)
    if source is not None:
        return apply_lod_colour(
            build_octree_streamed(source, progress=progress, colour_storage=colour_storage),
            lod_colour)
    return build_octree(load_scene(spec, options), progress=progress,
                        lod_colour=lod_colour, colour_storage=colour_storage)
