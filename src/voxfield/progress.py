"""Progress bars on stderr for long work; silent when disabled or when stderr is not a terminal."""

from __future__ import annotations

import contextlib
import sys

from tqdm import tqdm


@contextlib.contextmanager
def progress_bar(*, total: int, desc: str, unit: str = "it", enabled: bool = True):
    """A tqdm bar that writes to stderr only when enabled."""
    bar = tqdm(
        total=total, desc=desc, unit=unit, file=sys.stderr, disable=not enabled,
        leave=False, dynamic_ncols=True,
    )
    try:
        yield bar
    finally:
        bar.close()
