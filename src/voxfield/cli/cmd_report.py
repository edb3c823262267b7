"""``voxfield report``: rebuild a study folder's ``report.html`` from what the folder holds."""

from __future__ import annotations

from pathlib import Path

from voxfield.cli.commands import add_command, add_quiet
from voxfield.studies.html_report import write_html_report
from voxfield.studies.study_mark import STUDY_FIGURES, read_study_mark


def register(subparsers) -> None:
    p = add_command(
        subparsers, "report",
        description="Rebuild FOLDER/report.html (one self-contained page: each image beside "
        "the reference with a slider, difference and cost maps, the figures and the tables) "
        "from the folder's results.json, results.md and images. Studies, compare and sweep "
        "write it themselves; this refreshes an older folder. A figure the study drew that "
        "is gone from the folder is named in a note and marked missing on the page.",
    )
    p.add_argument("folder", help="a folder written by compare, sweep, shadows or study")
    add_quiet(p)
    p.set_defaults(func=run_report)


def run_report(args) -> int:
    folder = Path(args.folder)
    path = write_html_report(folder, expected=expected_figures(folder))
    if not args.quiet:
        print(f"wrote {path}")
    return 0


def expected_figures(folder: Path) -> list[str]:
    """The PNGs the folder should hold, from its study mark: the figures its study draws on
    every run and those its last report showed. A figure deleted since was left out of the
    rebuilt page without a word. A folder without a readable mark (an older voxfield's)
    expects none: the page then shows what is there, as before."""
    mark = read_study_mark(folder)
    study = mark.get("study")
    names = set(STUDY_FIGURES.get(study, ())) if isinstance(study, str) else set()
    published = mark.get("report")
    if isinstance(published, list):
        names |= {n for n in published if isinstance(n, str) and n.endswith(".png")}
    return sorted(names)
