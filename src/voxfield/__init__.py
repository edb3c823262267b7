"""voxfield: sparse voxel octrees with error-aware LOD, light probes with depth, ray queries."""

import hashlib
import os
from pathlib import Path


def _keyed_numba_cache() -> None:
    """Point Numba's cache at a folder keyed on this package's source, unless the user chose
    one: Numba revalidates a cached kernel against its own file only, so a kernel that inlines
    an edited kernel from another file would otherwise run stale code after an upgrade.
    (No effect if Numba was imported before voxfield.)"""
    if "NUMBA_CACHE_DIR" in os.environ:
        return
    digest = hashlib.sha1()
    for path in sorted(Path(__file__).parent.rglob("*.py")):
        digest.update(path.read_bytes())
    base = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache")
    os.environ["NUMBA_CACHE_DIR"] = str(base / "voxfield" / "numba" / digest.hexdigest()[:12])


_keyed_numba_cache()

from voxfield.errors import VoxfieldError  # noqa: E402

__all__ = ["VoxfieldError"]
__version__ = "0.1.0"
