"""Named terrains: ``RECIPES``, analogues of the EA thesis's four areas (desert, forest,
mountain, biomes; ch. 4), and ``recipe_layout`` / ``recipe_scene``, which build one from the
shared data folder (DEMs, colour images, ``.vox`` assets) at any footprint.

A recipe is declarative (which DEM and window, vertical scale, palette, assets sized relative
to the footprint), so ``terrain:NAME`` scenes mean the same thing at every size.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from voxfield.data import data_root as default_data_root
from voxfield.errors import DataNotFoundError, VoxfieldError
from voxfield.scene.terrain.asset_scatter import AssetGroup, downsample_scene
from voxfield.scene.terrain.columns import check_footprint
from voxfield.scene.terrain.dem import SAMPLE_DEMS, load_heightmap
from voxfield.scene.terrain.ground_colours import ColorRamp, linear_rgb
from voxfield.scene.terrain.layout import MAX_TERRAIN_VOXELS, TerrainLayout, terrain_layout
from voxfield.scene.vox import load_vox
from voxfield.scene.voxel_scene import VoxelScene


@dataclass(frozen=True)
class AssetSpec:
    """A ``.vox`` model to scatter in a recipe, sized relative to the footprint.

    ``height`` is the model's height as a fraction of the footprint (it picks an integer
    downsampling), ``spacing`` is in model widths, ``color`` (sRGB) repaints the model (e.g.
    a single-colour rock), ``embed`` sinks it by that fraction of its height.
    """

    file: str
    height: float
    density: float
    spacing: float = 1.0
    max_slope: float = 1.0
    height_range: tuple[float, float] = (0.0, 1.0)
    clumping: float = 0.0
    embed: float = 0.0
    color: tuple[float, float, float] | None = None


@dataclass(frozen=True)
class Recipe:
    """A declarative terrain: which DEM, which part, how tall, how coloured, what grows on it."""

    description: str
    dem: str
    window: tuple[float, float, float, float] = (0.0, 1.0, 0.0, 1.0)
    vertical_scale: float = 1.0
    fill_depth: int = 4
    ramp: ColorRamp = field(default_factory=ColorRamp)
    colors: str = "ramp"
    sea_level: float | None = None
    fit: str = "stretch"
    assets: tuple[AssetSpec, ...] = ()


_PINE = "PineFluffy.vox"  # a 128-voxel pine (trunk and foliage are two models in one group)
_ROCK = "nature.vox"  # a 120×60×120 cave-riddled noise block: repainted, it is a rock outcrop

RECIPES: dict[str, Recipe] = {
    "desert": Recipe(
        description=(
            "Smooth basins and plateaus (topobathy, coarse data upsampled ~20×, sea floor kept "
            "as dry basins), sand ramp with strong texture noise, a few isolated pines plus one "
            "clumped grove, scattered rock outcrops. EA ch. 4.1."
        ),
        dem="topobathy",
        fit="crop",
        vertical_scale=6.0,
        fill_depth=3,
        ramp=ColorRamp(
            low=(0.80, 0.66, 0.45),
            mid=(0.86, 0.74, 0.52),
            high=(0.76, 0.60, 0.42),
            rock=(0.62, 0.44, 0.32),
            earth=(0.55, 0.38, 0.25),
            snow_line=1.1,
            rock_slope=1.2,
            noise=0.12,
            jitter=0.06,
        ),
        assets=(
            AssetSpec(_PINE, height=1 / 32, density=0.03, clumping=1.0, max_slope=0.6),
            AssetSpec(
                _ROCK,
                height=1 / 96,
                density=0.015,
                embed=0.3,
                max_slope=2.0,
                color=(0.60, 0.45, 0.33),
            ),
        ),
    ),
    "forest": Recipe(
        description=(
            "Dissected Appalachian ridges and valleys (jacksboro, ~15 m/voxel), dense pines on "
            "all but the steepest slopes and highest ridges, exposed rock on cliffs, a dusting "
            "of snow on the highest ground. EA ch. 4.2."
        ),
        dem="jacksboro",
        vertical_scale=3.0,
        fill_depth=3,
        ramp=ColorRamp(
            mid=(0.22, 0.36, 0.14), high=(0.36, 0.38, 0.24), snow_line=0.92, rock_slope=1.3
        ),
        assets=(
            AssetSpec(
                _PINE,
                height=1 / 32,
                density=0.9,
                spacing=0.8,
                max_slope=1.2,
                height_range=(0.0, 0.9),
            ),
        ),
    ),
    "mountain": Recipe(
        description=(
            "The Japanese Northern Alps (dem_srtm30, north-west window), steep and tall, rock "
            "and snow above a tree line, pines at medium density below it, rock outcrops. "
            "EA ch. 4.3."
        ),
        dem="terrain/dem_srtm30.tif",
        window=(0.0, 0.5, 0.05, 0.55),
        vertical_scale=9.0,
        fill_depth=4,
        ramp=ColorRamp(
            mid=(0.28, 0.38, 0.18),
            high=(0.45, 0.43, 0.36),
            snow_line=0.55,
            rock_slope=1.4,
            snow_max_slope=2.5,
            jitter=0.08,
        ),
        assets=(
            AssetSpec(
                _PINE,
                height=1 / 32,
                density=0.45,
                max_slope=1.5,
                height_range=(0.0, 0.5),
                clumping=0.5,
            ),
            AssetSpec(
                _ROCK,
                height=1 / 96,
                density=0.02,
                embed=0.3,
                max_slope=3.0,
                color=(0.45, 0.43, 0.41),
            ),
        ),
    ),
    "biomes": Recipe(
        description=(
            "Central Japan from the sea to Mt Fuji (dem_srtm30 under the SRTM3 shaded-relief "
            "image, laid on by position): sea, plains, forests, mountains and snow in one "
            "scene, pines in clumps on low and middle ground. EA ch. 4.4."
        ),
        dem="terrain/dem_srtm30.tif",
        window=(0.2, 1.0, 0.1, 0.9),
        vertical_scale=5.0,
        fill_depth=2,
        colors="terrain/shadedrelief_srtm3.tif",
        sea_level=0.5,
        assets=(
            AssetSpec(
                _PINE,
                height=1 / 32,
                density=0.6,
                clumping=0.8,
                max_slope=1.2,
                height_range=(0.02, 0.5),
            ),
        ),
    ),
}



def _thesis_regime(name: str, vertical_scale: float, fill_depth: int, tree_colour, *,
                   density: float = 1.0) -> Recipe:
    """The recipe ``name`` in the EA thesis's colour regime (its Table 4.1 and §5.2): the
    buried voxels carry the surface colour, colour is smooth over about four columns (no
    per-column noise or ragged band edges), columns hold 3.5-6.7 voxels on average, and the
    trees are repainted close to the ground they stand on (low-contrast vegetation)."""
    base = RECIPES[name]
    ramp = replace(base.ramp, noise=0.0, jitter=0.0, smoothing=2.0, earth=None)
    assets = tuple(
        replace(a, color=tree_colour if a.file == _PINE else a.color,
                density=a.density * density)
        for a in base.assets
    )
    return replace(
        base, description=f"The {name} recipe in the EA thesis's smooth-colour regime (its Table "
        "4.1): colour smooth over about four columns with no per-column noise, buried voxels "
        "in the surface colour, trees painted close to the ground they stand on.",
        vertical_scale=vertical_scale, fill_depth=fill_depth, ramp=ramp, assets=assets,
    )


#: The thesis-regime variants; the four above stay as the hard-colour set.
RECIPES.update({
    "desert-smooth": _thesis_regime("desert", 6.0, 3, (0.70, 0.60, 0.42), density=0.5),
    "forest-smooth": _thesis_regime("forest", 3.0, 2, (0.22, 0.33, 0.14)),
    "mountain-smooth": _thesis_regime("mountain", 9.0, 3, (0.26, 0.35, 0.17)),
    "biomes-smooth": _thesis_regime("biomes", 5.0, 3, (0.24, 0.34, 0.16)),
})

def _asset_models(spec: AssetSpec, root: Path, footprint: int) -> list[VoxelScene]:
    """The model of one AssetSpec, loaded, repainted and downsampled to its footprint size."""
    model = load_vox(_data_file(root, "vox", spec.file))
    factor = max(1, int(round(model.extent[1] / max(spec.height * footprint, 1.0))))
    model = downsample_scene(model, factor).normalized()
    if spec.color is not None:
        # Repaint with a little height shading so a one-colour model still reads as a shape.
        shade = 0.75 + 0.25 * model.coords[:, 1:2] / max(int(model.extent[1]) - 1, 1)
        color = np.clip(linear_rgb(spec.color) * shade, 0, 1)
        model = VoxelScene(model.coords, color, name=model.name)
    return [model]


def _data_file(root: Path, *parts: str) -> Path:
    path = root.joinpath(*parts)
    if not path.exists():
        raise DataNotFoundError(
            f"{path} does not exist: this recipe's assets come from the shared data "
            "folder; point VOXFIELD_DATA at it"
        )
    return path


def recipe_scene(
    name: str, footprint: int = 2048, data_root=None, seed: int = 0,
    max_voxels: int = MAX_TERRAIN_VOXELS, **overrides
) -> VoxelScene:
    """The terrain a named recipe describes (``desert``, ``forest``, ``mountain``, ``biomes``).

    DEMs and images come from ``data_root`` (default ``voxfield.data.data_root()``) or from
    matplotlib's samples; ``overrides`` go to ``terrain_layout`` (e.g. ``fill_depth=1``).
    """
    return recipe_layout(name, footprint, data_root, seed, **overrides).scene(max_voxels)


def recipe_layout(
    name: str, footprint: int = 2048, data_root=None, seed: int = 0, **overrides
) -> TerrainLayout:
    """The layout of a recipe's terrain (``recipe_scene`` without making the voxels)."""
    recipe = RECIPES.get(name)
    if recipe is None:
        raise VoxfieldError(f"unknown terrain recipe {name!r}; choose one of {', '.join(RECIPES)}")
    footprint = check_footprint(footprint)
    if data_root is None:
        data_root = default_data_root()
    root = Path(data_root)
    dem = recipe.dem if recipe.dem in SAMPLE_DEMS else _data_file(root, recipe.dem)
    hm = load_heightmap(dem).window(*recipe.window)
    groups = []
    for spec in recipe.assets:
        models = _asset_models(spec, root, footprint)
        width = max(int(max(m.extent[0], m.extent[2])) for m in models)
        height = max(int(m.extent[1]) for m in models)
        groups.append(
            AssetGroup(
                models=models,
                density=spec.density,
                spacing=max(1.0, spec.spacing * width),
                max_slope=spec.max_slope,
                height_range=spec.height_range,
                clumping=spec.clumping,
                embed=int(round(spec.embed * height)),
            )
        )
    colors = recipe.colors if recipe.colors == "ramp" else _data_file(root, recipe.colors)
    kwargs = dict(
        vertical_scale=recipe.vertical_scale,
        fill_depth=recipe.fill_depth,
        colors=colors,
        ramp=recipe.ramp,
        seed=seed,
        assets=groups or None,
        sea_level=recipe.sea_level,
        fit=recipe.fit,
        name=f"terrain:{name}",
    )
    kwargs.update(overrides)
    return terrain_layout(hm, footprint, **kwargs)
