"""Progress on stderr for long work: bars, and a notice while kernels compile."""

from __future__ import annotations

import contextlib
import sys

from tqdm import tqdm

#: What ``compile_notice`` says, once per process.
COMPILING = ("voxfield: compiling kernels for this machine: a minute or two, once "
             "(they are cached for later runs)")


class _NoBar:
    """What a disabled bar is: a tqdm costs 30 µs to make even then, which a probe bake
    of small maps paid four times a probe."""

    def update(self, n: int = 1) -> None:
        pass


@contextlib.contextmanager
def progress_bar(*, total: int, desc: str, unit: str = "it", enabled: bool = True):
    """A tqdm bar on stderr when enabled and stderr is a terminal: redrawn in place there,
    a bar written to a log or a pipe is a trail of carriage returns. Its ``update`` is all
    callers use."""
    if not enabled or not _is_terminal(sys.stderr):
        yield _NoBar()
        return
    bar = tqdm(
        total=total, desc=desc, unit=unit, file=sys.stderr, leave=False, dynamic_ncols=True,
    )
    try:
        yield bar
    finally:
        bar.close()


def _is_terminal(stream) -> bool:
    isatty = getattr(stream, "isatty", None)
    return bool(isatty and isatty())


def _first_compile_listener(stream):
    """A context in which a Numba event listener writes ``COMPILING`` when the first kernel
    of the process starts compiling."""
    # Deferred: Numba takes 0.2 s to import, which commands that compile nothing (the
    # listing, `scenes`, `report`) need not pay.
    from numba.core import event

    class FirstCompile(event.Listener):
        said = False

        def on_start(self, _event) -> None:
            if not self.said:
                self.said = True
                tqdm.write(COMPILING, file=stream)

        def on_end(self, _event) -> None:
            pass

    return event.install_listener("numba:compile", FirstCompile())


@contextlib.contextmanager
def compile_notice(*, enabled: bool = True, stream=None):
    """Say once, on ``stream`` (stderr), when Numba starts compiling a kernel: on a
    machine's first run, or after an upgrade, that takes a minute or two before any bar
    moves. Kernels loaded from the cache compile nothing, and nothing is said."""
    if not enabled:
        yield
        return
    with _first_compile_listener(stream or sys.stderr):
        yield
