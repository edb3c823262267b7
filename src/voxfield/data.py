"""Where real scenes live: ``$VOXFIELD_DATA`` or ``../shared/data`` beside the checkout."""

from __future__ import annotations

import os
from pathlib import Path

from voxfield.errors import DataNotFoundError

_PROJECT_ROOT = Path(__file__).resolve().parents[2]


def data_root() -> Path:
    """The shared data folder; it may not exist (callers decide whether that is fatal)."""
    env = os.environ.get("VOXFIELD_DATA")
    if env:
        return Path(env)
    return _PROJECT_ROOT.parent / "shared" / "data"


def data_path(*parts: str) -> Path:
    """A path inside the shared data folder, raising a clear error when it is absent."""
    path = data_root().joinpath(*parts)
    if not path.exists():
        raise DataNotFoundError(
            f"{path} does not exist; set VOXFIELD_DATA to the folder holding the shared scenes"
        )
    return path
