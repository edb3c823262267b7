"""How a command ends when something goes wrong: one line on stderr and a status, never a
traceback. The ``voxfield`` command and the benchmark scripts end alike."""

from __future__ import annotations

import contextlib
import errno
import os
import signal
import sys
import threading
from collections.abc import Callable, Iterator

from voxfield.errors import VoxfieldError

EXIT_USAGE = 2
EXIT_INTERRUPTED = 130


class Terminated(KeyboardInterrupt):
    """SIGTERM or SIGHUP (``kill``, ``timeout``, a closed terminal) raised where Python runs
    next, as Ctrl-C is: every ``finally`` then removes its temporary files, where the
    default action killed the process and left them (half a gigabyte of octree)."""

    def __init__(self, signum: int):
        super().__init__(signal.Signals(signum).name)
        self.signum = signum


@contextlib.contextmanager
def stopping_on_termination() -> Iterator[None]:
    """SIGTERM and SIGHUP raise ``Terminated`` inside the block (main thread only, and not
    where the signal is ignored; the handlers before it are put back after)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def terminate(signum, _frame):
        raise Terminated(signum)

    # a signal ignored already (SIGHUP under nohup) stays ignored
    kinds = [s for s in (getattr(signal, "SIGTERM", None), getattr(signal, "SIGHUP", None))
             if s is not None and signal.getsignal(s) is not signal.SIG_IGN]
    before = {kind: signal.signal(kind, terminate) for kind in kinds}
    try:
        yield
    finally:
        for kind, handler in before.items():
            signal.signal(kind, handler)


#: Errors only a write gives: without a file name, they come from standard output.
_WRITE_ONLY_ERRORS = frozenset({errno.ENOSPC, errno.EDQUOT, errno.EFBIG})


def report_failures(prog: str, command: Callable[[], int | None]) -> int:
    """``command()``'s status (0 for None); bad input, an unusable file or a closed output
    pipe print ``prog: error: ...`` and give ``EXIT_USAGE``, Ctrl-C gives
    ``EXIT_INTERRUPTED``."""
    try:
        code = command()
    except VoxfieldError as exc:
        print(f"{prog}: error: {exc}", file=sys.stderr)
        return EXIT_USAGE
    except BrokenPipeError as exc:
        return stdout_failed(prog, exc)
    except OSError as exc:
        if exc.filename is None and exc.errno in _WRITE_ONLY_ERRORS:
            return stdout_failed(prog, exc)  # files are written by paths that name them
        print(f"{prog}: error: {os_error_text(exc)}", file=sys.stderr)
        return EXIT_USAGE
    except MemoryError as exc:
        detail = f" ({exc})" if str(exc) else ""
        print(f"{prog}: error: out of memory{detail}; ask for less (a smaller --size, "
              "--footprint or resolution)", file=sys.stderr)
        return EXIT_USAGE
    except KeyboardInterrupt as exc:
        return interrupted(prog, exc)
    return _flushed_stdout(prog, code or 0)


def _flushed_stdout(prog: str, code: int) -> int:
    """``code``, once what the command printed has reached its reader: a closed pipe or a
    full disk shows here, named as standard output, not as a traceback at exit."""
    try:
        sys.stdout.flush()
    except OSError as exc:
        return stdout_failed(prog, exc)
    return code


def stdout_failed(prog: str, exc: OSError) -> int:
    """One line for output that cannot be written: the reader went away (``voxfield scenes
    | head -1``) or the disk behind ``> file`` is full."""
    sys.stdout = open(os.devnull, "w")  # noqa: SIM115 - Python would flush the same bytes at exit
    if isinstance(exc, BrokenPipeError):
        print(f"{prog}: error: output closed early (broken pipe)", file=sys.stderr)
    else:
        reason = os_error_text(exc).split(": ", 1)[-1]
        print(f"{prog}: error: cannot write to standard output: {reason}", file=sys.stderr)
    return EXIT_USAGE


def interrupted(prog: str, exc: KeyboardInterrupt) -> int:
    """One line for Ctrl-C or a termination signal, and the shell's status for it."""
    if isinstance(exc, Terminated):
        print(f"{prog}: terminated ({exc})", file=sys.stderr)
        return 128 + exc.signum
    print(f"{prog}: interrupted", file=sys.stderr)
    return EXIT_INTERRUPTED


def os_error_text(exc: OSError) -> str:
    """An operating-system error in the user's terms: the path and what went wrong."""
    reason = {
        errno.ENAMETOOLONG: "the file name is too long",
        errno.EISDIR: "it is a folder, not a file",
        errno.ENOTDIR: "a part of the path is a file, not a folder",
        errno.EEXIST: "a part of the path is a file, not a folder",
        errno.EROFS: "the file system is read-only",
        errno.EACCES: "permission denied",
        errno.ENOSPC: "the disk is full",
    }.get(exc.errno, exc.strerror or str(exc))
    where = exc.filename if exc.filename is not None else "a file"
    return f"cannot use {where}: {reason}"
