"""Progress on stderr for long work: bars, and a notice while kernels compile."""

from __future__ import annotations

import contextlib
import sys

from numba.core import event
from tqdm import tqdm

#: What ``compile_notice`` says, once per process.
COMPILING = ("voxfield: compiling kernels for this machine: a minute or two, once "
             "(they are cached for later runs)")


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


class _FirstCompile(event.Listener):
    """Writes ``COMPILING`` when the first kernel of the process starts compiling."""

    def __init__(self, stream) -> None:
        self.stream = stream
        self.said = False

    def on_start(self, event) -> None:
        if not self.said:
            self.said = True
            tqdm.write(COMPILING, file=self.stream)

    def on_end(self, event) -> None:
        pass


@contextlib.contextmanager
def compile_notice(*, enabled: bool = True, stream=None):
    """Say once, on ``stream`` (stderr), when Numba starts compiling a kernel: on a
    machine's first run, or after an upgrade, that takes a minute or two before any bar
    moves. Kernels loaded from the cache compile nothing, and nothing is said."""
    if not enabled:
        yield
        return
    with event.install_listener("numba:compile", _FirstCompile(stream or sys.stderr)):
        yield
