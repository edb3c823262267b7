"""``voxfield bake`` (a probe grid into a resumable probe-set folder) and ``voxfield probes
show`` (a PNG to check it by eye)."""

from __future__ import annotations

import sys
import time
import warnings
from pathlib import Path

import numpy as np

from voxfield.checks import spoken_list
from voxfield.cli.commands import add_command, add_quiet
from voxfield.cli.options import (
    Given,
    add_channel_option,
    add_scene_options,
    check_render_memory,
    default_output,
    given_options,
    int_between,
    lod_arg,
    non_negative_float,
    open_octree,
    output_named,
    positive_float,
    threshold_arg,
    warn_ignored,
)
from voxfield.errors import VoxfieldError
from voxfield.probes.bake import RADIANCE_FIELDS, check_bake_options, export_cube_faces
from voxfield.probes.folder_bake import bake_to_folder, check_finish_memory, checked_folder_path
from voxfield.probes.grid import check_placement, parse_grid, relocate
from voxfield.probes.probe_folder import open_probe_set, read_header
from voxfield.probes.probe_set import BAKE_RENDERERS, MAX_RESOLUTION, MIN_RESOLUTION, BakeOptions
from voxfield.probes.show import write_show
from voxfield.progress import progress_bar
from voxfield.render.camera import CUBE_FACES, MAX_IMAGE_SIDE
from voxfield.render.image_io import save_exr
from voxfield.scene.loaders import SceneOptions
from voxfield.studies.html_report import write_page
from voxfield.studies.report import markdown_table
from voxfield.svo.open import open_octree as open_octree_from_spec

#: The overview render's side in pixels when ``probes show`` is given no --size.
SHOW_SIZE = 512


def register(subparsers) -> None:
    """Register ``bake`` and ``probes show`` on the main parser's sub-commands."""

    defaults = BakeOptions()

    p = add_command(
        subparsers, "bake",
        description="Bake octahedral light probes straight from the octree into a probe-set "
        "folder (probes.json, one .npz per probe, EXR atlases). Probes are written as they "
        "finish: re-running the same command resumes a stopped bake. Probes run on threads "
        "by default, or on Dask: --scheduler processes or a cluster address.",
    )
    add_scene_options(p)
    p.add_argument("--grid", required=True, metavar="SPEC",
                   help='probe grid: "NXxNYxNZ" fitted to the scene (e.g. 4x2x4), '
                   '"surface:NXxNZ@H" (one layer H voxels above the ground, for terrains) or '
                   '"origin=x,y,z;spacing=s or sx,sy,sz;counts=nx,ny,nz" in voxels')
    p.add_argument("--resolution", type=int_between(1, MAX_RESOLUTION, "texels per map side"),
                   default=defaults.resolution, metavar="R",
                   help=f"octahedral map side in texels, even, {MIN_RESOLUTION}.."
                   f"{MAX_RESOLUTION} (default {defaults.resolution})")
    p.add_argument("--renderer", choices=BAKE_RENDERERS, default=defaults.renderer,
                   help=f"radiance renderer (default {defaults.renderer}); distance and "
                   "normals always come from one exact LOD-0 ray per texel")
    p.add_argument("--samples", type=int_between(1, 16, "rays per texel side"),
                   action=Given, default=defaults.samples,
                   help=f"reference: CMJ rays per texel side, 1..16 (default "
                   f"{defaults.samples})")
    p.add_argument("--lod", type=lod_arg, action=Given, default=defaults.lod,
                   help="lod renderer: fixed LOD; adaptive/error-aware: base LOD; 'cone' "
                   "(default) picks it from the texel footprint")
    p.add_argument("--cone-scale", type=positive_float, action=Given,
                   default=defaults.cone_scale,
                   help="node size accepted per texel footprint (default 1)")
    p.add_argument("--threshold", type=threshold_arg, action=Given,
                   default=defaults.threshold,
                   help=f"error-aware: refinement threshold (default {defaults.threshold}; "
                   "inf never refines, a negative one refines everywhere)")
    p.add_argument("--decay", type=non_negative_float, action=Given,
                   default=defaults.decay,
                   help=f"error-aware: weight of the children's error (default {defaults.decay})")
    add_channel_option(p)
    p.add_argument("--relocate", action="store_true",
                   help="move probes out of and away from geometry first; probes that cannot "
                   "move clear are disabled")
    p.add_argument("--scheduler", default="threads", metavar="WHERE",
                   help="threads (default), processes, serial, or a Dask scheduler address "
                   "(tcp://host:8786) for a cluster; results are identical on each")
    p.add_argument("--out", default=None,
                   help="probe-set folder (default out/probes_NAME, NAME from the scene)")
    p.add_argument("--fresh", action="store_true",
                   help="discard the probe set the folder holds (even from another scene) "
                        "and start over; a folder of other files is refused, not emptied")
    add_quiet(p)
    p.set_defaults(func=run_bake)

    probes = add_command(
        subparsers, "probes",
        description="Look at a probe-set folder.")
    sub = probes.add_subparsers(dest="probes_command", required=True, metavar="ACTION")
    s = sub.add_parser(
        "show", help="PNG of the radiance, distance and normal atlases and a 3D overview",
        description="Write one PNG: atlases of every probe's radiance (sRGB), distance "
        "(colour-mapped, legend in voxels) and normals, and the probe positions drawn over an "
        "orbit render of the scene (hidden, moved and disabled probes marked). The scene is "
        "reopened as it was baked unless --scene names it.",
    )
    s.add_argument("folder", help="probe-set folder written by voxfield bake")
    s.add_argument("--out", default=None,
                   help="output PNG (default FOLDER/show.png); its report page goes beside "
                        "it, named after it (show.html)")
    which_scene = s.add_mutually_exclusive_group()
    which_scene.add_argument(
        "--scene", default=None,
        help="scene for the overview render (default: the one the bake recorded)")
    which_scene.add_argument("--no-scene", action="store_true",
                             help="draw the probe positions without rendering the scene")
    # None when not given: with --no-scene there is no render for it to size (noted).
    s.add_argument("--size", type=int_between(1, MAX_IMAGE_SIDE, "pixels per side"),
                   default=None, metavar="N",
                   help=f"overview render size in pixels, 1..{MAX_IMAGE_SIDE} (default "
                   f"{SHOW_SIZE}; only with the scene, not --no-scene)")
    add_quiet(s)
    s.set_defaults(func=run_show)

    c = sub.add_parser(
        "export-cubes", help="six cube-map faces per probe as EXR, for engines",
        description="Trace every enabled probe's six 90° cube faces straight from the baked "
        "scene (OpenGL face order and orientation: +x, -x, +y, -y, +z, -z) and write one EXR "
        "per face with linear RGB radiance and Z = radial distance.",
    )
    c.add_argument("folder", help="probe-set folder written by voxfield bake")
    c.add_argument("--size", type=int_between(1, MAX_IMAGE_SIDE, "pixels per side"),
                   default=None, help=f"face side in pixels, 1..{MAX_IMAGE_SIDE} (default "
                   "half the octahedral resolution)")
    c.add_argument("--out", default=None, help="output folder (default FOLDER/cubes)")
    c.add_argument("--scene", default=None,
                   help="the baked scene (default: the one the bake recorded)")
    add_quiet(c)
    c.set_defaults(func=run_export_cubes)


def _bake_options(args):
    # The radiance options on the command line, whatever their values: one given at its
    # default is as ignored by a renderer that does not take it as any other.
    given = given_options(args)
    takers: dict[str, list[str]] = {}  # each radiance field: the renderers that take it
    for renderer, taken in RADIANCE_FIELDS.items():
        for name in taken:
            takers.setdefault(name, []).append(renderer)
    ignored = {f"--{name.replace('_', '-')}": users for name, users in takers.items()
               if args.renderer not in users and name in given}
    if ignored:  # --samples with the default error-aware renderer did nothing unsaid
        warn_ignored(ignored, f"the {args.renderer} radiance renderer")
    unread = []
    if (args.renderer in takers["cone_scale"] and args.lod is not None
            and "cone_scale" in given):
        unread.append("--cone-scale only with --lod cone")
    if args.renderer == "error-aware" and args.lod == 0:  # nothing finer to refine into
        refining = [f"--{name}" for name in ("threshold", "decay") if name in given]
        if refining:
            unread.append(f"{spoken_list(refining)} only with a --lod other than 0")
    if unread:
        warnings.warn(f"the {args.renderer} radiance renderer reads {', '.join(unread)}; "
                      "ignored", stacklevel=2)
    return BakeOptions(
        resolution=args.resolution, renderer=args.renderer, channel=args.channel,
        samples=args.samples, lod=args.lod, cone_scale=args.cone_scale,
        threshold=args.threshold, decay=args.decay, seed=args.seed,
    )


def _source(args) -> dict:
    """How to reopen the scene later (``probes show``): the scene argument and its options."""
    spec = args.scene
    path = Path(spec)
    if ":" not in spec or path.exists():
        spec = str(path.resolve())
    return {"scene": spec, "mesh_resolution": args.mesh_resolution,
            "footprint": args.footprint, "vertical_scale": args.vertical_scale,
            "dem_fit": args.dem_fit, "seed": args.seed, "lod_colour": args.lod_colour}


def run_bake(args) -> int:
    options = _bake_options(args)  # bad options fail before the scene is built
    out = checked_folder_path(args.out or default_output("probes", args.scene))
    octree = open_octree(args)
    check_bake_options(octree, options)  # before the grid's notes, not after them
    grid = parse_grid(args.grid, octree.voxel_bounds, octree=octree)
    check_finish_memory(grid.count, options.resolution)  # before relocating and notes
    report = None
    if args.relocate:
        grid, report = relocate(grid, octree, seed=args.seed)
        if not args.quiet:
            print(report.summary())
    check_placement(grid, octree, args.grid, relocated=args.relocate)
    start = time.perf_counter()
    probe_set = bake_to_folder(
        octree, grid, options, out, scheduler=args.scheduler, fresh=args.fresh,
        progress=not args.quiet, source=_source(args), relocation=report,
    )
    wall = time.perf_counter() - start
    if not args.quiet:
        run = read_header(out).get("last_run", {})
        print(bake_summary(probe_set, run, wall, out))
    return 0


def bake_summary(probe_set, run: dict, wall: float, out) -> str:
    """Cost per probe and per texel, and what this run did."""
    s = probe_set.cost_summary()
    cost = probe_set.cost
    rays = cost["radiance_rays"] + cost["geometry_rays"]
    steps = cost["radiance_steps"] + cost["geometry_steps"]
    seconds = cost["radiance_seconds"] + cost["geometry_seconds"]
    texels = probe_set.resolution ** 2
    lines = [
        f"{s['baked']} of {s['probes']} probes, {s['resolution']}² texels, {s['renderer']}: "
        f"this run baked {run.get('baked', '?')} and reused {run.get('reused', '?')} "
        f"({run.get('scheduler') or 'threads'}, {wall:.2f} s wall)",
        f"total: {s['rays']:,} rays, {s['steps']:,} steps, {s['seconds']:.3f} s kernel time",
        f"per probe: {s['rays'] / max(s['baked'], 1):,.0f} rays, "
        f"{s['steps'] / max(s['baked'], 1):,.0f} steps, {s['seconds_per_probe'] * 1e3:.2f} ms",
        f"per texel: {s['rays_per_texel']:.3f} rays ({s['radiance_rays_per_texel']:.3f} "
        f"radiance), {s['steps_per_texel']:.2f} steps, {s['nanoseconds_per_texel']:.0f} ns",
    ]
    enabled = np.flatnonzero(probe_set.enabled)
    if 0 < len(enabled) <= 32:
        lines.append(f"{'probe':>6}{'position':>26}{'rays/texel':>12}{'steps/texel':>13}"
                     f"{'ms':>9}")
        for i in enabled:
            x, y, z = probe_set.positions[i]
            lines.append(f"{i:>6}{f'({x:.1f}, {y:.1f}, {z:.1f})':>26}"
                         f"{rays[i] / texels:>12.3f}{steps[i] / texels:>13.2f}"
                         f"{seconds[i] * 1e3:>9.2f}")
    lines.append(f"wrote {out}/probes.json, {len(enabled)} probe files and radiance.exr, "
                 "distance.exr, normal.exr")
    return "\n".join(lines)


def run_show(args) -> int:
    folder = Path(args.folder)
    probe_set = open_probe_set(folder)
    header = read_header(folder)
    out = output_named(args.out or folder / "show.png", ".png", "the probe set's picture")
    if args.no_scene and args.size is not None:  # it sizes the scene's render alone
        warn_ignored({"--size": ["the scene's overview render"]}, "probes show with --no-scene")
    octree = None if args.no_scene else _reopen_scene(header, args.scene, args.quiet)
    s = probe_set.cost_summary()
    title = (f"{header['scene'].get('name', 'scene')}: {s['baked']} of {s['probes']} probes, "
             f"{s['resolution']}² texels, {s['renderer']}, {s['rays_per_texel']:.2f} rays/texel")
    write_show(probe_set, out, octree=octree, title=title,
               size=SHOW_SIZE if args.size is None else args.size)
    # Named after the picture: a shared folder (out/) may hold a study's report.html, or
    # another probe set's page.
    page = write_page(out.with_suffix(".html"), title=title,
                      subtitle=f"probe set {folder}", figures=[out],
                      markdown_text=probe_set_markdown(probe_set, header))
    if not args.quiet:
        print(f"wrote {out} and {page}")
    return 0


def probe_set_markdown(probe_set, header: dict) -> str:
    """The bake's cost as tables for the probe set's report page."""
    s = probe_set.cost_summary()
    cost = probe_set.cost
    texels = probe_set.resolution ** 2
    lines = [
        "## Bake", "",
        markdown_table(["probes baked", "resolution", "renderer", "rays", "steps",
                        "kernel seconds", "rays / texel", "steps / texel"],
                       [[f"{s['baked']} of {s['probes']}", f"{s['resolution']}²", s["renderer"],
                         f"{s['rays']:,}", f"{s['steps']:,}", f"{s['seconds']:.3f}",
                         f"{s['rays_per_texel']:.3f}", f"{s['steps_per_texel']:.2f}"]]),
        f"Scene `{header['scene'].get('name', 'scene')}`, grid "
        f"{' × '.join(str(c) for c in probe_set.grid.counts)}.", "",
    ]
    enabled = np.flatnonzero(probe_set.enabled)
    rows = []
    for i in enabled[:256]:
        x, y, z = probe_set.positions[i]
        rays = cost["radiance_rays"][i] + cost["geometry_rays"][i]
        steps = cost["radiance_steps"][i] + cost["geometry_steps"][i]
        seconds = cost["radiance_seconds"][i] + cost["geometry_seconds"][i]
        rows.append([i, f"({x:.1f}, {y:.1f}, {z:.1f})", f"{rays / texels:.3f}",
                     f"{steps / texels:.2f}", f"{seconds * 1e3:.2f}"])
    if rows:
        lines += ["## Probes" + (" (first 256)" if len(enabled) > 256 else ""), "",
                  markdown_table(["probe", "position", "rays / texel", "steps / texel", "ms"],
                                 rows)]
    return "\n".join(lines)


#: Bytes a pixel of a probe's six held cube faces costs: per face float16 RGB and float32
#: distance, and the float32 copy of one face's RGB the EXR writer takes.
CUBE_FACE_BYTES_PER_PIXEL = 6 * (3 * 2 + 4) + 3 * 4


def run_export_cubes(args) -> int:
    folder = Path(args.folder)
    probe_set = open_probe_set(folder)
    probes = [i for i in range(probe_set.count) if probe_set.enabled[i]]
    if not probes:
        raise VoxfieldError(f"{folder}: every probe is disabled (no free space found for "
                            "it); there is nothing to export")
    size = max(1, probe_set.resolution // 2) if args.size is None else args.size
    # The six faces are held (float16 RGB, float32 distance) while each is rendered.
    check_render_memory(size, held_bytes_per_pixel=CUBE_FACE_BYTES_PER_PIXEL,
                        work=f"exporting a probe's six {size}×{size} cube faces")
    octree = _reopen_scene(read_header(folder), args.scene, args.quiet, exact=True)
    out = Path(args.out) if args.out else folder / "cubes"
    out.mkdir(parents=True, exist_ok=True)
    with progress_bar(total=len(probes), desc="cube faces", unit="probe",
                      enabled=not args.quiet) as bar:
        for i in probes:
            radiance, distance = export_cube_faces(probe_set, octree, i, size)
            for f, (name, _, _) in enumerate(CUBE_FACES):
                save_exr({"RGB": radiance[f].astype(np.float32), "Z": distance[f]},
                         out / f"probe_{i:05d}_{name.replace('+', 'pos').replace('-', 'neg')}"
                         ".exr")
            bar.update(1)
    if not args.quiet:
        print(f"wrote {6 * len(probes)} faces of {len(probes)} probes to {out}")
    return 0


def _reopen_scene(header: dict, scene: str | None, quiet: bool, *, exact: bool = False):
    """The baked scene for the overview: ``scene`` if given, else the recorded source; None
    (probes drawn without the render) when the recorded one cannot be opened or is not the
    baked one. A ``scene`` given that cannot be opened is an error, and so is either case
    under ``exact`` (cube faces, traced from the scene itself)."""

    def unusable(problem: str, instead: str) -> None:
        """``problem`` as the error (``exact``), or as a note saying what is drawn instead."""
        if exact:
            raise VoxfieldError(f"{problem}; cube faces are traced from the baked scene: name "
                                "it with --scene")
        _note(f"{problem}; {instead}")

    source = dict(header["scene"].get("source") or {})
    spec = scene or source.get("scene")
    if not spec:
        unusable("no scene recorded with these probes", "pass --scene to draw probes over a "
                 "render")
        return None
    options = SceneOptions(
        mesh_resolution=source.get("mesh_resolution", 256),
        terrain_footprint=source.get("footprint", 512),
        vertical_scale=source.get("vertical_scale"), seed=source.get("seed", 0),
        dem_fit=source.get("dem_fit"),
    )
    try:
        octree = open_octree_from_spec(spec, options, progress=not quiet,
                                       lod_colour=source.get("lod_colour", "mean"))
    except VoxfieldError as exc:
        if scene:  # named on the command line: a typo is the user's to correct, not to skip
            raise VoxfieldError(f"--scene {scene}: {exc}") from exc
        unusable(f"cannot open the baked scene {spec!r} ({exc})", "drawing probes without it")
        return None
    channel = header["scene"].get("channel", "albedo")
    try:
        same = octree.fingerprint(channel) == header["scene"]["fingerprint"]
    except VoxfieldError:
        same = False
    if not same:
        unusable(f"{spec!r} is not the scene these probes were baked from", "drawing it anyway")
    return octree


def _note(text: str) -> None:
    """A note on what was drawn: printed with --quiet too (it silences bars and summaries,
    not word that the picture is not what was asked for)."""
    print(f"voxfield: note: {text}", file=sys.stderr)
