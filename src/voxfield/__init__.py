"""voxfield: sparse voxel octrees with error-aware LOD, light probes with depth, ray queries."""

import hashlib
import os
import sys
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


#: The folder of Numba's cache this source compiles into, inside the chosen cache folder.
KERNEL_CACHE_KEY = f"voxfield-{SOURCE_DIGEST}"


def _keyed_numba_cache() -> None:
    """Point Numba's cache at ``KERNEL_CACHE_KEY`` inside the folder ``NUMBA_CACHE_DIR``
    names, or inside ``~/.cache/voxfield/numba``. Numba revalidates a cached kernel against
    its own file only, so a kernel that inlines code from another file (an edited helper, a
    constant, a lowering in ``kernels.scalar_ops``) would otherwise run stale code after an
    edit or an upgrade, in a folder the user chose as much as in ours. A folder already keyed
    (a child process's inherited setting) is kept. Numba imported before voxfield rereads its
    settings, before any kernel of ours asks where its cache is."""
    chosen = os.environ.get("NUMBA_CACHE_DIR")
    if chosen:
        base = Path(chosen)
    else:
        base = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache")
        base = base / "voxfield" / "numba"
    if base.name != KERNEL_CACHE_KEY:
        os.environ["NUMBA_CACHE_DIR"] = str(base / KERNEL_CACHE_KEY)
    config = sys.modules.get("numba.core.config")
    if config is not None:
        config.reload_config()


_keyed_numba_cache()

from voxfield.errors import VoxfieldError  # noqa: E402

__all__ = ["VoxfieldError"]
__version__ = "0.1.0"
