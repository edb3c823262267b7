"""Voxel terrain from real elevation data (DEMs), with colours and scattered ``.vox`` assets.

Our stand-in for the EA thesis's production terrain (ch. 4: 2048³ voxels, 15–28M voxels per
area): real DEMs become a 2048×2048-column heightfield of solid voxels, coloured from an image
or a height/slope ramp, with trees and rocks from MagicaVoxel files standing on the surface.
One module per step, so tests can check one at a time::

    dem            load_heightmap ─► Heightmap      .hgt .tif .npz .npy, matplotlib samples
    resample       fill_voids, resample             void fill, DEM grid → footprint² columns
    columns        terrain_columns ─► TerrainColumns  integer top/bottom per column, slope
    ground_colours ColorRamp, image colours         surface colour per column
    asset_scatter  AssetGroup, place_assets         models standing on the columns
    layout         terrain_layout ─► TerrainLayout ─► VoxelScene (or streamed column blocks)
    recipes        RECIPES, recipe_layout, recipe_scene: the ``terrain:NAME`` scenes

Conventions: row 0 of a heightmap is its northern edge and column 0 its western edge. In the
voxel world a column ``(row, col)`` is ``(z, x) = (row, col)`` and heights run along +y, so
north is −z and east is +x (right-handed, y up). Heights are relative: the lowest filled voxel
is at y = 0.

The names below are re-exported so ``from voxfield.scene.terrain import X`` keeps working.
"""

from voxfield.scene.terrain.asset_scatter import (
    AssetGroup,
    Placements,
    downsample_scene,
    place_assets,
    poisson_disk,
)
from voxfield.scene.terrain.columns import MAX_FOOTPRINT, TerrainColumns, terrain_columns
from voxfield.scene.terrain.dem import (
    METRES_PER_DEGREE,
    SAMPLE_DEMS,
    GeoGrid,
    Heightmap,
    load_heightmap,
    read_geotiff,
    read_hgt,
    read_npz,
)
from voxfield.scene.terrain.ground_colours import ColorRamp
from voxfield.scene.terrain.layout import (
    MAX_TERRAIN_VOXELS,
    TerrainLayout,
    terrain_layout,
    terrain_scene,
)
from voxfield.scene.terrain.recipes import RECIPES, AssetSpec, Recipe, recipe_layout, recipe_scene
from voxfield.scene.terrain.resample import fill_voids, resample

__all__ = [
    "MAX_FOOTPRINT",
    "MAX_TERRAIN_VOXELS",
    "METRES_PER_DEGREE",
    "RECIPES",
    "SAMPLE_DEMS",
    "AssetGroup",
    "AssetSpec",
    "ColorRamp",
    "GeoGrid",
    "Heightmap",
    "Placements",
    "Recipe",
    "TerrainColumns",
    "TerrainLayout",
    "downsample_scene",
    "fill_voids",
    "load_heightmap",
    "place_assets",
    "poisson_disk",
    "read_geotiff",
    "read_hgt",
    "read_npz",
    "recipe_layout",
    "recipe_scene",
    "resample",
    "terrain_columns",
    "terrain_layout",
    "terrain_scene",
]
