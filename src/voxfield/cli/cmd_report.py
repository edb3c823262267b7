"""``voxfield report``: rebuild a study folder's ``report.html`` from what the folder holds."""

from __future__ import annotations

from voxfield.cli.commands import add_command, add_quiet
from voxfield.studies.html_report import write_html_report


def register(subparsers) -> None:
    p = add_command(
        subparsers, "report",
        description="Rebuild FOLDER/report.html (one self-contained page: each image beside "
        "the reference with a slider, difference and cost maps, the figures and the tables) "
        "from the folder's results.json, results.md and images. Studies, compare and sweep "
        "write it themselves; this refreshes an older folder.",
    )
    p.add_argument("folder", help="a folder written by compare, sweep, shadows or study")
    add_quiet(p)
    p.set_defaults(func=run_report)


def run_report(args) -> int:
    path = write_html_report(args.folder)
    if not args.quiet:
        print(f"wrote {path}")
    return 0
