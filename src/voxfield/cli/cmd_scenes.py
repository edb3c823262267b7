"""``voxfield info``, ``build`` and ``scenes``: what a scene becomes as an octree, saving it,
and the scenes that need no files."""

from __future__ import annotations

import json
import time
from pathlib import Path

from voxfield.cli.commands import add_command, add_quiet
from voxfield.cli.options import (
    add_scene_options,
    is_saved_octree,
    note_unread_scene_options,
    open_octree,
    output_named,
)
from voxfield.scene.builtin import BUILTIN_SCENES
from voxfield.scene.terrain import RECIPES
from voxfield.scene.terrain.dem import SAMPLE_DEMS
from voxfield.svo.io import load_octree, save_octree


def register(subparsers) -> None:
    p = add_command(subparsers, "info",
                    description="Levels, node counts per level, bytes per node, build time.")
    add_scene_options(p)
    p.add_argument("--json", action="store_true", help="print JSON")
    add_quiet(p)
    p.set_defaults(func=run_info)

    p = add_command(subparsers, "build",
                    description="Build the SVO once and save it for fast reuse.")
    add_scene_options(p)
    p.add_argument("--out", required=True, help="output octree file (.npz)")
    add_quiet(p)
    p.set_defaults(func=run_build)

    p = add_command(subparsers, "scenes",
                    description="Scenes that need no files, and terrain recipes.")
    p.set_defaults(func=run_scenes)


def run_info(args) -> int:
    path = Path(args.scene)
    if is_saved_octree(args.scene):
        octree = load_octree(path)
        note_unread_scene_options(args, args.scene)
        load_note = "loaded"
    else:
        # As every command opens a scene: terrains stream block by block (bounded memory,
        # Ctrl-C heard between blocks), --lod-colour and --colour-storage apply.
        start = time.perf_counter()
        octree = open_octree(args)
        load_note = f"scene opened in {time.perf_counter() - start:.2f} s"
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
        "channels": octree.channel_names,
        "build_seconds": None if load_note == "loaded" else octree.build_seconds,
    }
    if args.json:
        print(json.dumps(info, indent=2))
        return 0
    print(f"{info['name']}: {info['voxels']:,} voxels, extent {info['extent']}, "
          f"depth {info['depth']} (root {info['root_size']}^3), {load_note}")
    built = "" if info["build_seconds"] is None else f"built in {info['build_seconds']:.3f} s; "
    print(f"{built}{info['nodes']:,} nodes; channels: {', '.join(info['channels'])}")
    print(f"{'level':>5} {'lod':>4} {'nodes':>12} {'node size':>10}")
    for level, count in enumerate(info["nodes_per_level"]):
        lod = octree.depth - level
        print(f"{level:>5} {lod:>4} {count:>12,} {1 << lod:>10}")
    per = info["bytes_per_node"]
    parts = ", ".join(f"{k} {v:.1f}" for k, v in per.items() if k != "total")
    print(f"bytes per node: {per['total']:.1f} ({parts})")
    return 0


def run_build(args) -> int:
    output_named(args.out, ".npz", "an octree", source=args.scene)  # before the build
    octree = open_octree(args)
    path = save_octree(octree, args.out)
    if not args.quiet:
        print(f"{octree.voxel_count:,} voxels, {octree.node_count:,} nodes, depth {octree.depth}, "
              f"built in {octree.build_seconds:.2f} s; wrote {path}")
    return 0


def run_scenes(args) -> int:
    builtin = {f"builtin:{name}": (make.__doc__ or "").strip().splitlines()[0]
               for name, make in sorted(BUILTIN_SCENES.items())}
    terrain = {f"terrain:{name}": recipe.description for name, recipe in RECIPES.items()}
    dems = {f"dem:{name}": f"matplotlib's sample DEM {file}, as a terrain"
            for name, file in SAMPLE_DEMS.items()}
    width = max(map(len, [*builtin, *terrain, *dems]))
    for title, names in (("built-in scenes (no files needed)", builtin),
                         ("terrain recipes over the shared DEMs (see README)", terrain),
                         ("sample DEMs (no files needed)", dems)):
        print(f"{title}:")
        for name, text in names.items():
            print(f"  {name:<{width}} {text}")
    return 0
