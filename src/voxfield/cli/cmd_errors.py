"""``voxfield errors build|build-lighting|info|show``: the error tables (EA §3.1–3.2, §6.1)."""

from __future__ import annotations

import argparse
import time
import warnings
from pathlib import Path

import numpy as np

from voxfield.cli.commands import add_command, add_quiet
from voxfield.cli.options import finite_float, int_between, output_named, seed_arg
from voxfield.error_table import build_error_table, fit_report, load_error_table, save_error_table
from voxfield.error_table.lighting_table import (
    DEFAULT_LIGHTING_TABLE,
    build_lighting_error_table,
    load_lighting_error_table,
    save_lighting_error_table,
)
from voxfield.error_table.plot import plot_mask_error
from voxfield.error_table.symmetry import distinct_mask_count
from voxfield.error_table.table import (
    DEFAULT_TABLE,
    ENCODINGS,
    LIGHTING_FORMAT,
    MAX_RESOLUTION,
    MIN_RESOLUTION,
    THESIS_THRESHOLD,
    table_format,
)
from voxfield.errors import VoxfieldError


def mask_arg(text: str) -> int:
    """A child mask, 0..255, in any Python integer notation."""
    try:
        value = int(text, 0)
    except ValueError:
        message = f"a child mask is 0..255 (e.g. 15, 0x0f, 0b1111), got {text!r}"
        raise argparse.ArgumentTypeError(message) from None
    if not 0 <= value <= 255:
        raise argparse.ArgumentTypeError(f"a child mask is 0..255, got {value}")
    return value


def _add_raycast_options(p: argparse.ArgumentParser) -> None:
    p.add_argument("--resolution",
                   type=int_between(MIN_RESOLUTION, MAX_RESOLUTION, "rays per direction side"),
                   default=512, help=f"framebuffer side in rays per direction, "
                   f"{MIN_RESOLUTION}..{MAX_RESOLUTION} (default 512, as the thesis)")
    p.add_argument("--oct-resolution", type=int_between(2, 256, "texels a side"), default=32,
                   help="octahedral map side in texels, 2..256 (default 32)")
    p.add_argument("--seed", type=seed_arg, default=0, help="CMJ jitter seed")


def register(subparsers) -> None:
    errors = add_command(
        subparsers, "errors",
        description="The error of sampling a node instead of its children (EA §3.1–3.2).",
    )
    actions = errors.add_subparsers(dest="errors_command", required=True, metavar="ACTION")

    p = actions.add_parser("build", help="ray-cast the table for all 256 masks and fit encodings",
                           description="Ray-cast e = 1 - hits(children)/hits(parent) for every "
                           "child mask over a Fibonacci set of directions (CMJ-jittered "
                           "orthographic rays), fit 9 SH coefficients and octahedral maps.")
    p.add_argument("--directions", type=int_between(16, 65536, "each is a full ray cast"),
                   default=1024, help="Fibonacci directions for the SH fit, 16..65536 "
                   "(default 1024; thesis 256)")
    _add_raycast_options(p)
    p.add_argument("--out", default=None,
                   help="output .npz file (default: the table shipped with the package)")
    p.add_argument("--report", action="store_true",
                   help="also measure both encodings against held-out directions")
    add_quiet(p)
    p.set_defaults(func=run_build)

    p = actions.add_parser(
        "build-lighting", help="ray-cast the lighting-aware (bright-flag) colour error table",
        description="Ray-cast the colour error of every child mask with every subset of "
        "children flagged bright (EA §6.1), one octahedral map per cube-symmetry class.")
    _add_raycast_options(p)
    p.add_argument("--out", default=None,
                   help="output .npz file (default: the lighting table shipped with the "
                   "package)")
    add_quiet(p)
    p.set_defaults(func=run_build_lighting)

    p = actions.add_parser("info", help="parameters of a table, symmetry classes, fit quality",
                           description="Describe an error table or a lighting error table.")
    p.add_argument("--table", default=None, help="error table or lighting error table file "
                   "(default: the packaged error table)")
    p.add_argument("--report", action="store_true",
                   help="measure both encodings' fit (error tables)")
    add_quiet(p)
    p.set_defaults(func=run_info)

    p = actions.add_parser("show", help="picture one mask's error over the sphere (EA fig. 3.2)",
                           description="Child configuration and three views of the error "
                           "sphere, directions above the threshold marked red.")
    p.add_argument("mask", type=mask_arg, help="child mask 0..255 (bit c = x | y<<1 | z<<2)")
    p.add_argument("--threshold", type=finite_float, default=THESIS_THRESHOLD,
                   help=f"error threshold to mark (default {THESIS_THRESHOLD}, the thesis's "
                   "calibration)")
    p.add_argument("--encoding", choices=tuple(reversed(ENCODINGS)), default=None,
                   help="encoding to show (default: the table's default)")
    p.add_argument("--table", default=None, help="table file (default: the packaged one)")
    p.add_argument("--out", default=None, help="output PNG (default out/error_mask_MASK.png)")
    add_quiet(p)
    p.set_defaults(func=run_show)


def _table_output(out: str | None, default: Path) -> Path:
    """Where a built table goes: an ``.npz`` archive, whatever ``--out`` names (checked
    before the ray casts, which take minutes). Without ``--out`` it is the packaged table,
    said before the build: a quick trial build replaced, without a word, the table every
    error-aware render reads."""
    if not out:
        warnings.warn(f"no --out: the table built replaces the one voxfield ships ({default}), "
                      "which every error-aware render reads; give --out to keep it", stacklevel=2)
    return output_named(out if out else default, ".npz", "an error table")


def run_build(args) -> int:
    out = _table_output(args.out, DEFAULT_TABLE)
    start = time.perf_counter()
    table = build_error_table(
        n_directions=args.directions, resolution=args.resolution,
        oct_resolution=args.oct_resolution, seed=args.seed, progress=not args.quiet,
    )
    seconds = time.perf_counter() - start
    save_error_table(table, out)
    if not args.quiet:
        p = table.params
        print(f"256 masks × {p['n_directions']} directions (+ {p['oct_resolution']}² octahedral "
              f"texels) at {p['resolution']}² rays in {seconds:.1f} s; wrote {out}")
    if args.report:  # asked for by name: --quiet silences the progress, not the report
        _print_fit_report(fit_report(table))
    return 0


def run_build_lighting(args) -> int:
    out = _table_output(args.out, DEFAULT_LIGHTING_TABLE)
    start = time.perf_counter()
    table = build_lighting_error_table(resolution=args.resolution,
                                       oct_resolution=args.oct_resolution, seed=args.seed,
                                       progress=not args.quiet)
    seconds = time.perf_counter() - start
    save_lighting_error_table(table, out)
    if not args.quiet:
        p = table.params
        print(f"{p['configurations']} bright-flag configurations in {p['classes']} symmetry "
              f"classes × {p['oct_resolution']}² octahedral texels at {p['resolution']}² rays "
              f"in {seconds:.1f} s; wrote {out}")
    return 0


def _print_fit_report(report: dict) -> None:
    print(f"fit against {report['n_holdout']} held-out directions (fresh ray casts), masks 1..255:")
    print(f"{'encoding':>9} {'max |err|':>10} {'rms':>8} {'mean |err|':>11}")
    for encoding in ("sh", "oct"):
        r = report[encoding]
        print(f"{encoding:>9} {r['max_abs']:>10.4f} {r['rms']:>8.4f} {r['mean_abs']:>11.4f}")


def run_info(args) -> int:
    if args.table is not None and table_format(args.table) == LIGHTING_FORMAT:
        return _lighting_info(args)
    table = load_error_table(args.table)
    p = table.params
    print(f"error table: {p.get('n_directions')} Fibonacci directions, {p.get('resolution')}² "
          f"rays per direction, seed {p.get('seed')}, octahedral maps {table.oct_resolution}², "
          f"default encoding {table.default_encoding}")
    print(f"child masks distinct under the 48 cube symmetries: {distinct_mask_count()} of 256")
    if args.report:
        _print_fit_report(fit_report(table))
    return 0


def _lighting_info(args) -> int:
    """``errors info`` on a lighting table: what built it (its one encoding is octahedral)."""
    if args.report:
        raise VoxfieldError(f"--report measures an error table's two encodings; {args.table} "
                            "is a lighting error table, which has one (octahedral maps)")
    table = load_lighting_error_table(args.table)  # checksummed, as an error table is
    p = table.params
    configurations = int(np.count_nonzero(table.class_of >= 0))  # from the checksummed arrays
    print(f"lighting error table: {configurations:,} bright-flag configurations in "
          f"{table.class_count} symmetry classes, octahedral maps {p.get('oct_resolution')}², "
          f"{p.get('resolution')}² rays per texel, seed {p.get('seed')}")
    return 0


def run_show(args) -> int:
    out = output_named(args.out or f"out/error_mask_{args.mask}.png", ".png",
                       "the mask's picture")
    table = load_error_table(args.table)
    path = plot_mask_error(table, args.mask, out, threshold=args.threshold,
                           encoding=args.encoding)
    if not args.quiet:
        print(f"wrote {path}")
    return 0
