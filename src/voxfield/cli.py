"""The ``voxfield`` command line: one entry point, one sub-command per task.

Bad input prints one line, ``voxfield: error: ...``, and exits with status 2.
"""

from __future__ import annotations

import argparse
import json
import re
import sys
import time
from pathlib import Path

import numpy as np

from voxfield.errors import VoxfieldError

EXIT_USAGE = 2


def _vector_arg(text: str) -> tuple[float, float, float]:
    try:
        values = tuple(float(v) for v in text.split(","))
    except ValueError:
        message = f"expected three numbers like 1,2,3, got {text!r}"
        raise argparse.ArgumentTypeError(message) from None
    if len(values) != 3:
        raise argparse.ArgumentTypeError(f"expected three numbers like 1,2,3, got {text!r}")
    return values


def _lod_arg(text: str) -> int | None:
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


def _int_at_least(low: int):
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


_positive_int = _int_at_least(1)


def default_output(prefix: str, scene: str, suffix: str = "") -> Path:
    """``out/PREFIX_NAME[SUFFIX]``, NAME the scene's file stem or ``kind:NAME`` name, made
    path-safe: where a command writes when no ``--out`` is given."""
    name = scene.split(":", 1)[1] if ":" in scene and not Path(scene).exists() else scene
    name = Path(name).stem or "scene"
    return Path("out") / f"{prefix}_{re.sub(r'[^A-Za-z0-9_.-]+', '_', name)}{suffix}"


def _add_scene_options(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "scene",
        help="scene: a .vox/.obj/.glb/.ply/.hgt/.tif/.npz file, builtin:NAME, terrain:RECIPE "
        "or dem:jacksboro (see `voxfield scenes`)",
    )
    p.add_argument("--mesh-resolution", type=_positive_int, default=256, metavar="N",
                   help="voxels along a mesh's longest side (default 256)")
    p.add_argument("--footprint", type=_positive_int, default=512, metavar="N",
                   help="terrain footprint in voxels per side (default 512)")
    p.add_argument("--vertical-scale", type=float, default=None, metavar="S",
                   help="terrain height multiplier (default: true scale)")
    p.add_argument("--seed", type=int, default=0, help="seed for sampling and scattering")
    p.add_argument("--colour-storage", choices=("srgb8", "float32"), default="srgb8",
                   help="how a built octree keeps its albedo: 8-bit sRGB, 3 bytes a node "
                   "(default), or float32, 12 bytes")
    p.add_argument("--lod-colour", choices=("mean", "surface"), default="mean",
                   help="inner-node colours: mean of the children (default, as the EA thesis) "
                   "or mean of the voxels with an exposed face")


def _add_channel_option(p: argparse.ArgumentParser) -> None:
    p.add_argument("--channel", default="albedo",
                   help="colour channel: albedo or a baked time of day (`voxfield light`)")


def _scene_options(args):
    from voxfield.scene.loaders import SceneOptions

    return SceneOptions(
        mesh_resolution=args.mesh_resolution, terrain_footprint=args.footprint,
        vertical_scale=args.vertical_scale, seed=args.seed,
    )


def _open_octree(args):
    from voxfield.svo.io import open_octree

    return open_octree(args.scene, _scene_options(args), progress=not args.quiet,
                       lod_colour=args.lod_colour, colour_storage=args.colour_storage)


def _camera(args, octree):
    from voxfield.render.camera import Camera, oblique_camera, orbit_camera, top_down_camera

    lo, hi = octree.voxel_bounds
    if args.eye is not None or args.target is not None:
        if args.eye is None or args.target is None:
            raise VoxfieldError("--eye and --target must be given together")
        return Camera.look_at(args.eye, args.target, fov_deg=args.fov or 60.0, width=args.size)
    preset = args.camera
    if preset == "top":
        return top_down_camera(lo, hi, size=args.size, fov_deg=args.fov or 90.0)
    if preset == "oblique":
        return oblique_camera(lo, hi, size=args.size, fov_deg=args.fov or 90.0)
    if preset == "orbit":
        return orbit_camera(lo, hi, size=args.size, fov_deg=args.fov or 45.0)
    if preset.startswith("cube"):
        face = preset[4:] or "+x"
        return Camera.cube_face((lo + hi) / 2.0, face, size=args.size)
    if preset == "ortho-top":
        c = (lo + hi) / 2.0
        extent = float(max(hi[0] - lo[0], hi[2] - lo[2]))
        return Camera.orthographic(
            (c[0], hi[1] + 1.0, c[2]), (0.0, -1.0, 0.0), (0.0, 0.0, -1.0),
            view_height=extent, width=args.size,
        )
    raise VoxfieldError(
        f"unknown camera {preset!r}; use top, oblique, orbit, ortho-top, cube+x..cube-z "
        "or --eye/--target"
    )


def cmd_render(args) -> int:
    from voxfield.render.counter_maps import write_counter_maps
    from voxfield.render.image_io import save_result_image
    from voxfield.render.renderers import render_lod, render_reference

    octree = _open_octree(args)
    camera = _camera(args, octree)
    progress = not args.quiet
    options = {"seed": args.seed, "channel": args.channel, "threads": args.threads,
               "progress": progress}
    if args.renderer == "reference":
        result = render_reference(octree, camera, side=args.spp_side, **options)
    elif args.renderer == "lod":
        result = render_lod(octree, camera, lod=args.lod, cone_scale=args.cone_scale, **options)
    elif args.renderer == "error-aware":
        from voxfield.render.error_aware import render_error_aware

        result = render_error_aware(
            octree, camera, threshold=args.threshold, decay=args.decay, base_lod=args.base_lod,
            cone_scale=args.cone_scale, max_refinements=args.refinements,
            encoding=args.encoding, reuse_parent=args.reuse_parent,
            lighting_aware=args.lighting_aware, bright_ratio=args.bright_ratio, **options,
        )
    else:
        from voxfield.render.adaptive import render_adaptive

        result = render_adaptive(octree, camera, base_lod=args.base_lod,
                                 iterations=args.iterations, **options)
    out = Path(args.out)
    if args.shade:
        result.image = shade_for_display(result)
    save_result_image(result, out)
    written = [out]
    if args.counters:
        written += write_counter_maps(result, out, octree.depth)
    if not args.quiet:
        s = result.summary()
        print(
            f"{s['renderer']}: {s['width']}x{s['height']}, {s['rays']:,} rays, "
            f"{s['traversal_steps']:,} steps ({s['steps_per_ray']:.2f}/ray), "
            f"{s['seconds']:.2f} s, {s['mrays_per_second']:.2f} Mrays/s"
        )
        for path in written:
            print(f"wrote {path}")
    return 0


def shade_for_display(result) -> np.ndarray:
    """Albedo times a fixed key light on the face normals: easier on the eye, not for metrics."""
    light = np.array([0.45, 0.8, 0.4])
    light /= np.linalg.norm(light)
    lambert = np.clip(result.normal @ light, 0.0, 1.0)
    side = np.abs(result.normal @ np.array([0.8, 0.0, -0.6]))
    factor = 0.35 + 0.55 * lambert + 0.1 * side
    return (result.image * factor[..., None]).astype(np.float32)


def cmd_info(args) -> int:
    from voxfield.scene.loaders import npz_kind
    from voxfield.svo.build import build_octree
    from voxfield.svo.io import load_octree

    path = Path(args.scene)
    if path.suffix.lower() == ".npz" and path.is_file() and npz_kind(path) == "octree":
        octree = load_octree(path)
        load_note = "loaded"
    else:
        from voxfield.scene.loaders import load_scene

        start = time.perf_counter()
        scene = load_scene(args.scene, _scene_options(args))
        load_seconds = time.perf_counter() - start
        octree = build_octree(scene, progress=not args.quiet)
        load_note = f"scene read in {load_seconds:.2f} s"
    lo, hi = octree.voxel_bounds
    info = {
        "name": octree.name,
        "depth": octree.depth,
        "root_size": octree.size,
        "voxels": octree.voxel_count,
        "nodes": octree.node_count,
        "extent": (hi - lo).tolist(),
        "nodes_per_level": octree.nodes_per_level(),
        "bytes_per_node": octree.bytes_per_node(),
        "channels": sorted("albedo" if k == "color" else k for k in octree.attributes),
        "build_seconds": octree.build_seconds,
    }
    if args.json:
        print(json.dumps(info, indent=2))
        return 0
    print(f"{info['name']}: {info['voxels']:,} voxels, extent {info['extent']}, "
          f"depth {info['depth']} (root {info['root_size']}^3), {load_note}")
    print(f"built in {info['build_seconds']:.3f} s; {info['nodes']:,} nodes; "
          f"channels: {', '.join(info['channels'])}")
    print(f"{'level':>5} {'lod':>4} {'nodes':>12} {'node size':>10}")
    for level, count in enumerate(info["nodes_per_level"]):
        lod = octree.depth - level
        print(f"{level:>5} {lod:>4} {count:>12,} {1 << lod:>10}")
    per = info["bytes_per_node"]
    parts = ", ".join(f"{k} {v:.1f}" for k, v in per.items() if k != "total")
    print(f"bytes per node: {per['total']:.1f} ({parts})")
    return 0


def cmd_build(args) -> int:
    from voxfield.svo.io import save_octree

    octree = _open_octree(args)
    path = save_octree(octree, args.out)
    if not args.quiet:
        print(f"{octree.voxel_count:,} voxels, {octree.node_count:,} nodes, depth {octree.depth}, "
              f"built in {octree.build_seconds:.2f} s; wrote {path}")
    return 0


def cmd_scenes(args) -> int:
    from voxfield.scene.builtin import BUILTIN_SCENES

    print("built-in scenes (no files needed):")
    for name, make in sorted(BUILTIN_SCENES.items()):
        doc = (make.__doc__ or "").strip().splitlines()[0]
        print(f"  builtin:{name:<10} {doc}")
    try:
        from voxfield.scene.terrain import RECIPES
    except ImportError:
        return 0
    print("terrain recipes over the shared DEMs (see README):")
    for name, recipe in RECIPES.items():
        print(f"  terrain:{name:<10} {recipe.description}")
    return 0


def _parse_mask(text: str) -> int:
    try:
        value = int(text, 0)
    except ValueError:
        message = f"a child mask is 0..255 (e.g. 15, 0x0f, 0b1111), got {text!r}"
        raise argparse.ArgumentTypeError(message) from None
    if not 0 <= value <= 255:
        raise argparse.ArgumentTypeError(f"a child mask is 0..255, got {value}")
    return value


def cmd_errors_build(args) -> int:
    from voxfield.error_table import build_error_table, fit_report, save_error_table
    from voxfield.error_table.table import DEFAULT_TABLE

    table = build_error_table(
        n_directions=args.directions, resolution=args.resolution,
        oct_resolution=args.oct_resolution, seed=args.seed, progress=not args.quiet,
    )
    out = Path(args.out) if args.out else DEFAULT_TABLE
    save_error_table(table, out)
    if not args.quiet:
        p = table.params
        print(f"256 masks × {p['n_directions']} directions (+ {p['oct_resolution']}² octahedral "
              f"texels) at {p['resolution']}² rays in {p['build_seconds']:.1f} s; wrote {out}")
        if args.report:
            _print_fit_report(fit_report(table))
    return 0


def cmd_errors_build_lighting(args) -> int:
    from voxfield.error_table.lighting import (
        DEFAULT_LIGHTING_TABLE,
        build_lighting_error_table,
        save_lighting_error_table,
    )

    table = build_lighting_error_table(resolution=args.resolution,
                                       oct_resolution=args.oct_resolution, seed=args.seed,
                                       progress=not args.quiet)
    out = Path(args.out) if args.out else DEFAULT_LIGHTING_TABLE
    save_lighting_error_table(table, out)
    if not args.quiet:
        p = table.params
        print(f"{p['configurations']} bright-flag configurations in {p['classes']} symmetry "
              f"classes × {p['oct_resolution']}² octahedral texels at {p['resolution']}² rays "
              f"in {p['build_seconds']:.1f} s; wrote {out}")
    return 0


def _print_fit_report(report: dict) -> None:
    print(f"fit against {report['n_holdout']} held-out directions (fresh ray casts), masks 1..255:")
    print(f"{'encoding':>9} {'max |err|':>10} {'rms':>8} {'mean |err|':>11}")
    for encoding in ("sh", "oct"):
        r = report[encoding]
        print(f"{encoding:>9} {r['max_abs']:>10.4f} {r['rms']:>8.4f} {r['mean_abs']:>11.4f}")


def cmd_errors_info(args) -> int:
    from voxfield.error_table import fit_report, load_error_table
    from voxfield.error_table.symmetry import distinct_mask_count

    table = load_error_table(args.table)
    p = table.params
    print(f"error table: {p.get('n_directions')} Fibonacci directions, {p.get('resolution')}² "
          f"rays per direction, seed {p.get('seed')}, octahedral maps {table.oct_resolution}², "
          f"default encoding {table.default_encoding}")
    print(f"child masks distinct under the 48 cube symmetries: {distinct_mask_count()} of 256")
    if args.report:
        _print_fit_report(fit_report(table))
    return 0


def cmd_errors_show(args) -> int:
    from voxfield.error_table import load_error_table
    from voxfield.error_table.plot import plot_mask_error

    table = load_error_table(args.table)
    out = args.out or f"out/error_mask_{args.mask}.png"
    path = plot_mask_error(table, args.mask, out, threshold=args.threshold,
                           encoding=args.encoding)
    if not args.quiet:
        print(f"wrote {path}")
    return 0


def cmd_calibrate(args) -> int:
    from voxfield.atomic import atomic_path
    from voxfield.studies.calibrate import calibrate_threshold

    octree = _open_octree(args)
    camera = _camera(args, octree)
    cal = calibrate_threshold(
        octree, camera, target_rays=args.target_rays, target_psnr=args.target_psnr,
        decay=args.decay, base_lod=args.base_lod, iterations=args.iterations, seed=args.seed,
        channel=args.channel, progress=not args.quiet,
    )
    if args.out:
        with atomic_path(args.out) as tmp:
            tmp.write_text(json.dumps(cal.as_dict(), indent=2))
    if not args.quiet:
        quality = f", PSNR {cal.psnr:.2f} dB" if np.isfinite(cal.psnr) else ""
        print(f"threshold {cal.threshold:.4f} (decay {args.decay}): {cal.rays:,} rays, "
              f"{cal.steps:,} steps{quality}; {len(cal.trail)} renders")
    return 0


def _float_list(text: str) -> tuple[float, ...]:
    try:
        values = tuple(float(v) for v in text.split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected numbers like 0.1,0.2, got {text!r}") from None
    if not values:
        raise argparse.ArgumentTypeError("expected at least one number")
    return values


def cmd_sweep(args) -> int:
    from voxfield.studies.sweep import run_sweep

    octree = _open_octree(args)
    camera = _camera(args, octree)
    out = args.out or f"out/sweep_{Path(args.scene).stem.replace(':', '_')}"
    report = run_sweep(octree, camera, out, decays=args.decays, thresholds=args.thresholds,
                       base_lod=args.base_lod, seed=args.seed, channel=args.channel,
                       scene_name=args.scene, progress=not args.quiet, fresh=args.fresh)
    if not args.quiet:
        print(f"adaptive: {report['adaptive']['rays']:,} rays; per decay, the threshold "
              "closest to it:")
        for pick in report["closest_to_adaptive"]:
            print(f"  d={pick['decay']}: t={pick['threshold']} → {pick['rays']:,} rays, "
                  f"PSNR {pick['psnr']:.2f} dB")
        print(f"wrote {out}/results.md, results.json, sweep.png")
    return 0


def _add_view_options(p, size: int = 512) -> None:
    """Camera and image options shared by every command that renders, plus --quiet."""
    p.add_argument("--camera", default="top",
                   help="top (thesis setup, 90° looking down), oblique, orbit, ortho-top, "
                   "cube+x..cube-z (default top)")
    p.add_argument("--eye", type=_vector_arg, default=None, metavar="X,Y,Z",
                   help="pinhole eye position in octree voxel units (with --target)")
    p.add_argument("--target", type=_vector_arg, default=None, metavar="X,Y,Z")
    p.add_argument("--fov", type=float, default=None, help="vertical field of view in degrees")
    p.add_argument("--size", type=_positive_int, default=size,
                   help=f"image width = height (default {size})")
    p.add_argument("--quiet", action="store_true", default=argparse.SUPPRESS,
                   help="no progress bars or summaries")


def _add_sweep_parser(sub) -> None:
    from voxfield.studies.sweep import THESIS_DECAYS, THESIS_THRESHOLDS

    p = sub.add_parser(
        "sweep", help="decay × threshold grid of ray counts and quality (EA Table 5.1)",
        description="Render the error-aware renderer over a decay × threshold grid, beside "
        "the adaptive renderer and the 4×4 reference; resumable.",
    )
    _add_scene_options(p)
    p.add_argument("--decays", type=_float_list, default=THESIS_DECAYS,
                   help="comma-separated decays (default the thesis's 0.05..0.3)")
    p.add_argument("--thresholds", type=_float_list, default=THESIS_THRESHOLDS,
                   help="comma-separated thresholds (default the thesis's 0.175..0.05)")
    p.add_argument("--base-lod", type=_lod_arg, default=2, help="LOD of the first ray")
    p.add_argument("--out", default=None, help="output folder (default out/sweep_SCENE)")
    _add_channel_option(p)
    p.add_argument("--fresh", action="store_true", help="ignore cached cells")
    _add_view_options(p)
    p.set_defaults(func=cmd_sweep)


def _add_calibrate_parser(sub) -> None:
    p = sub.add_parser(
        "calibrate", help="solve for the error threshold meeting a ray budget or PSNR",
        description="Bisection on the error-aware renderer's threshold (EA §5.1.4): the "
        "smallest threshold within a ray budget, or the largest meeting a PSNR target.",
    )
    _add_scene_options(p)
    target = p.add_mutually_exclusive_group(required=True)
    target.add_argument("--target-rays", type=_positive_int, help="ray budget for the image")
    target.add_argument("--target-psnr", type=float, help="PSNR target in dB vs the reference")
    p.add_argument("--decay", type=float, default=0.2, help="decay factor d (default 0.2)")
    p.add_argument("--base-lod", type=_lod_arg, default=2, help="LOD of the first ray")
    p.add_argument("--iterations", type=_positive_int, default=14, help="bisection steps")
    p.add_argument("--out", default=None, help="write the result and trail as JSON")
    _add_channel_option(p)
    _add_view_options(p)
    p.set_defaults(func=cmd_calibrate)


def _add_table_raycast_options(p: argparse.ArgumentParser) -> None:
    p.add_argument("--resolution", type=_positive_int, default=512,
                   help="framebuffer side in rays per direction (default 512, as the thesis)")
    p.add_argument("--oct-resolution", type=_positive_int, default=32,
                   help="octahedral map side in texels (default 32)")
    p.add_argument("--seed", type=int, default=0, help="CMJ jitter seed")


def _add_errors_parser(sub) -> None:
    errors = sub.add_parser(
        "errors", help="error tables: build, inspect, picture one mask",
        description="The error of sampling a node instead of its children (EA §3.1–3.2).",
    )
    esub = errors.add_subparsers(dest="errors_command", required=True, metavar="ACTION")
    quiet = {"action": "store_true", "default": argparse.SUPPRESS,
             "help": "no progress bars or summaries"}

    p = esub.add_parser("build", help="ray-cast the table for all 256 masks and fit encodings",
                        description="Ray-cast e = 1 - hits(children)/hits(parent) for every "
                        "child mask over a Fibonacci set of directions (CMJ-jittered "
                        "orthographic rays), fit 9 SH coefficients and octahedral maps.")
    p.add_argument("--directions", type=_positive_int, default=1024,
                   help="Fibonacci directions for the SH fit (default 1024; thesis 256)")
    _add_table_raycast_options(p)
    p.add_argument("--out", default=None,
                   help="output file (default: the table shipped with the package)")
    p.add_argument("--report", action="store_true",
                   help="also measure both encodings against held-out directions")
    p.add_argument("--quiet", **quiet)
    p.set_defaults(func=cmd_errors_build)

    p = esub.add_parser(
        "build-lighting", help="ray-cast the lighting-aware (bright-flag) colour error table",
        description="Ray-cast the colour error of every child mask with every subset of "
        "children flagged bright (EA §6.1), one octahedral map per cube-symmetry class.")
    _add_table_raycast_options(p)
    p.add_argument("--out", default=None,
                   help="output file (default: the lighting table shipped with the package)")
    p.add_argument("--quiet", **quiet)
    p.set_defaults(func=cmd_errors_build_lighting)

    p = esub.add_parser("info", help="parameters of a table, symmetry classes, fit quality",
                        description="Describe an error table.")
    p.add_argument("--table", default=None, help="table file (default: the packaged one)")
    p.add_argument("--report", action="store_true", help="measure both encodings' fit")
    p.add_argument("--quiet", **quiet)
    p.set_defaults(func=cmd_errors_info)

    p = esub.add_parser("show", help="picture one mask's error over the sphere (EA fig. 3.2)",
                        description="Child configuration and three views of the error sphere, "
                        "directions above the threshold marked red.")
    p.add_argument("mask", type=_parse_mask, help="child mask 0..255 (bit c = x | y<<1 | z<<2)")
    p.add_argument("--threshold", type=float, default=0.154,
                   help="error threshold to mark (default 0.154, the thesis's calibration)")
    p.add_argument("--encoding", choices=("oct", "sh"), default=None,
                   help="encoding to show (default: the table's default)")
    p.add_argument("--table", default=None, help="table file (default: the packaged one)")
    p.add_argument("--out", default=None, help="output PNG (default out/error_mask_MASK.png)")
    p.add_argument("--quiet", **quiet)
    p.set_defaults(func=cmd_errors_show)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="voxfield",
        description="Sparse voxel octrees with error-aware LOD, light probes and ray queries.",
    )
    parser.add_argument("--quiet", action="store_true", help="no progress bars or summaries")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")

    p = sub.add_parser("render", help="render a scene to PNG or EXR",
                       description="Trace a scene with the reference or LOD renderer.")
    _add_scene_options(p)
    p.add_argument("--renderer", choices=("reference", "lod", "error-aware", "adaptive"),
                   default="reference",
                   help="reference (4×4 rays, LOD 0), lod (1 ray, fixed/cone LOD), error-aware "
                   "(EA §5.1.3) or adaptive (variance baseline, EA §5.1.2)")
    _add_view_options(p)
    p.add_argument("--spp-side", type=_positive_int, default=4,
                   help="reference: side of the CMJ sample grid per pixel (default 4 → 16 rays)")
    p.add_argument("--lod", type=_lod_arg, default=None,
                   help="lod renderer: a fixed LOD (0 = voxels) or 'cone' (default)")
    p.add_argument("--cone-scale", type=float, default=1.0,
                   help="lod renderer, cone mode: node size accepted per pixel footprint")
    p.add_argument("--threshold", type=float, default=0.154,
                   help="error-aware: refinement threshold (default 0.154, EA §5.1.4)")
    p.add_argument("--decay", type=float, default=0.2,
                   help="error-aware: weight of the children's error (default 0.2)")
    p.add_argument("--base-lod", type=_lod_arg, default=2,
                   help="error-aware/adaptive: LOD of the first ray, or 'cone' (default 2)")
    p.add_argument("--refinements", type=int, default=2,
                   help="error-aware: maximum 2×2 refinements per pixel (default 2 → ≤ 21 rays)")
    p.add_argument("--encoding", choices=("oct", "sh"), default=None,
                   help="error-aware: error-table encoding (default: the table's)")
    p.add_argument("--reuse-parent", action="store_true",
                   help="error-aware: continue a refined ray as one of its 4 sub-rays (EA §6.2)")
    p.add_argument("--lighting-aware", action="store_true",
                   help="error-aware: add the bright-flag colour error (EA §6.1)")
    p.add_argument("--bright-ratio", type=float, default=0.25,
                   help="lighting-aware: a child is bright above (1 + R) × its parent's "
                   "luminance (default 0.25)")
    p.add_argument("--iterations", type=int, default=1,
                   help="adaptive: refinement iterations (default 1, as the thesis)")
    p.add_argument("--channel", default="albedo", help="colour channel to show (default albedo)")
    p.add_argument("--threads", type=_positive_int, default=None, help="kernel threads")
    p.add_argument("--shade", action="store_true",
                   help="light the albedo with a fixed key light (display only, not for metrics)")
    p.add_argument("--counters", action="store_true",
                   help="also write traversal-step and LOD maps and a JSON summary")
    p.add_argument("--out", required=True, help="output .png (sRGB) or .exr (linear RGB + Z)")
    p.set_defaults(func=cmd_render)

    p = sub.add_parser("info", help="build a scene's octree and print its structure",
                       description="Levels, node counts per level, bytes per node, build time.")
    _add_scene_options(p)
    p.add_argument("--json", action="store_true", help="print JSON")
    p.add_argument("--quiet", action="store_true", default=argparse.SUPPRESS,
                   help="no progress bars or summaries")
    p.set_defaults(func=cmd_info)

    p = sub.add_parser("build", help="build a scene's octree and save it (.npz)",
                       description="Build the SVO once and save it for fast reuse.")
    _add_scene_options(p)
    p.add_argument("--out", required=True, help="output octree file (.npz)")
    p.add_argument("--quiet", action="store_true", default=argparse.SUPPRESS,
                   help="no progress bars or summaries")
    p.set_defaults(func=cmd_build)

    _add_errors_parser(sub)
    _add_calibrate_parser(sub)
    _add_sweep_parser(sub)
    from voxfield.lightfield.cli_probe_render import add_probe_render_parser
    from voxfield.lighting.cli_light import add_light_parser
    from voxfield.probes.cli_probes import add_probe_parsers
    from voxfield.render.cli_shadow import add_shadow_parser
    from voxfield.studies.cli_compare import add_compare_parser
    from voxfield.studies.cli_study import add_study_parser

    add_compare_parser(sub)
    add_study_parser(sub)
    add_light_parser(sub)
    add_shadow_parser(sub)
    add_probe_parsers(sub)
    add_probe_render_parser(sub)

    p = sub.add_parser("scenes", help="list built-in scenes and terrain recipes",
                       description="Scenes that need no files, and terrain recipes.")
    p.set_defaults(func=cmd_scenes)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    args.quiet = getattr(args, "quiet", False)
    try:
        return args.func(args)
    except VoxfieldError as exc:
        print(f"voxfield: error: {exc}", file=sys.stderr)
        return EXIT_USAGE
    except KeyboardInterrupt:
        print("voxfield: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
