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


#: Pause iterations an idle OpenMP thread spins before it sleeps (libgomp's own default is
#: 300,000, several milliseconds). A thread spinning at the end of a parallel region holds
#: a core that another process's threads are waiting for, so two voxfield jobs on one
#: machine stalled each other: two 512² renders side by side took 70-80 ms each against
#: 46-48 ms with this count, two serial bakes of 32² probes up to 53 ms a probe against
#: 2.3-4.7 ms; alone, renders and bakes took the same within the noise (a few per cent).
OPENMP_SPIN_COUNT = 3000


def _short_openmp_spin() -> None:
    """Set ``GOMP_SPINCOUNT`` to ``OPENMP_SPIN_COUNT`` unless the user chose a spin count or a
    wait policy. libgomp reads it once, when Numba's threading layer first loads it (the
    first parallel kernel call), so a program that loaded an OpenMP runtime before it
    imported voxfield keeps that runtime's settings."""
    if "GOMP_SPINCOUNT" not in os.environ and "OMP_WAIT_POLICY" not in os.environ:
        os.environ["GOMP_SPINCOUNT"] = str(OPENMP_SPIN_COUNT)


_keyed_numba_cache()
_short_openmp_spin()

from voxfield.errors import VoxfieldError  # noqa: E402

__all__ = ["VoxfieldError"]
__version__ = "0.1.0"
