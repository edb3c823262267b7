"""``voxfield light``: bake sun lighting for times of day into an octree file."""

from __future__ import annotations

import argparse
import json
import warnings
from collections.abc import Sequence
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np

from voxfield.atomic import atomic_paths, check_writable, write_figure_png
from voxfield.cli.commands import add_command, add_quiet
from voxfield.cli.options import (
    add_scene_options,
    default_output,
    int_between,
    is_saved_octree,
    open_octree,
    output_named,
    positive_int,
    scheduler_name,
    warn_ignored,
)
from voxfield.json_output import json_text
from voxfield.lighting.sun import parse_suns
from voxfield.lighting.sun_bake import MAX_RAYS, bake_sun_lighting
from voxfield.render.camera import top_down_camera
from voxfield.render.image_io import png_bytes
from voxfield.render.primary import render_reference
from voxfield.scaleout import SCHEDULER_HELP, check_scheduler
from voxfield.studies.figures import Panel, contact_sheet
from voxfield.studies.report import scene_title
from voxfield.svo.io import write_octree_file

#: Side of each sun's top-down preview PNG unless ``--preview-size`` says.
PREVIEW_SIZE = 256


def register(subparsers) -> argparse.ArgumentParser:
    """Register ``light`` on the main parser's sub-commands (scene options as ``render``)."""
    p = add_command(
        subparsers, "light",
        description="Per voxel and sun: lit colour = albedo × (sun × cos θ × shadow-ray "
        "visibility + sky × cosine-weighted sky visibility), traced through the octree at "
        "LOD 0 and stored as one channel per sun next to the albedo (render it with "
        "--channel NAME). Coarse levels average the voxels that see the sky. Writes the "
        "octree file, a top-down preview per sun, a labelled sheet of them all "
        "(NAME.png, beside NAME.npz) and a JSON cost report.",
    )
    add_scene_options(p)
    p.add_argument(
        "--times", default="all", metavar="SUNS",
        help="times of day: morning, noon, afternoon, evening, comma-separated (the thesis's "
        "time0, time1, time2, time3 are morning, evening, noon, afternoon, and bake the "
        "channel of that name); or suns as AZ,EL / NAME=AZ,EL in degrees (azimuth clockwise from "
        "north = -z, east = +x), ';'-separated (default all four times)",
    )
    p.add_argument("--sky-rays", type=int_between(0, MAX_RAYS, "rays per voxel"), default=16,
                   metavar="K", help=f"cosine-weighted sky rays per surface voxel, 0..{MAX_RAYS};"
                   " 0 turns sky light off (black shadows, as the thesis's data) (default 16)")
    p.add_argument("--shadow-rays", type=int_between(1, MAX_RAYS, "rays per face"), default=4,
                   metavar="R", help=f"shadow rays per sun-facing voxel face, stratified over "
                   f"the face, 1..{MAX_RAYS} (default 4; 1 = one from the face centre)")
    p.add_argument("--threads", type=positive_int, default=None, help="kernel threads")
    p.add_argument("--scheduler", type=scheduler_name, default=None, metavar="WHERE",
                   help=SCHEDULER_HELP + "; voxel chunks become tasks, the result is "
                   "bit-identical (default: serial, each chunk on every core here)")
    p.add_argument("--out", default=None,
                   help="output octree file (default out/lit_NAME.npz, NAME from the scene)")
    p.add_argument("--preview-size", type=int_between(1, 4096, "pixels per side"),
                   default=None, metavar="N",  # None: not given (noted under --no-preview)
                   help=f"side of the top-down preview PNG per sun, 1..4096 (default "
                   f"{PREVIEW_SIZE})")
    p.add_argument("--no-preview", action="store_true", help="write no preview images")
    add_quiet(p)
    p.set_defaults(func=run)
    return p


def run(args) -> int:
    suns = parse_suns(args.times)  # before the (slow) scene load: bad input fails fast
    check_scheduler(args.scheduler)
    out = output_named(args.out or default_output("lit", args.scene, ".npz"), ".npz",
                       "a lit octree", source=_replaceable(args.scene))
    # Every output, checked before the scene opens: a folder or a name too long where a
    # preview or the record goes failed after the bake (20 s on a 2048² terrain).
    channels = [] if args.no_preview else [s.name for s in suns]
    written = [out, out.with_suffix(".json"),
               *(out.with_name(f"{out.stem}_{name}.png") for name in channels),
               *([out.with_suffix(".png")] if channels else [])]  # no channel's name
    for path in written[1:]:
        check_writable(path)
    args.quiet = quiet = getattr(args, "quiet", False)  # as ``voxfield.cli.main`` sets it
    if args.no_preview and args.preview_size is not None:
        warn_ignored({"--preview-size": ["the previews"]}, "a bake with --no-preview")
    preview_size = args.preview_size or PREVIEW_SIZE
    octree = open_octree(args)
    names = [s.name for s in suns]
    replaced = [name for name in names if name in octree.attributes]
    if replaced:
        warnings.warn(f"{args.scene} already has channel{'s' if len(replaced) > 1 else ''} "
                      f"{', '.join(replaced)}; this bake replaces "
                      f"{'them' if len(replaced) > 1 else 'it'}", stacklevel=2)
    kept = [name for name in octree.attributes
            if name not in NOT_LIGHT and name not in names]
    lit, report = bake_sun_lighting(
        octree, suns, sky_rays=args.sky_rays, shadow_rays=args.shadow_rays, seed=args.seed,
        threads=args.threads, progress=not quiet, scheduler=args.scheduler,
    )
    details = {
        "scene": args.scene,
        "octree": str(out),
        "suns": [
            {"name": s.name, "azimuth_deg": s.azimuth_deg, "elevation_deg": s.elevation_deg,
             "irradiance": list(s.irradiance), "sky": list(s.sky)}
            for s in suns
        ],
        "seed": args.seed,
        "cost": report.as_dict(),
        **kept_record(args.scene, kept, replaced, out, written),
    }
    # The octree file (a gigabyte on a 2048² terrain) is written by a thread while the
    # previews render in memory (writing is mostly the kernel copying pages, which leaves
    # the GIL free). Every output is staged and all are committed together once all are
    # ready: a failure or Ctrl-C leaves none of them, nor a temporary file.
    if channels:
        details["previews"] = {**{path.name: [name] for path, name in
                                  zip(written[2:], channels, strict=False)},
                               written[-1].name: channels}
    stale = stale_previews(out, written, kept if _in_place(args.scene, out) else [])
    if stale:
        details["stale_previews"] = [path.name for path in stale]
    with atomic_paths(written) as staged, ThreadPoolExecutor(1) as writer:
        saving = writer.submit(write_octree_file, lit, staged[0])
        staged[1].write_text(json_text(details))
        if channels:
            previews = render_previews(lit, channels, size=preview_size,
                                       threads=args.threads)
            for tmp, (_, image) in zip(staged[2:], previews, strict=False):
                tmp.write_bytes(png_bytes(image))
            sheet = preview_sheet(previews, suns, args.scene)
            write_figure_png(sheet, staged[-1], dpi=100)
        saving.result()  # raises the save's error; leaving waits for the thread either way
    if stale:
        warnings.warn(f"{', '.join(p.name for p in stale)} beside {out} "
                      f"{'are previews' if len(stale) > 1 else 'is a preview'} of an earlier "
                      f"bake that no longer {'match' if len(stale) > 1 else 'matches'} it; "
                      f"left as {'they are' if len(stale) > 1 else 'it is'}", stacklevel=2)
    if not quiet:
        print(report.summary())
        for path in written:
            print(f"wrote {path}")
    return 0


#: Attributes of an octree that are not light channels: the albedo and the emission.
NOT_LIGHT = ("color", "emission")


def read_record(octree_path: Path) -> dict | None:
    """The JSON ``light`` wrote beside a lit octree, or None where there is none that reads
    as one."""
    try:
        record = json.loads(octree_path.with_suffix(".json").read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    if not isinstance(record, dict) or not isinstance(record.get("suns"), list):
        return None
    return record


def _own_previews(bake: dict, out: Path, kept: list[str], written: Sequence[Path]) -> dict:
    """A bake's ``previews`` entry, kept only where the bake wrote them beside ``out``, and
    only the files that still show it: still there, not written again by this bake, and
    showing only channels of it that ``out`` keeps (``kept``). Kept whole, the entry named
    files this bake overwrote (the sheet, now of its suns) or that were gone; the dropped
    files still there are named in ``stale_previews``. Empty: none of its previews is
    left."""
    octree, previews = bake.get("octree"), bake.get("previews")
    if not (isinstance(octree, str) and Path(octree).name == out.name
            and isinstance(previews, dict)):
        return {}
    return {"previews": {
        name: shows for name, shows in previews.items()
        if isinstance(name, str) and name and Path(name).name == name
        and out.with_name(name) not in written and out.with_name(name).is_file()
        and isinstance(shows, list) and set(shows) <= set(kept)}}


def kept_record(scene: str, kept: list[str], replaced: list[str], out: Path,
                written: Sequence[Path] = ()) -> dict:
    """What the record of a bake over a lit octree adds for the channels it keeps: the
    earlier bakes that made them (from the JSON beside the octree, newest first, each
    with only the suns whose channels are kept: its seed and rays made them), the kept
    channels no record names, and the channels this bake replaced. A record that listed
    only the new suns lost the suns behind the kept channels. A note names kept channels
    of a lit octree whose suns are not on record; a voxel scene's own channels, which no
    sun made, are listed as ``scene_channels``. ``written``: the files this bake writes,
    whose earlier contents no earlier bake's ``previews`` may name."""
    extra: dict = {"replaced": replaced} if replaced else {}
    if not kept:
        return extra
    if not is_saved_octree(scene):  # channels a scene file brought: no bake made them
        return {**extra, "scene_channels": kept}
    record = read_record(Path(scene)) or {}
    # Previews are files beside the octree a bake wrote: those of another octree's bakes
    # are not this one's to judge (they stay true of that octree, and lie beside it).
    here = _in_place(scene, out)
    bakes = [{k: v for k, v in record.items()
              if k not in ("earlier_bakes", "unrecorded_channels", "replaced",
                           "stale_previews")},
             *(b for b in record.get("earlier_bakes") or [] if isinstance(b, dict))]
    unclaimed = set(kept)
    earlier = []
    for bake in bakes:
        suns = [s for s in bake.get("suns") or [] if isinstance(s, dict)
                and s.get("name") in unclaimed]
        unclaimed -= {s["name"] for s in suns}
        if suns:
            earlier.append({**{k: v for k, v in bake.items() if k != "previews"},
                            "suns": suns,
                            **(_own_previews(bake, out, [s["name"] for s in suns], written)
                               if here else {})})
    if earlier:
        extra["earlier_bakes"] = earlier
    if unclaimed:
        unrecorded = [name for name in kept if name in unclaimed]
        extra["unrecorded_channels"] = unrecorded
        sidecar = Path(scene).with_suffix(".json")
        warnings.warn(f"no record of the suns behind channel{'s' if len(unrecorded) > 1 else ''}"
                      f" {', '.join(unrecorded)} of {scene} (none in {sidecar}); the new "
                      "record lists them as unrecorded", stacklevel=2)
    return extra


def stale_previews(out: Path, written: list[Path], kept: list[str]) -> list[Path]:
    """Previews an earlier ``light`` wrote beside ``out`` that are still there, are not
    written again now and no longer show the octree: each shows channels of the bake that
    wrote it (its record's ``previews``), and stays true only where that bake still owns
    every one of them in an octree lit again in place (``kept``: the channels this bake
    keeps as they are). A record without ``previews`` names its suns' previews and its
    sheet. They are named in a note, not removed: a file of that name may be the user's by
    now, and nothing here can tell for certain."""
    record = read_record(out)
    if record is None:
        return []
    stale: dict[Path, None] = {}
    bakes = [record, *(b for b in record.get("earlier_bakes") or [] if isinstance(b, dict))]
    for bake in bakes:
        owned = {s.get("name") for s in bake.get("suns") or [] if isinstance(s, dict)}
        previews = bake.get("previews")
        if not isinstance(previews, dict):
            if bake is not record:
                continue
            previews = {f"{out.stem}_{name}.png": [name] for name in owned}
            previews[f"{out.stem}.png"] = list(owned)
        for name, shows in previews.items():
            if not isinstance(name, str) or Path(name).name != name or not name:
                continue  # a record names files beside its octree, no others
            path = out.with_name(name)
            valid = isinstance(shows, list) and set(shows) <= owned & set(kept)
            if path.is_file() and path not in written and not valid:
                stale[path] = None
    for name in record.get("stale_previews") or []:
        if not isinstance(name, str) or Path(name).name != name or not name:
            continue
        path = out.with_name(name)
        if path.is_file() and path not in written:
            stale[path] = None
    return sorted(stale)


def _in_place(scene: str, out: Path) -> bool:
    """Whether ``out`` is the scene's own file: an octree lit again in place, whose record
    and previews lie beside it."""
    return out.is_file() and Path(scene).is_file() and out.samefile(scene)


def _replaceable(scene: str) -> str | None:
    """The scene file ``--out`` must not name: any but an octree (a lit octree may be lit
    again in place, the file is read whole before it is replaced)."""
    return None if is_saved_octree(scene) else scene


def preview_sheet(previews: list[tuple[str, np.ndarray]], suns, scene: str):
    """The previews side by side, each titled with its sun's name and position: the files
    alone say only the channel's name."""
    by_name = {sun.name: sun for sun in suns}
    panels = [Panel(f"{name}: azimuth {by_name[name].azimuth_deg:g}°, elevation "
                    f"{by_name[name].elevation_deg:g}°", image) for name, image in previews]
    return contact_sheet(panels, columns=min(len(panels), 4),
                         title=f"{scene_title(scene)}: baked sun and sky light from above, "
                               "north (-z) up")


def render_previews(octree, channels: list[str], *, size: int,
                    threads: int | None = None) -> list[tuple[str, np.ndarray]]:
    """A top-down reference render (2×2 rays per pixel) of each channel, as
    ``(channel, image)``."""
    lo, hi = octree.voxel_bounds
    camera = top_down_camera(lo, hi, size=size)
    return [(name, render_reference(octree, camera, side=2, channel=name,
                                    threads=threads).image) for name in channels]

