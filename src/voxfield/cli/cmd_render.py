"""``voxfield render``: one image of a scene with any registered renderer."""

from __future__ import annotations

import argparse
import dataclasses
import sys

from voxfield.atomic import atomic_paths
from voxfield.cli.commands import add_command
from voxfield.cli.options import (
    add_display_options,
    add_renderer_options,
    add_scene_options,
    add_view_options,
    check_base_lod,
    display_shaded,
    open_octree,
    positive_int,
    renderer_options_from,
    scene_camera,
)
from voxfield.render.counter_maps import counter_map_paths, write_counter_files
from voxfield.render.device import CUDA_RENDERERS, DEVICES, check_device
from voxfield.render.image_io import check_image_output, save_result_image, shade_for_display
from voxfield.render.placement import view_note
from voxfield.render.registry import RENDERERS, render


def register(subparsers) -> argparse.ArgumentParser:
    p = add_command(
        subparsers, "render",
        description="Trace a scene with any of voxfield's renderers.")
    add_scene_options(p)
    p.add_argument("--renderer", choices=tuple(RENDERERS), default="reference",
                   help="; ".join(f"{name}: {entry.summary}" for name, entry in RENDERERS.items())
                   + " (default reference)")
    add_view_options(p)
    add_renderer_options(p, ("reference", "lod", "error-aware", "adaptive"))
    p.add_argument("--channel", default="albedo", help="colour channel to show (default albedo)")
    p.add_argument("--threads", type=positive_int, default=None, help="kernel threads")
    p.add_argument("--device", choices=DEVICES, default="cpu",
                   help="where the rays are traced: cpu (default) or cuda (an NVIDIA GPU, "
                   f"`pip install voxfield[cuda]`; renderers {', '.join(CUDA_RENDERERS)}); "
                   "the same image either way")
    add_display_options(p)
    p.add_argument("--counters", action="store_true",
                   help="also write maps of traversal steps, finest LOD and rays per pixel, "
                        "and a JSON summary")
    p.add_argument("--out", required=True, help="output .png (sRGB) or .exr (linear RGB + Z)")
    p.set_defaults(func=run)
    return p


def run(args) -> int:
    check_device(args.device, args.renderer)  # before the scene loads: fail fast
    out = check_image_output(args.out)
    octree = open_octree(args)
    if any(f.name == "base_lod" for f in dataclasses.fields(RENDERERS[args.renderer].options_type)):
        check_base_lod(args, octree)  # the renderer's message named no option
    view = scene_camera(args, octree)
    note = view_note(octree, view)
    if note is not None:
        print(f"voxfield: note: {note}", file=sys.stderr)
    on_gpu = {"device": "cuda"} if args.device == "cuda" else {}
    result = render(octree, view, args.renderer, renderer_options_from(args, args.renderer),
                    seed=args.seed, channel=args.channel, threads=args.threads,
                    progress=not args.quiet, **on_gpu)
    if display_shaded(args, out, args.channel):
        result.image = shade_for_display(result)
    # The image and its counter maps appear together or not at all (a full disk part way).
    written = [out] + (counter_map_paths(out) if args.counters else [])
    with atomic_paths(written) as staged:
        save_result_image(result, staged[0])
        if args.counters:
            write_counter_files(result, staged[1:], octree.depth)
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
