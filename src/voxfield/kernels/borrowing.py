"""``borrowing``: the Numba compilation of the hot helpers that only borrow their arrays.

Numba counts references to every array a compiled function receives: it adds one to the
array's count on entry and takes it off at every return, each an atomic update of the
array's header. The threads of a parallel kernel share those headers (the octree's
descriptors, the column pyramid), so the header's cache line moves between cores on every
call: the rising-ray walk made 14 such updates a ray, 9 % of a 2048² desert sun bake, and
the closest-hit walk as much of a primary render.

A helper that creates no array and keeps none past its return needs no count: its caller
owns every array it touches. ``borrowing`` compiles it without reference counting (Numba's
``_nrt=False``); an allocation in it (``np.empty``, a copy) fails to compile rather than
leak, so scratch comes from the caller. The functions it calls are compiled without counting
too only where they are inlined or compiled first from it: Numba keeps one compiled version
per signature, so a plain ``njit`` callee already compiled elsewhere keeps its counts (and
an allocation in it would leak). Hence the rule: a borrowing function calls, with arrays,
only ``inline="always"`` helpers and other borrowing functions.
"""

from __future__ import annotations

from numba import njit

__all__ = ["borrowing"]

#: What every borrowing helper is compiled with (``kernels`` functions are all cached and
#: release the GIL).
BORROWING_OPTIONS = {"cache": True, "nogil": True, "_nrt": False}


def borrowing(function=None, /, **options):
    """``njit`` without reference counting, as ``@borrowing`` or ``@borrowing(...)`` with
    further Numba options."""
    jit = njit(**{**BORROWING_OPTIONS, **options})
    return jit if function is None else jit(function)
