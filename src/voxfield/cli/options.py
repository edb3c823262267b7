"""Options shared by the commands: argument types, the scene, view and renderer option
groups, and turning parsed arguments into an octree, a camera and an output path.

Renderer options are generated from each renderer's options dataclass (``render.registry``),
so a default or a help text is written once, beside the renderer.
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import re
import warnings
from pathlib import Path

import numpy as np

from voxfield.atomic import check_writable
from voxfield.checks import MAX_SEED, spoken_list
from voxfield.cli.commands import add_quiet
from voxfield.errors import VoxfieldError
from voxfield.kernels.colour import SRGB8, decode_channel, storage_of
from voxfield.lightfield.trace import (
    COLOUR_PROBES,
    EPSILON_MODES,
    EPSILON_READERS,
    LightFieldOptions,
)
from voxfield.memory import check_fits_in_memory
from voxfield.metrics import SSIM_WINDOW
from voxfield.render.camera import (
    CAMERA_PRESETS,
    MAX_IMAGE_SIDE,
    MIN_FOV_DEG,
    Camera,
    preset_camera,
)
from voxfield.render.framing import content_box
from voxfield.render.placement import check_camera_placement, one_colour_view_note
from voxfield.render.registry import RENDERERS
from voxfield.scaleout import SCHEDULER_HELP, check_scheduler
from voxfield.scene.loaders import SCENE_KINDS, SceneOptions, is_heightmap, scene_kind
from voxfield.scene.terrain.columns import DEM_FITS, MAX_FOOTPRINT, MIN_FOOTPRINT
from voxfield.svo.lod_colours import DEFAULT_LOD_COLOUR, LOD_COLOURS
from voxfield.svo.open import open_octree as open_octree_from_spec

# --------------------------------------------------------------------------- argument types


#: The largest coordinate ``--eye``/``--target``/``--box-min`` take, in voxels: a billion
#: times a 1,024-voxel scene's side. Beyond some such bound the camera's vectors overflow
#: (``--eye 1e308,1e308,1e308`` printed NumPy's overflow warnings and wrote an empty image).
MAX_COORDINATE = 1e12


def vector_arg(text: str) -> tuple[float, float, float]:
    """Three comma-separated finite numbers, ``1,2,3``, each within ``MAX_COORDINATE``."""
    try:
        values = tuple(float(v) for v in text.split(","))
    except ValueError:
        values = ()
    if len(values) != 3:
        raise argparse.ArgumentTypeError(f"expected three numbers like 1,2,3, got {text!r}")
    if not all(math.isfinite(v) and abs(v) <= MAX_COORDINATE for v in values):
        raise argparse.ArgumentTypeError(f"expected finite coordinates within ±{MAX_COORDINATE:g} "
                                         f"voxels, got {text!r}")
    return values


def lod_arg(text: str) -> int | None:
    """A LOD number (0 = voxels) or 'cone' (None: chosen from the pixel footprint)."""
    if text == "cone":
        return None
    try:
        value = int(text)
    except ValueError:
        message = f"expected a LOD (0, 1, 2, ...) or 'cone', got {text!r}"
        raise argparse.ArgumentTypeError(message) from None
    if value < 0:
        raise argparse.ArgumentTypeError(f"a LOD is 0 or more, got {value}")
    return value


def int_at_least(low: int):
    """An argparse type: a whole number no smaller than ``low``."""
    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected a whole number, got {text!r}") from None
        if value < low:
            raise argparse.ArgumentTypeError(f"expected {low} or more, got {text!r}")
        return value

    return parse


positive_int = int_at_least(1)


def int_between(low: int, high: int, why: str = ""):
    """An argparse type: a whole number in ``low..high`` (``why`` says where the top comes
    from, for the message)."""
    def parse(text: str) -> int:
        value = int_at_least(low)(text)
        if value > high:
            reason = f" ({why})" if why else ""
            raise argparse.ArgumentTypeError(f"expected at most {high:,}{reason}, got {text!r}")
        return value

    return parse


def finite_float(text: str) -> float:
    """A number that is neither NaN nor infinite."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"expected a finite number, got {text!r}")
    return value


def positive_float(text: str) -> float:
    """A finite number above zero."""
    value = finite_float(text)
    if not value > 0.0:
        raise argparse.ArgumentTypeError(f"expected a number above 0, got {text!r}")
    return value


def non_negative_float(text: str) -> float:
    """A finite number of at least zero: a weight (the error-aware decay)."""
    value = finite_float(text)
    if not value >= 0.0:
        raise argparse.ArgumentTypeError(f"expected a number of at least 0, got {text!r}")
    return value


def non_negative_or_inf(text: str) -> float:
    """A number of at least zero, or ``inf`` (a cap that is off)."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not value >= 0.0:  # NaN too
        raise argparse.ArgumentTypeError(f"expected a number of at least 0 or inf, got "
                                         f"{text!r}")
    return value


def threshold_arg(text: str) -> float:
    """An error-aware threshold: any number but NaN (inf never refines, a negative one
    refines everywhere, as 0 does where a node's error is not zero)."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if math.isnan(value):
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}")
    return value


def fov_arg(text: str) -> float:
    """A field of view from ``MIN_FOV_DEG`` to below 180 degrees."""
    value = finite_float(text)
    if not MIN_FOV_DEG <= value < 180.0:
        raise argparse.ArgumentTypeError(
            f"a field of view is at least {MIN_FOV_DEG} and below 180 degrees, got {text!r}")
    return value


#: Seeds feed 32-bit hashes (``checks.MAX_SEED``): larger values would silently wrap, so
#: they are refused.
seed_arg = int_between(0, MAX_SEED, "seeds are 32-bit")
#: Size bound, from memory and time on a workstation: a mesh voxelized at N voxels a side
#: keeps about 6·N² surface voxels (16 bytes each while building). Images: the camera's own.
MAX_MESH_RESOLUTION = 8192


def distinct(values: tuple, text: str) -> tuple:
    """``values`` (parsed from ``text``) when none repeats: a study's knob given twice
    renders the same row twice and, in a curve, passes for two points that are one."""
    seen = set()
    for value in values:
        if value in seen:
            raise argparse.ArgumentTypeError(f"{value} is given twice in {text!r}")
        seen.add(value)
    return values


def float_list(text: str) -> tuple[float, ...]:
    """Comma-separated numbers, at least one, each once; infinity is a number here (a
    threshold nothing passes), NaN is not."""
    try:
        values = tuple(float(v) for v in text.split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected numbers like 0.1,0.2, got {text!r}") from None
    if any(math.isnan(v) for v in values):
        raise argparse.ArgumentTypeError(f"expected numbers, got NaN in {text!r}")
    return distinct(values, text)


def non_negative_float_list(text: str) -> tuple[float, ...]:
    """``float_list`` of finite numbers of at least zero (decays, weights)."""
    values = float_list(text)
    if any(not (math.isfinite(v) and v >= 0.0) for v in values):
        raise argparse.ArgumentTypeError(
            f"expected finite numbers of at least 0, got {text!r}")
    return values


def positive_int_list(text: str) -> tuple[int, ...]:
    """Comma-separated positive whole numbers (sizes, resolutions), each once."""
    try:
        values = tuple(int(v) for v in text.split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected sizes like 128,256, got {text!r}") from None
    if any(v < 1 for v in values):
        raise argparse.ArgumentTypeError(f"sizes must be positive, got {text!r}")
    return distinct(values, text)


def image_side_list(text: str) -> tuple[int, ...]:
    """``positive_int_list`` of image sides, each at most ``MAX_IMAGE_SIDE``: a study asked
    for a side no camera takes loaded its scene before the camera refused it."""
    values = positive_int_list(text)
    if max(values) > MAX_IMAGE_SIDE:
        raise argparse.ArgumentTypeError(
            f"image sides must be at most {MAX_IMAGE_SIDE:,}, got {text!r}")
    return values


def name_list(text: str) -> tuple[str, ...]:
    """Comma-separated names, at least one, each once; blanks between commas dropped."""
    values = tuple(v.strip() for v in text.split(",") if v.strip())
    if not values:
        raise argparse.ArgumentTypeError(f"expected names like a,b, got {text!r}")
    return distinct(values, text)


#: argparse types named by a renderer option's ``metadata["type"]``.
_FIELD_TYPES = {"lod": lod_arg, "positive": positive_int, "positive_float": positive_float,
                "non_negative_float": non_negative_float, "threshold": threshold_arg}


# --------------------------------------------------------------------------- option groups


def add_scene_options(p: argparse.ArgumentParser) -> None:
    """The scene argument and how to read and build it."""
    p.add_argument(
        "scene",
        help="scene: a .vox/.obj/.gltf/.glb/.ply/.hgt/.tif/.npy/.npz file, builtin:NAME, "
        "terrain:RECIPE or dem:jacksboro/dem:topobathy (see `voxfield scenes`)",
    )
    p.add_argument("--mesh-resolution", default=256, metavar="N",
                   type=int_between(1, MAX_MESH_RESOLUTION, "about 6·N² surface voxels"),
                   help=f"voxels along a mesh's longest side, 1..{MAX_MESH_RESOLUTION} "
                   "(default 256)")
    p.add_argument("--footprint", default=512, metavar="N",
                   type=int_between(MIN_FOOTPRINT, MAX_FOOTPRINT, "a terrain's largest footprint"),
                   help=f"terrain footprint in voxels per side, {MIN_FOOTPRINT}..{MAX_FOOTPRINT} "
                   "(default 512)")
    p.add_argument("--vertical-scale", type=positive_float, default=None, metavar="S",
                   help="DEM height multiplier, > 0 (default: true scale; terrain:RECIPE "
                   "scenes set their own)")
    p.add_argument("--dem-fit", choices=DEM_FITS, default=None,
                   help="a DEM not square on the ground: stretch it into the square of "
                   "columns, or crop its centred square (default: stretch, with a note where "
                   "that distorts it by more than 10%%)")
    p.add_argument("--seed", type=seed_arg, default=0,
                   help=f"seed for sampling and scattering, 0..{MAX_SEED} (default 0)")
    p.add_argument("--colour-storage", choices=("srgb8", "float32"), default="srgb8",
                   help="how a built octree keeps its colours: compact (default; albedo as "
                   "8-bit sRGB, 3 bytes a node, and lit colours from `voxfield light` as "
                   "shared-exponent RGB9E5, 4 bytes) or float32, 12 bytes each")
    p.add_argument("--lod-colour", choices=LOD_COLOURS, default=DEFAULT_LOD_COLOUR,
                   help="inner-node colours: facing (default; per node the colour seen along each "
                   "axis, read by ray direction: hidden interiors never show), surface (mean of "
                   "the voxels weighted by exposed faces) or mean (of the children, as the EA "
                   "thesis)")


def add_channel_option(p: argparse.ArgumentParser) -> None:
    p.add_argument("--channel", default="albedo",
                   help="colour channel: albedo or a baked time of day (`voxfield light`)")


class _ChosenView(argparse.Action):
    """Stores ``--camera`` and notes that it was given: a preset given beside --eye/--target
    is a contradiction to refuse, a command's default preset is not."""

    def __call__(self, parser, namespace, values, option_string=None) -> None:
        setattr(namespace, self.dest, values)
        namespace.camera_given = True


def add_display_options(p: argparse.ArgumentParser) -> None:
    """``--shade`` / ``--albedo``: whether the written picture is lit for display."""
    look = p.add_mutually_exclusive_group()
    look.add_argument("--shade", action="store_true",
                      help="light the colours with a fixed key light, EXR too (default for "
                      "albedo PNGs; display only, never used by metrics)")
    look.add_argument("--albedo", action="store_true",
                      help="write the flat colour channel the metrics compare, PNG too (EXR "
                      "default)")


def display_shaded(args, out: Path, channel: str) -> bool:
    """Whether a picture written to ``out`` is lit for display (``add_display_options``):
    asked for, or an albedo PNG not asked to stay flat. Baked light channels are lit
    already: only the albedo gets the display light unasked."""
    return args.shade or (out.suffix.lower() == ".png" and not args.albedo
                          and channel == "albedo")


def add_view_options(p: argparse.ArgumentParser, size: int = 512, camera: str = "auto",
                     auto_view: str | None = None) -> None:
    """Camera and image options shared by every command that renders, plus --quiet; the
    command's own default view is said in the help it prints (``auto_view``: what ``auto``
    means for this command, if not ``AUTO_VIEW``)."""
    described = (auto_view or AUTO_VIEW) if camera == "auto" else CAMERA_PRESETS[camera][1]
    p.add_argument("--camera", default=camera, action=_ChosenView,
                   help=f"preset view: {', '.join(_preset_names(camera == 'auto'))} (default "
                   f"{camera}: {described})")
    p.add_argument("--eye", type=vector_arg, default=None, metavar="X,Y,Z",
                   help="pinhole eye position in octree voxel units (with --target)")
    p.add_argument("--target", type=vector_arg, default=None, metavar="X,Y,Z")
    p.add_argument("--fov", type=fov_arg, default=None,
                   help=f"vertical field of view in degrees, {MIN_FOV_DEG} to below 180")
    p.add_argument("--size", type=int_between(1, MAX_IMAGE_SIDE, "pixels a side"),
                   default=size, help=f"image width = height, 1..{MAX_IMAGE_SIDE} "
                   f"(default {size})")
    add_quiet(p)


def _preset_names(auto: bool = False) -> list[str]:
    names = [n for n in CAMERA_PRESETS if not n.startswith("cube")]
    return [*(["auto"] if auto else []), *names, "cube+x..cube-z"]


#: ``--camera auto``: the view a scene of its kind is looked at from.
AUTO_VIEW = "top for a terrain or DEM (the EA thesis's view), orbit for an object or a room"


def auto_preset(scene: str, octree=None) -> str:
    """The preset ``--camera auto`` means for ``scene``, or for the scene a saved octree was
    built from (its name: ``build terrain:desert --out t.npz`` keeps ``terrain:desert``)."""
    names = [scene, str(getattr(octree, "name", "") or "")]
    return "top" if any(name and is_heightmap(name) for name in names) else "orbit"


def add_study_folder(p: argparse.ArgumentParser, prefix: str, cached: str = "items", *,
                     scheduled: bool = False) -> None:
    """``--out`` (the study folder, ``out/PREFIX_SCENE`` by default) and ``--fresh``: every
    resumable study reuses what its folder holds unless told to start over. ``scheduled``
    studies also take ``--scheduler``: their independent items run as tasks (``scaleout``)."""
    p.add_argument("--out", default=None,
                   help=f"output folder (default out/{prefix}_SCENE, SCENE from the scene)")
    p.add_argument("--fresh", action="store_true", help=f"ignore cached {cached} in --out")
    if scheduled:
        p.add_argument("--scheduler", type=scheduler_name, default=None, metavar="WHERE",
                       help=f"{SCHEDULER_HELP}; the {cached} run as tasks, each cached as it "
                       "lands (default: one after another here, each on every core)")


def scheduler_name(text: str) -> str:
    """A ``--scheduler`` value, checked before any work starts."""
    try:
        check_scheduler(text)
    except VoxfieldError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from exc
    return text


def add_threshold_options(p: argparse.ArgumentParser) -> None:
    """The error-aware threshold and decay, for studies that fix the rest."""
    add_renderer_options(p, ("error-aware",), only=("threshold", "decay"), prefix=False)


class Given(argparse.Action):
    """Store the value and remember (``given_options``) that the option was on the command
    line. Notes on options a choice ignores ask whether the user gave one, not whether its
    value differs from the default: ``--renderer lod --samples 4`` (4 being the default) was
    ignored without a word, ``--samples 5`` noted."""

    def __call__(self, parser, namespace, values, option_string=None):
        setattr(namespace, self.dest, values)
        namespace.given = given_options(namespace) | {self.dest}


def given_options(args) -> frozenset[str]:
    """The destinations of the ``Given`` options on the command line."""
    return getattr(args, "given", frozenset())


def add_renderer_options(p: argparse.ArgumentParser, renderers, *, only=None,
                         prefix: bool = True) -> None:
    """One option per field of the named renderers' options dataclasses (fields marked
    ``cli: False`` excepted). A field shared by several renderers becomes one option whose
    help names them all; ``prefix`` starts each help with the renderers it applies to."""
    by_flag: dict[str, tuple[dataclasses.Field, list[str]]] = {}
    for name in renderers:
        for f in dataclasses.fields(RENDERERS[name].options_type):
            if f.metadata.get("cli", True) is False or (only and f.name not in only):
                continue
            flag = _flag(f)
            if flag in by_flag:
                by_flag[flag][1].append(name)
            else:
                by_flag[flag] = (f, [name])
    for flag, (f, names) in by_flag.items():
        text = f.metadata.get("help", "")
        if "default" not in text and f.type not in ("bool",) and f.default is not None:
            text = f"{text} (default {f.default})"
        if prefix:
            text = f"{'/'.join(names)}: {text}"
        kwargs = {"dest": f.name, "default": f.default, "help": text}
        if f.type == "bool":
            p.add_argument(flag, action="store_true", **kwargs)
            continue
        if "choices" in f.metadata:
            kwargs["choices"] = f.metadata["choices"]
        kwargs["type"] = _FIELD_TYPES.get(f.metadata.get("type"), _python_type(f.type))
        kwargs["metavar"] = flag[2:].upper().replace("-", "_")
        p.add_argument(flag, action=Given, **kwargs)


def _flag(f: dataclasses.Field) -> str:
    """The command-line flag of a renderer options field."""
    return f.metadata.get("flag", "--" + f.name.replace("_", "-"))


def warn_ignored(ignored: dict[str, list[str]], what: str, *, verb: str = "takes no") -> None:
    """A note naming options given that ``what`` does not take, and who does."""
    parts = [f"{flag} (for {'/'.join(users)})" for flag, users in ignored.items()]
    warnings.warn(f"{what} {verb} {', '.join(parts)}; ignored", stacklevel=3)


def _python_type(annotation: str):
    """The argparse type of an options field from its (string) annotation."""
    head = annotation.split("|")[0].strip()
    return {"int": int, "float": float, "str": str}[head]


def renderer_options_from(args, renderer: str):
    """The named renderer's options dataclass filled from parsed arguments; a note names
    the options given that only other renderers take (``--reuse-parent`` with the
    reference renderer did nothing without a word)."""
    options_type = RENDERERS[renderer].options_type
    # A field the command line does not set (the LOD renderer's CMJ side) is not its own.
    own = {f.name for f in dataclasses.fields(options_type)
           if f.metadata.get("cli", True) is not False}
    ignored: dict[str, list[str]] = {}
    given = given_options(args)
    for other, spec in RENDERERS.items():
        for f in dataclasses.fields(spec.options_type):
            if (f.name not in own and f.metadata.get("cli", True) is not False
                    and f.default is not dataclasses.MISSING and hasattr(args, f.name)
                    and (f.name in given or getattr(args, f.name) != f.default)):
                ignored.setdefault(_flag(f), []).append(other)
    if ignored:
        warn_ignored(ignored, f"the {renderer} renderer")
    values = {f.name: getattr(args, f.name) for f in dataclasses.fields(options_type)
              if f.metadata.get("cli", True) is not False and hasattr(args, f.name)}
    options = options_type(**values)
    note_options_read_only_with_others(options, renderer, given)
    return options


def note_options_read_only_with_others(options, renderer: str,
                                       given: frozenset[str] = frozenset()) -> None:
    """A note naming options given that this renderer reads only with another setting
    (``read_when`` in the field's metadata: a ``(condition, setting)`` pair, or a tuple of
    them all of which must hold, the first unmet one named): ``--bright-ratio`` without
    ``--lighting-aware`` changed nothing, without a word."""
    flags_by_setting: dict[str, list[str]] = {}
    for f in dataclasses.fields(options):
        read_when = f.metadata.get("read_when")
        if read_when is None or (getattr(options, f.name) == f.default
                                 and f.name not in given):  # given at its default: noted
            continue
        conditions = (read_when,) if callable(read_when[0]) else read_when
        unmet = next((setting for condition, setting in conditions
                      if not condition(options)), None)
        if unmet is not None:
            flags_by_setting.setdefault(unmet, []).append(_flag(f))
    if flags_by_setting:
        unread = [f"{spoken_list(flags)} only with {setting}"
                  for setting, flags in flags_by_setting.items()]
        warnings.warn(f"the {renderer} renderer reads {', '.join(unread)}; ignored",
                      stacklevel=3)


# --------------------------------------------------------------------------- arguments → objects


def scene_options(args) -> SceneOptions:
    return SceneOptions(
        mesh_resolution=args.mesh_resolution, terrain_footprint=args.footprint,
        vertical_scale=args.vertical_scale, seed=args.seed,
        dem_fit=getattr(args, "dem_fit", None),
    )


def open_octree(args, *, note_unread: bool = True):
    """The octree the scene options name: loaded from a file or built (streamed for
    terrains), with a progress bar unless --quiet; a note names the build options given
    that this scene does not read (unless ``note_unread`` is false: a caller of several
    scenes names those none of them reads)."""
    octree = open_octree_from_spec(
        args.scene, scene_options(args), progress=not args.quiet,
        lod_colour=args.lod_colour, colour_storage=getattr(args, "colour_storage", "srgb8"))
    if note_unread:
        note_unread_scene_options(args, args.scene)
    return octree


#: The scene options only a build reads: their defaults, who takes them, and the kinds of
#: scene (``scene.loaders.SCENE_KINDS``) whose build reads them.
_BUILT = ("scene", "builtin", "recipe", "dem", "vox", "mesh")
BUILD_OPTIONS = {
    "mesh_resolution": ("--mesh-resolution", SceneOptions.mesh_resolution, "meshes",
                        ("mesh",)),
    "footprint": ("--footprint", SceneOptions.terrain_footprint, "terrains and DEMs",
                  ("recipe", "dem")),
    "vertical_scale": ("--vertical-scale", None, "DEMs", ("dem",)),
    "dem_fit": ("--dem-fit", None, "DEMs", ("dem",)),
    "colour_storage": ("--colour-storage", "srgb8", "a scene being built", _BUILT),
    "lod_colour": ("--lod-colour", DEFAULT_LOD_COLOUR, "a scene being built", _BUILT),
}


def note_unread_scene_options(args, *scenes: str) -> None:
    """A note naming the build options given (other than their defaults) that no scene of
    ``scenes`` reads: ``render lit.npz --vertical-scale 3`` drew the saved relief, and
    ``render builtin:sphere --footprint 4096`` the sphere, without a word."""
    kinds = [scene_kind(scene) for scene in scenes]
    if None in kinds:  # no scene this names could have opened: nothing to say
        return
    ignored = {flag: [users] for dest, (flag, default, users, readers) in BUILD_OPTIONS.items()
               if getattr(args, dest, default) != default and not set(readers) & set(kinds)}
    if not ignored:
        return
    if len(scenes) == 1:
        warn_ignored(ignored, f"{scenes[0]}, {SCENE_KINDS[kinds[0]]},")
    else:
        warn_ignored(ignored, f"none of the scenes {', '.join(scenes)}", verb="takes")


def is_saved_octree(scene: str) -> bool:
    """Whether ``scene`` names a saved octree file (``svo.open`` loads it as it is)."""
    return scene_kind(scene) == "octree"


#: Peak bytes a pixel of one render costs (the result's maps, the renderer's sums, the image
#: written): 114 for the reference, 132 for the error-aware and 161 for the adaptive
#: renderer, measured over 4096² renders of builtin:sphere; with room for the rest.
RENDER_BYTES_PER_PIXEL = 192


def check_render_memory(size: int, *, held_bytes_per_pixel: int = 0,
                        work: str | None = None, option: str = "--size") -> None:
    """Refuse an image the machine cannot hold: ``render --size 16384`` (within the option's
    range) ran for four minutes and was killed for memory, exit 137 and not a word.
    ``held_bytes_per_pixel``: what the ``work`` keeps beside the render (a probe's six cube
    faces); ``option`` names the side where it is not ``--size``."""
    check_fits_in_memory(size * size * (RENDER_BYTES_PER_PIXEL + held_bytes_per_pixel),
                         f"{option} {size}: {work or f'a {size}×{size} render'}",
                         f"give a smaller {option}")


def camera(args, bounds) -> Camera:
    """The view the options ask for over ``bounds`` (an octree's voxel box): --eye/--target,
    or a preset, at a ``--size`` this machine can render (``check_render_memory``)."""
    check_render_memory(args.size)
    lo, hi = (np.asarray(b, np.float64) for b in bounds)
    if args.eye is not None or args.target is not None:
        if args.eye is None or args.target is None:
            raise VoxfieldError("--eye and --target must be given together")
        if getattr(args, "camera_given", False):
            raise VoxfieldError(f"--camera {args.camera} and --eye/--target both name the "
                                "view; give one of them")
        return Camera.look_at(args.eye, args.target, fov_deg=args.fov or 60.0, width=args.size)
    preset = "cube+x" if args.camera == "cube" else args.camera
    if args.fov is not None and preset in CAMERA_PRESETS and CAMERA_PRESETS[preset][0] is None:
        raise VoxfieldError(f"--camera {args.camera} has no field of view to set with --fov")
    return preset_camera(args.camera, lo, hi, size=args.size, fov_deg=args.fov)


def with_camera(args, preset: str) -> argparse.Namespace:
    """``args`` with ``--camera preset`` in place of the one given: how a command resolves
    ``auto`` to the view it settles on."""
    return argparse.Namespace(**{**vars(args), "camera": preset})


def settled_view(args, octree) -> argparse.Namespace:
    """``args`` with ``--camera auto`` replaced by the preset it means for the scene
    (``auto_preset``), so that what a command prints or records names the view it used."""
    return with_camera(args, auto_preset(args.scene, octree)) if args.camera == "auto" else args


def scene_camera(args, octree) -> Camera:
    """``camera`` over an octree: the orbit view frames its content (``content_box``), not a
    ground plane that dominates its voxel box; every other view keeps the voxel box.
    ``--camera auto`` is resolved from the scene's kind (``settled_view``)."""
    args = settled_view(args, octree)
    if args.camera == "orbit" and args.eye is None and args.target is None:
        return camera(args, content_box(octree))
    return camera(args, octree.voxel_bounds)


def study_camera(args, octree) -> Camera:
    """``scene_camera`` for a command that measures from the view (studies, ``compare``,
    ``sweep``, ``calibrate``), with the checks such a command makes before its first render:
    a ``--base-lod`` the octree has no level for, and a camera inside or under the scene or
    seeing nothing of it, as its figures would describe no view; a view of one colour in the
    measured ``--channel`` is noted, as its figures describe outlines alone."""
    check_base_lod(args, octree)
    view = scene_camera(args, octree)
    check_camera_placement(octree, view)
    channel = getattr(args, "channel", None)  # lighting and shadows measure their own light
    note = one_colour_view_note(octree, view, channel) if channel else None
    if note:
        warnings.warn(note, UserWarning, stacklevel=2)
    return view


def check_measured_sides(sides, option: str = "--size") -> None:
    """Refuse image sides too small for SSIM before any work: a comparison at ``--size 6``
    rendered (or baked and cached) everything, then stopped at the first measurement."""
    small = sorted({int(side) for side in sides if side < SSIM_WINDOW})
    if small:
        raise VoxfieldError(f"{option} {','.join(map(str, small))}: the comparison measures "
                            f"SSIM, whose {SSIM_WINDOW}×{SSIM_WINDOW} window needs images of "
                            f"at least {SSIM_WINDOW} pixels a side")


def check_measured_channel(octree, channel: str) -> None:
    """Refuse, before any render, a channel whose colours pass 1: PSNR, RMSE and SSIM take
    linear colours in [0, 1], and a measuring command failed after all its renders
    (``--channel emission`` of builtin:cornell, whose lamp's voxels emit 4). A render is an
    average of its voxels' colours, so the voxels' peak bounds every image's."""
    stored = octree.channel(channel)[octree.level_slice(octree.depth)]
    if storage_of(stored) == SRGB8:
        return  # 8-bit sRGB codes decode to [0, 1]
    peak = 0.0
    for first in range(0, len(stored), 1 << 20):  # decoded a million voxels at a time
        peak = max(peak, float(decode_channel(stored[first:first + (1 << 20)]).max()))
    if peak > 1.0:
        raise VoxfieldError(f"channel {channel!r} holds colours up to {peak:.3g}; PSNR, RMSE "
                            "and SSIM take linear colours in [0, 1]: measure another channel")


def check_refinable_base_lod(args, same_image: str) -> None:
    """Refuse ``--base-lod 0`` where a command varies the error-aware refinement: from LOD 0
    there is nothing finer to refine into, so every value of it renders the same image
    (``calibrate`` reported whichever threshold its bisection stopped at). ``same_image``
    says which renders come out alike."""
    if getattr(args, "base_lod", None) == 0:
        raise VoxfieldError(f"--base-lod 0: the error-aware renderer has nothing finer than "
                            f"LOD 0 to refine into, so {same_image}; give a base LOD of 1 "
                            "or more, or cone")


def check_base_lod(args, octree) -> None:
    """Refuse a ``--base-lod`` the octree has no level for before any render: the renderer
    refused it only after the reference (minutes on a large view) had been rendered."""
    base_lod = getattr(args, "base_lod", None)
    if base_lod is not None and base_lod > octree.depth:
        # Not given, it is the default, which the user may not know they asked for.
        which = "" if "base_lod" in given_options(args) else " (the default)"
        raise VoxfieldError(f"--base-lod {base_lod}{which} is coarser than the scene "
                            f"{octree.name!r} goes: its octree's LODs run 0..{octree.depth}; "
                            f"give one of those or 'cone'")


def default_output(prefix: str, scene: str, suffix: str = "") -> Path:
    """``out/PREFIX_NAME[SUFFIX]``, NAME the scene's file stem or ``kind:NAME`` name, made
    path-safe: where a command writes when no ``--out`` is given."""
    name = scene.split(":", 1)[1] if ":" in scene and not Path(scene).exists() else scene
    name = Path(name).stem or "scene"
    return Path("out") / f"{prefix}_{re.sub(r'[^A-Za-z0-9_.-]+', '_', name)}{suffix}"


def add_hit_options(p: argparse.ArgumentParser, prefix: str = "") -> None:
    """How a light-field trace accepts, checks and colours a hit: the options ``probe-render``
    and ``study probes`` share (``prefix`` starts each help line); ``hit_options`` reads
    them back."""
    defaults = LightFieldOptions()
    p.add_argument("--epsilon", choices=tuple(EPSILON_MODES), default=defaults.epsilon,
                   help=f"{prefix}hit acceptance rule (default {defaults.epsilon}: thick "
                   "behind a surface by the depth one texel spans; adaptive is the probe "
                   "thesis's §7.1 as printed, adaptive-text the form its text derives)")
    p.add_argument("--epsilon-value", type=non_negative_float, default=defaults.epsilon_value,
                   metavar="E",
                   help=f"{prefix}constant epsilon: thickness in voxels; the slope and "
                   "footprint epsilons add it to the thickness they derive behind a surface "
                   f"(default {defaults.epsilon_value})")
    p.add_argument("--epsilon-k", type=non_negative_float, default=defaults.epsilon_k, metavar="K",
                   help=f"{prefix}adaptive/angular epsilon: scale k "
                   f"(default {defaults.epsilon_k})")
    p.add_argument("--epsilon-front", type=non_negative_or_inf, default=defaults.epsilon_front,
                   metavar="T",
                   help=f"{prefix}footprint epsilon: at most T texel widths in front of "
                   f"a surface, inf for no cap (default {defaults.epsilon_front})")
    p.add_argument("--refine-window", type=non_negative_float, default=defaults.refine_window,
                   metavar="W", help=f"{prefix}check a hit against the probes that may see "
                   "a surface in front of it and trace it again against its colour probe, "
                   f"over W of their texel widths; 0 for off (default "
                   f"{defaults.refine_window})")
    p.add_argument("--consensus", action=argparse.BooleanOptionalAction,
                   default=defaults.consensus,
                   help=f"{prefix}before taking a hit, ask the other probes around it "
                   "whether they see empty space there (fewer false hits, more fetches; "
                   f"default {'on' if defaults.consensus else 'off'})")
    p.add_argument("--ring", action=argparse.BooleanOptionalAction, default=defaults.ring,
                   help=f"{prefix}when every probe of the cage around the point a ray has "
                   "reached loses it, let the probes one grid step further out try, nearest "
                   "first, before falling back (fewer fallbacks on occluded scenes; "
                   f"default {'on' if defaults.ring else 'off'}; off is the thesis)")
    p.add_argument("--backface", action="store_true",
                   help=f"{prefix}reject hits whose stored normal faces along the ray")
    p.add_argument("--no-fallback", action="store_true",
                   help=f"{prefix}leave rays every probe loses unknown (black) instead of "
                   "reading the nearest probe as an environment map")
    p.add_argument("--colour-probe", choices=tuple(COLOUR_PROBES),
                   default=defaults.colour_probe,
                   help=f"{prefix}which probe that sees a hit answers its colour: "
                   "footprint (its texel is smallest there; for the view-independent "
                   "radiance bakes store) or parallel (it sees the hit most nearly along the "
                   f"ray) (default {defaults.colour_probe})")


def note_unused_epsilon_options(options: LightFieldOptions) -> None:
    """A note naming the epsilon parameters given (away from their defaults) that the chosen
    ``--epsilon`` does not read: ``--epsilon-k 4`` under the footprint epsilon changed
    nothing, without a word."""
    defaults = LightFieldOptions()
    ignored = {f"--{name.replace('_', '-')}": list(readers)
               for name, readers in EPSILON_READERS.items()
               if options.epsilon not in readers
               and getattr(options, name) != getattr(defaults, name)}
    if ignored:
        warn_ignored(ignored, f"the {options.epsilon} epsilon")


def hit_options(args) -> dict:
    """The ``LightFieldOptions`` fields ``add_hit_options`` put on the command line."""
    return {"epsilon": args.epsilon, "epsilon_value": args.epsilon_value,
            "epsilon_k": args.epsilon_k, "epsilon_front": args.epsilon_front,
            "refine_window": args.refine_window, "consensus": args.consensus,
            "ring": args.ring,
            "backface": args.backface, "fallback": not args.no_fallback,
            "colour_probe": args.colour_probe}


def output_named(out: str | Path, suffix: str, what: str, *, source: str | None = None) -> Path:
    """``--out`` as a path, refused unless it ends in ``suffix`` (a file whose name says
    another format, an octree called ``.png``, misleads whoever opens it next), unless it
    can be written (``atomic.check_writable``) and where it is the ``source`` scene file
    itself (the command would replace its own input): all before the command's work."""
    path = Path(out)
    if path.suffix.lower() != suffix:
        raise VoxfieldError(f"{path}: {what} is written as {suffix}; give --out a name ending "
                            f"in {suffix}")
    if source is not None and path.exists() and Path(source).exists() and \
            path.samefile(source):
        raise VoxfieldError(f"{path}: --out names the scene it reads; write {what} elsewhere")
    return check_writable(path)
