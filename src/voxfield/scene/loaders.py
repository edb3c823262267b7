"""One entry point from a scene description (file path or ``builtin:NAME``) to a VoxelScene.

Descriptions: ``builtin:NAME`` (procedural), ``terrain:RECIPE`` (a documented terrain recipe
over the shared DEMs), ``dem:jacksboro`` / ``dem:topobathy`` (matplotlib's sample DEMs), or a
file: ``.vox``, ``.obj/.gltf/.glb/.ply`` (voxelized), ``.hgt/.tif/.tiff/.npy`` (DEM), ``.npz``
(a saved voxel scene, a saved octree, or a DEM array).
"""

from __future__ import annotations

import json
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from voxfield.array_files import load_arrays
from voxfield.error_table.table import FORMAT as ERROR_TABLE_FORMAT
from voxfield.error_table.table import LIGHTING_FORMAT
from voxfield.errors import DataNotFoundError, SceneFormatError, VoxfieldError
from voxfield.scene.builtin import builtin_scene
from voxfield.scene.mesh import MESH_SUFFIXES, load_mesh
from voxfield.scene.npz_io import load_scene_npz
from voxfield.scene.terrain.dem import load_heightmap
from voxfield.scene.terrain.layout import terrain_layout
from voxfield.scene.terrain.recipes import recipe_layout, recipe_scene
from voxfield.scene.vox import load_vox
from voxfield.scene.voxel_scene import VoxelScene
from voxfield.scene.voxelize import voxelize_mesh

DEM_SUFFIXES = (".hgt", ".tif", ".tiff", ".npy")  # .npy: a bare 2-D height array


@dataclass(frozen=True)
class SceneOptions:
    """How file formats without a native voxel size become voxels."""

    mesh_resolution: int = 256
    terrain_footprint: int = 512
    vertical_scale: float | None = None
    seed: int = 0
    #: How a DEM that is not square on the ground fills the square of columns: "stretch" or
    #: "crop" (its centred square); None stretches it with a note where that distorts it.
    dem_fit: str | None = None


#: The ``format`` a saved octree's header names (``svo.io.FORMAT``, a layer above this one).
OCTREE_FORMAT = "voxfield-octree"
#: The arrays of one probe of a baked probe set (``probes.probe_folder.write_probe``).
PROBE_FILE_ARRAYS = frozenset({"radiance", "distance", "normal", "record"})


def npz_kind(path: Path) -> str:
    """``octree``, ``scene`` or ``dem`` for a ``.npz`` file, by the arrays it holds. The
    other files voxfield writes as ``.npz`` are refused by name: taken for a DEM, a probe
    file's distance map (its one 2-D array) became a terrain without a word, and an error
    table was refused for lacking an elevation array."""
    try:
        with load_arrays(path) as data:
            files = set(data.files)
            written_as = _header_format(data) if "header" in files else None
    except Exception as exc:  # noqa: BLE001 - any failure here means "not a readable npz"
        raise SceneFormatError(f"{path}: not a readable .npz file ({exc})") from exc
    if written_as == OCTREE_FORMAT or (
            "header" in files and ("descriptors" in files or "child_mask" in files)):
        return "octree"  # the octree reader names what a damaged one lacks
    if written_as in (ERROR_TABLE_FORMAT, LIGHTING_FORMAT):
        raise SceneFormatError(f"{path}: a voxfield error table ({written_as}), not a scene; "
                               "`voxfield errors info --table FILE` describes it")
    if PROBE_FILE_ARRAYS <= files:
        raise SceneFormatError(f"{path}: one probe of a baked probe set (its radiance, "
                               "distance and normal maps), not a scene; give a scene, and "
                               "the probe set's folder where a command takes probes")
    if "coords" in files:
        return "scene"
    return "dem"


def _header_format(data) -> str | None:
    """The ``format`` named by a voxfield file's JSON header array; None where the array
    is no such header (a DEM may hold an array of that name)."""
    try:
        header = json.loads(np.asarray(data["header"], np.uint8).tobytes())
    except (ValueError, TypeError, UnicodeDecodeError, RecursionError):
        return None
    written_as = header.get("format") if isinstance(header, dict) else None
    return written_as if isinstance(written_as, str) else None


def load_scene(spec: str, options: SceneOptions | None = None) -> VoxelScene:
    """The VoxelScene a description names."""
    options = options or SceneOptions()
    if spec.startswith("builtin:"):
        return builtin_scene(spec.split(":", 1)[1])
    if spec.startswith("terrain:"):
        _no_vertical_scale(spec, options)
        return recipe_scene(spec.split(":", 1)[1], footprint=options.terrain_footprint)
    if spec.startswith("dem:"):
        return _terrain_from(spec.split(":", 1)[1], options)
    if not spec.strip():
        raise SceneFormatError("no scene named: give a scene file, builtin:NAME or "
                               "terrain:RECIPE")
    path = _scene_file(spec)
    suffix = path.suffix.lower()
    if suffix == ".vox":
        return load_vox(path)
    if suffix in MESH_SUFFIXES:
        return voxelize_mesh(load_mesh(path), resolution=options.mesh_resolution)
    if suffix in DEM_SUFFIXES:
        return _terrain_from(str(path), options)
    if suffix == ".npz":
        kind = npz_kind(path)
        if kind == "scene":
            return load_scene_npz(path)
        if kind == "octree":
            raise VoxfieldError(f"{path} is an octree, not a voxel scene; load it with load_octree")
        return _terrain_from(str(path), options)
    raise SceneFormatError(
        f"{path}: unknown scene format {suffix!r} (expected .vox, a mesh, a DEM or .npz)"
    )


def _scene_file(spec: str) -> Path:
    """The file a scene names: there, and a plain file (a pipe would wait for a writer for
    ever, ``/dev/zero`` fill the memory)."""
    path = Path(spec)
    if not path.exists():
        raise DataNotFoundError(f"{spec}: no such file (or use builtin:NAME, terrain:RECIPE)")
    if path.is_dir():
        raise SceneFormatError(f"{spec}: a folder, not a scene file")
    if not path.is_file():
        raise SceneFormatError(f"{spec}: a pipe, device or socket, not a scene file")
    return path


def _no_vertical_scale(spec: str, options: SceneOptions) -> None:
    """A recipe fixes its own height scale: a vertical scale given with one is refused rather
    than silently ignored."""
    if options.vertical_scale is not None:
        raise VoxfieldError(f"{spec} sets its own height scale; --vertical-scale applies to "
                            "DEM files and dem:NAME")
    if options.dem_fit is not None:
        raise VoxfieldError(f"{spec} sets its own extent; --dem-fit applies to DEM files and "
                            "dem:NAME")


def _terrain_from(source: str, options: SceneOptions) -> VoxelScene:
    return _terrain_layout(source, options).scene()


def _terrain_layout(source: str, options: SceneOptions):
    kwargs = {"footprint": options.terrain_footprint, "seed": options.seed,
              "fit": options.dem_fit or "stretch"}
    if options.vertical_scale is not None:
        kwargs["vertical_scale"] = options.vertical_scale
    heightmap = load_heightmap(source)
    layout = terrain_layout(heightmap, **kwargs)
    cols = layout.cols
    if options.dem_fit is None:
        _note_stretch(heightmap)
    if options.vertical_scale is not None and cols.scale_capped:
        # Asked for by name and not given: say so, as the picture alone would not.
        warnings.warn(f"{cols.name}: a vertical scale of {options.vertical_scale:g} would "
                      f"raise the relief above the {cols.footprint}³ cube; it was scaled down "
                      f"to fit ({cols.voxels_per_metre:.3g} voxels per metre)", stacklevel=2)
    if cols.flattened:
        # A vertical scale of 1e-300 built a flat slab without a word.
        scale = ("" if options.vertical_scale is None
                 else f" at a vertical scale of {options.vertical_scale:g}")
        warnings.warn(f"{cols.name}: its relief of {cols.relief_metres:.3g} m is less than "
                      f"a voxel tall{scale} ({cols.voxels_per_metre:.3g} voxels per metre): "
                      "every column has the same height; a larger --vertical-scale raises "
                      "it", stacklevel=2)
    return layout


#: How far a DEM's ground may be from square before stretching it earns a note.
STRETCH_NOTED = 1.10


def _note_stretch(heightmap) -> None:
    """Say so where square columns stretch the DEM's ground (an SRTM tile away from the
    equator is narrower east to west than north to south: 1.31× at 40°)."""
    north_south, east_west = heightmap.ground
    ratio = max(north_south, east_west) / min(north_south, east_west)
    if ratio > STRETCH_NOTED:
        unit = "m" if heightmap.spacing else "samples"
        stretched = "east to west" if east_west < north_south else "north to south"
        warnings.warn(f"{heightmap.name}: its ground is {east_west:,.0f} × {north_south:,.0f} "
                      f"{unit} (east × north), stretched {ratio:.2f}× {stretched} into square "
                      "columns; --dem-fit crop keeps its proportions (its centred square), "
                      "--dem-fit stretch this without the note", stacklevel=3)


def is_heightmap(spec: str) -> bool:
    """Whether ``spec`` names a terrain: a recipe, a DEM file or a DEM ``.npz``: scenes seen
    from above, where an object or a room is seen from the side."""
    return scene_kind(spec) in ("recipe", "dem")


#: What each kind of scene description is called in a note.
SCENE_KINDS = {
    "octree": "a saved octree", "scene": "a saved voxel scene", "builtin": "a built-in scene",
    "recipe": "a terrain recipe", "dem": "a DEM", "vox": "a MagicaVoxel scene",
    "mesh": "a mesh",
}


def scene_kind(spec: str) -> str | None:
    """Which of ``SCENE_KINDS`` a description names, by its prefix, suffix or (``.npz``)
    arrays; None where it names none of them (a missing file, an unknown suffix)."""
    if spec.startswith("builtin:"):
        return "builtin"
    if spec.startswith("terrain:"):
        return "recipe"
    if spec.startswith("dem:"):
        return "dem"
    path = Path(spec)
    suffix = path.suffix.lower()
    if not path.is_file():
        return None
    if suffix == ".npz":
        return npz_kind(path)
    if suffix in DEM_SUFFIXES:
        return "dem"
    if suffix == ".vox":
        return "vox"
    return "mesh" if suffix in MESH_SUFFIXES else None


def block_source(spec: str, options: SceneOptions | None = None):
    """The scene as column blocks (``svo.streamed_build.BlockSource``) where its format can
    deliver them without making every voxel first (terrains), else None."""
    options = options or SceneOptions()
    if spec.startswith("terrain:"):
        _no_vertical_scale(spec, options)
        return recipe_layout(spec.split(":", 1)[1], footprint=options.terrain_footprint)
    if spec.startswith("dem:"):
        return _terrain_layout(spec.split(":", 1)[1], options)
    if spec.strip() and Path(spec).exists():
        _scene_file(spec)  # a folder or a pipe is refused before its kind is read
    if scene_kind(spec) == "dem":
        return _terrain_layout(spec, options)
    return None
