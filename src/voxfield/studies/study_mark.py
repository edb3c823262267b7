"""A study folder's mark (``study.json``): which study the folder holds and which report
files its last report published; and the figures each study draws. Read by the studies
(``report.StudyFolder``) and by ``voxfield report``, which must stay light to load."""

from __future__ import annotations

import json
from pathlib import Path

#: The file that names the study a folder holds (``StudyFolder``'s ``study``) and the
#: report files its last published report wrote.
STUDY_MARK = "study.json"

#: The figures each study (``StudyFolder``'s ``study``) writes on every run, under names of
#: its own: a folder in the way of one is refused with the report files.
STUDY_FIGURES = {
    "study thresholds": ("thresholds.png", "view.png"),
    "study resolution": ("resolution.png", "view.png"),
    "study lighting": ("lighting.png", "contact_sheet.png"),
    "study curves": ("curves.png", "view.png"),
    "study probes": ("fetches_vs_resolution.png", "probe_count.png", "orderings.png",
                     "contact_sheet.png"),
    "sweep": ("sweep.png", "view.png"),
    "compare": ("contact_sheet.png",),
    "shadows": ("contact_sheet.png",),
}


def read_study_mark(folder: str | Path) -> dict:
    """The folder's mark; empty where there is none (a new folder, or one an older
    voxfield wrote) or where it cannot be read or is not a JSON object."""
    try:
        mark = json.loads((Path(folder) / STUDY_MARK).read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, ValueError, RecursionError):
        return {}
    return mark if isinstance(mark, dict) else {}
