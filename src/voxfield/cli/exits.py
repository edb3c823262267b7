"""How a command ends when something goes wrong: one line on stderr and a status, never a
traceback. The ``voxfield`` command and the benchmark scripts end alike."""

from __future__ import annotations

import errno
import os
import sys
from collections.abc import Callable

from voxfield.errors import VoxfieldError

EXIT_USAGE = 2
EXIT_INTERRUPTED = 130


def report_failures(prog: str, command: Callable[[], int | None]) -> int:
    """``command()``'s status (0 for None); bad input, an unusable file or a closed output
    pipe print ``prog: error: ...`` and give ``EXIT_USAGE``, Ctrl-C gives
    ``EXIT_INTERRUPTED``."""
    try:
        code = command()
        sys.stdout.flush()  # a closed pipe shows here, not at exit
        return code or 0
    except VoxfieldError as exc:
        print(f"{prog}: error: {exc}", file=sys.stderr)
        return EXIT_USAGE
    except BrokenPipeError:
        # The reader went away (``voxfield scenes | head -1``): say so once, quietly.
        sys.stdout = open(os.devnull, "w")  # noqa: SIM115 - Python would flush into the pipe
        print(f"{prog}: error: output closed early (broken pipe)", file=sys.stderr)
        return EXIT_USAGE
    except OSError as exc:
        print(f"{prog}: error: {os_error_text(exc)}", file=sys.stderr)
        return EXIT_USAGE
    except KeyboardInterrupt:
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
