"""voxfield: sparse voxel octrees with error-aware LOD, light probes with depth, ray queries."""

import hashlib
import os
from pathlib import Path


def _source_digest() -> str:
    """A hash of this package's Python source: what compiled kernels and cached study results
    were made by."""
    digest = hashlib.sha1()
    for path in sorted(Path(__file__).parent.rglob("*.py")):
        digest.update(path.read_bytes())
    return digest.hexdigest()[:12]


#: Identifies the code that made a compiled kernel or a cached study item.
SOURCE_DIGEST = _source_digest()


def _keyed_numba_cache() -> None:
    """Point Numba's cache at a folder keyed on this package's source, unless the user chose
    one: Numba revalidates a cached kernel against its own file only, so a kernel that inlines
    an edited kernel from another file would otherwise run stale code after an upgrade.
    (No effect if Numba was imported before voxfield.)"""
    if "NUMBA_CACHE_DIR" in os.environ:
        return
    base = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache")
    os.environ["NUMBA_CACHE_DIR"] = str(base / "voxfield" / "numba" / SOURCE_DIGEST)


_keyed_numba_cache()

from voxfield.errors import VoxfieldError  # noqa: E402

__all__ = ["VoxfieldError"]
__version__ = "0.1.0"
