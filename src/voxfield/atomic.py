"""Atomic file output: write beside the target, then rename, so readers never see half a file."""

from __future__ import annotations

import contextlib
import errno
import os
import stat
import tempfile
from collections.abc import Iterator
from pathlib import Path

from voxfield.errors import VoxfieldError


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike) -> Iterator[Path]:
    """A temporary path in the target's folder; renamed onto ``path`` if the block succeeds.

    The temporary name keeps the target's suffix, so writers that pick a format by suffix
    (Pillow, OpenEXR) still work; on failure it is removed and the target is untouched. The
    result has the mode a plain ``open`` would give it: an existing file's own, else
    0666 less the umask (``mkstemp`` alone would leave every output 0600).
    """
    path = _ready_folder(path)
    try:
        fd, tmp = tempfile.mkstemp(
            prefix=f".{path.stem[:64]}.", suffix=f".tmp{path.suffix[:16]}", dir=path.parent
        )
    except OSError as exc:  # name the target, not the temporary file that was refused
        raise type(exc)(exc.errno, exc.strerror or str(exc), str(path)) from None
    os.close(fd)
    tmp_path = Path(tmp)
    try:
        yield tmp_path
        os.chmod(tmp_path, _mode_for(path))
        os.replace(tmp_path, path)
    except OSError as exc:
        if exc.filename in (None, str(tmp_path)):  # a writer that names no file, or ours
            raise type(exc)(exc.errno, exc.strerror or str(exc), str(path)) from exc
        raise
    finally:
        tmp_path.unlink(missing_ok=True)


def named_for(path: str | os.PathLike, suffix: str, what: str) -> Path:
    """``path``, refused unless it ends in ``suffix``: a writer of one format under another
    name (an octree as ``o.vox``, a PNG as ``a.jpg``) leaves a file that every reader of that
    name then misreads."""
    path = Path(path)
    if path.suffix.lower() != suffix:
        raise VoxfieldError(f"{path}: {what} writes {suffix} files; give a name ending in "
                            f"{suffix}")
    return path


def save_figure(figure, path: str | os.PathLike, *, dpi: float | None = None) -> Path:
    """``write_figure_png`` atomically."""
    path = Path(path)
    with atomic_path(path) as tmp:
        write_figure_png(figure, tmp, dpi=dpi)
    return path


def write_figure_png(figure, path: str | os.PathLike, *, dpi: float | None = None) -> None:
    """A matplotlib Figure as PNG on its own background colour, at ``dpi`` (the figure's
    own by default), straight into ``path`` (staged by the caller)."""
    figure.savefig(path, format="png", dpi=dpi or figure.dpi, facecolor=figure.get_facecolor())


@contextlib.contextmanager
def atomic_paths(paths) -> Iterator[list[Path]]:
    """``atomic_path`` for several files that belong together (an image and its maps): all
    are renamed into place if the block succeeds, none if it fails part way. An error that
    names a staged file is reported for its target; one that names no file, for them all."""
    paths = [Path(path) for path in paths]
    with contextlib.ExitStack() as stack:
        staged = [stack.enter_context(atomic_path(path)) for path in paths]
        try:
            yield staged
        except OSError as exc:
            if exc.filename is not None:
                raise
            raise type(exc)(exc.errno, exc.strerror or str(exc),
                            ", ".join(map(str, paths))) from exc


def check_writable(path: str | os.PathLike) -> Path:
    """Fail now, before the work, where ``atomic_path`` would fail after it: a folder in
    the way, a file where a folder should be, a folder that cannot be created or written.
    Leaves nothing behind, not even the missing folders writing will create (a command
    refused later, for its scene, left them empty); errors name the target or the file in
    its way, not the probe."""
    path = Path(path)
    try:
        target = _checked_target(path)
        folder = _nearest_folder(target.parent)
        if folder == target.parent:
            fd, probe = tempfile.mkstemp(prefix=f".{target.stem[:64]}.", suffix=".probe",
                                         dir=folder)
            os.close(fd)
            os.unlink(probe)
        else:  # the missing folders, made as writing would make them, then removed
            _make_and_remove(folder, target.parent)
    except OSError as exc:  # name the target, or the file in its way, never the probe
        named = "" if exc.filename is None else str(exc.filename)
        culprit = named if named and not named.endswith(".probe") else str(path)
        raise type(exc)(exc.errno, exc.strerror, culprit) from None
    return path


def _checked_target(path: Path) -> Path:
    """``path`` (a link's target for a link), refused if it names a folder or anything but a
    plain file (a device, a pipe, a socket: the rename would put a file in its place,
    ``/dev/null`` included) or a file its owner made read-only. A link whose target's folder
    is missing is refused, as ``open()`` refuses it: writing made that folder, wherever the
    link pointed."""
    if path.is_symlink():  # written through, as open() would: the link stays a link
        link, path = path, Path(os.path.realpath(path))
        if not path.parent.is_dir():
            raise FileNotFoundError(
                errno.ENOENT, f"it is a link to {path}, whose folder does not exist", str(link))
    if path.is_dir():
        raise IsADirectoryError(errno.EISDIR, "is a folder, not a file", str(path))
    if path.exists() and not path.is_file():
        raise OSError(errno.EINVAL, "it is a device, pipe or socket, not a file", str(path))
    if path.exists() and not os.access(path, os.W_OK):  # the rename would replace it anyway
        raise PermissionError(errno.EACCES, "the file is read-only", str(path))
    return path


def _make_and_remove(existing: Path, wanted: Path) -> None:
    """Create the folders from ``existing`` down to ``wanted`` and remove them again,
    deepest first: every refusal writing would meet (permissions, a name too long) shows
    now, and nothing is left behind."""
    missing = [wanted, *(p for p in wanted.parents if p != existing and existing in p.parents)]
    made = []
    try:
        for folder in reversed(missing):
            folder.mkdir()
            made.append(folder)
    finally:
        for folder in reversed(made):
            folder.rmdir()


def _nearest_folder(folder: Path) -> Path:
    """``folder`` or its nearest existing ancestor; a file where a folder should be, or a
    link to nothing, is named as in the way."""
    for candidate in (folder, *folder.parents):
        if candidate.is_symlink() and not candidate.exists():
            raise FileNotFoundError(errno.ENOENT, "it is a link to nothing", str(candidate))
        if candidate.exists():
            if not candidate.is_dir():
                raise NotADirectoryError(errno.ENOTDIR, "is a file, not a folder",
                                         str(candidate))
            return candidate
    return Path(os.getcwd())


def _ready_folder(path: str | os.PathLike) -> Path:
    """``_checked_target(path)`` with its folder created if missing."""
    path = _checked_target(Path(path))
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
    except (FileExistsError, NotADirectoryError):  # "File exists" named no culprit
        _nearest_folder(path.parent)
        raise
    return path


def _mode_for(path: Path) -> int:
    """The permission bits ``path`` should get: its own if it exists, else 0666 & ~umask."""
    try:
        return stat.S_IMODE(path.stat().st_mode)
    except FileNotFoundError:
        mask = os.umask(0)
        os.umask(mask)
        return 0o666 & ~mask
