"""One writer per output folder: a long job claims its folder while it writes into it.

A probe bake resumes from what its folder holds and a study reuses the items it cached, so
two jobs writing into one folder at once undo each other: one's ``--fresh`` deletes the
other's probes, one's header replaces the other's record, and the first then fails on a
checksum it cannot explain. Each job therefore holds an advisory lock (``flock``) on a hidden
file in the folder while it writes, and a second job is refused at once with who holds it.

The lock belongs to the process: the system drops it when the process ends, however it
ends, so no stale lock survives a kill; and the same process may claim a folder it already
holds (a study that checks its folder before a bake and writes it after). The file is
removed when the last claim is given up; a job that finds the file replaced under it while
it waited takes the new one. Where the file system has no locks (some network mounts) or
the platform has no ``fcntl``, the job runs unguarded, with a note.
"""

from __future__ import annotations

import contextlib
import errno
import os
import threading
import time
import warnings
from pathlib import Path

from voxfield.errors import VoxfieldError

try:
    import fcntl
except ImportError:  # not a POSIX system: folders go unguarded
    fcntl = None

#: The lock file's name: a dot file, which bakes and studies pass over as their own.
LOCK_NAME = ".voxfield-lock"


class FolderBusyError(VoxfieldError):
    """Another process is writing into the folder a job was given."""


class _Claim:
    """This process's hold on one folder: the open lock file and how many claims share it."""

    def __init__(self, fd: int | None):
        self.fd = fd
        self.count = 1


_claims: dict[str, _Claim] = {}
_claims_guard = threading.Lock()


class FolderLock:
    """``job``'s claim on ``folder`` (a command's name, shown to whoever is refused).

    ``take()`` claims the folder if it exists (or makes it with ``make=True``) and returns
    whether it now holds it; a job whose folder does not exist yet takes it when it first
    writes there, so a job refused before its work leaves no folder behind. ``release()``
    (or the end of a ``with`` block) gives the claim up; so does the process's end."""

    def __init__(self, folder: str | os.PathLike, job: str):
        self.folder = Path(folder)
        self.job = job
        self.held = False

    def take(self, *, make: bool = False) -> bool:
        if self.held:
            return True
        if make:
            self.folder.mkdir(parents=True, exist_ok=True)
        elif not self.folder.is_dir():
            return False
        key = os.path.realpath(self.folder)
        with _claims_guard:
            claim = _claims.get(key)
            if claim is not None:
                claim.count += 1
            else:
                _claims[key] = _Claim(_lock_file(Path(key), self.folder, self.job))
        self.held = True
        return True

    def release(self) -> None:
        if not self.held:
            return
        self.held = False
        key = os.path.realpath(self.folder)
        with _claims_guard:
            claim = _claims.get(key)
            if claim is None:
                return
            claim.count -= 1
            if claim.count > 0:
                return
            del _claims[key]
            if claim.fd is not None:
                # Removed while still locked, so no other job can lock this file and then
                # lose it; one that opened it already sees it gone and opens afresh.
                with contextlib.suppress(OSError):
                    os.unlink(Path(key) / LOCK_NAME)
                os.close(claim.fd)

    def __enter__(self) -> FolderLock:
        return self

    def __exit__(self, *exc) -> None:
        self.release()


def _lock_file(path: Path, shown: Path, job: str) -> int | None:
    """The open, locked lock file of folder ``path`` (``shown`` as the user named it); None
    where locks are not to be had. Refuses with ``FolderBusyError`` when another process
    holds it."""
    if fcntl is None:
        return None
    lock_path = path / LOCK_NAME
    while True:
        fd = os.open(lock_path, os.O_RDWR | os.O_CREAT, 0o666)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError as exc:
            holder = _holder(fd)
            os.close(fd)
            if exc.errno in (errno.EAGAIN, errno.EACCES):
                raise FolderBusyError(
                    f"{shown} is being written by another voxfield job ({holder}); wait for "
                    "it to finish, or give this one another --out") from None
            warnings.warn(f"{shown} cannot be locked ({exc.strerror or exc}): another job "
                          "writing into it at the same time would not be noticed", stacklevel=4)
            return None
        if _same_file(fd, lock_path):
            break
        os.close(fd)  # its holder removed it as we took it: lock the one there now
    os.ftruncate(fd, 0)
    os.write(fd, f"{os.getpid()} {time.strftime('%Y-%m-%d %H:%M:%S')} {job}\n".encode())
    return fd


def _same_file(fd: int, path: Path) -> bool:
    try:
        return os.path.samestat(os.fstat(fd), os.stat(path))
    except FileNotFoundError:
        return False


def _holder(fd: int) -> str:
    """Who holds a lock file, from what it wrote there: ``study thresholds, process 123,
    since 2026-12-08 10:00:00``."""
    try:
        text = os.pread(fd, 4096, 0).decode("utf-8", "replace").strip()
        pid, day, clock, job = text.split(" ", 3)
        return f"{job}, process {int(pid)}, since {day} {clock}"
    except (OSError, ValueError):
        return "it has not said which"
