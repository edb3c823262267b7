"""Checks of the numbers the library's entry points take, in one wording.

A kernel compiled for an ``int`` and handed ``1.5`` fails deep in Numba's type inference
with pages of text (and a bool or a NumPy integer would compile a second copy), and a NaN
bound turns every ray into a miss without a word. The renderers and ray queries check their
arguments here first, so bad input is one ``VoxfieldError`` line (exit 2 on the command
line).
"""

from __future__ import annotations

import math
import numbers
import os
from pathlib import Path

import numpy as np

from voxfield.errors import VoxfieldError

__all__ = ["MAX_SEED", "flag", "integer_in", "is_integer", "is_real", "path_value", "ray_arrays",
           "real_number", "seed_value"]

#: Seeds are hashed as 32-bit words: 0..MAX_SEED.
MAX_SEED = 2**32 - 1


def is_integer(value) -> bool:
    """A Python or NumPy integer, not a bool (``True`` is an ``int`` to Python)."""
    return isinstance(value, (int, np.integer)) and not isinstance(value, bool)


def is_real(value) -> bool:
    """A Python or NumPy real number (NaN and infinities included), not a bool."""
    return isinstance(value, numbers.Real) and not isinstance(value, (bool, np.bool_))


def integer_in(value, what: str, low: int, high: int | None = None) -> int:
    """``value`` as an ``int`` when it is an integer (``is_integer``) in ``low..high`` (no
    upper end for ``None``)."""
    if not is_integer(value) or value < low or (high is not None and value > high):
        limits = f"≥ {low}" if high is None else f"in {low}..{high}"
        raise VoxfieldError(f"{what} must be an integer {limits}, got {value!r}")
    return int(value)


def real_number(value, what: str, *, finite: bool = True) -> float:
    """``value`` as a ``float`` when it is a real number (``is_real``), not NaN; infinities
    only where ``finite`` is false."""
    if not is_real(value):
        raise VoxfieldError(f"{what} must be a number, got {value!r}")
    x = float(value)
    if math.isnan(x) or (finite and math.isinf(x)):
        kind = "finite number" if finite else "number (not NaN)"
        raise VoxfieldError(f"{what} must be a {kind}, got {value!r}")
    return x


def flag(value, what: str) -> bool:
    """``value`` as a ``bool`` when it is one (Python's or NumPy's): any object is truthy,
    so ``reuse_parent="no"`` turned the option on."""
    if not isinstance(value, (bool, np.bool_)):
        raise VoxfieldError(f"{what} must be True or False, got {value!r}")
    return bool(value)


def ray_arrays(origins, directions) -> tuple[np.ndarray, np.ndarray]:
    """Rays as two contiguous, writable float64 N×3 arrays, every component finite and no
    direction the zero vector (it has no crossing times). A read-only array is copied: to
    Numba it is another type, and the kernels compiled again for it (a first call on
    read-only rays took seconds more)."""
    try:
        arrays = [np.asarray(origins), np.asarray(directions)]
    except ValueError as exc:  # ragged lists
        raise VoxfieldError("origins and directions must both be N×3, rows of three numbers") \
            from exc
    if any(a.dtype.kind not in "biuf" for a in arrays):  # text, objects, complex numbers
        raise VoxfieldError(f"ray origins and directions must be real numbers, got "
                            f"{arrays[0].dtype} and {arrays[1].dtype}")
    o, d = (_writable(np.ascontiguousarray(a, dtype=np.float64)) for a in arrays)
    if o.ndim != 2 or o.shape[1] != 3 or d.shape != o.shape:
        raise VoxfieldError(f"origins and directions must both be N×3, got {o.shape}, {d.shape}")
    if not (np.isfinite(o).all() and np.isfinite(d).all()):
        raise VoxfieldError("ray origins or directions hold NaN or infinity")
    if np.any(~d.any(axis=1)):
        raise VoxfieldError("a ray direction is the zero vector")
    return o, d


def _writable(array: np.ndarray) -> np.ndarray:
    return array if array.flags.writeable else array.copy()


def path_value(value, what: str) -> Path:
    """A file or folder path (``str`` or ``os.PathLike``) as a ``Path``: ``None`` or a number
    failed inside ``pathlib`` with Python's TypeError."""
    if not isinstance(value, str | os.PathLike) or value == "":
        raise VoxfieldError(f"{what} must be a path (str or os.PathLike), got {value!r}")
    return Path(value)


def seed_value(value) -> int:
    """A sampling seed: an integer in ``0..MAX_SEED``."""
    return integer_in(value, "seed", 0, MAX_SEED)


def spoken_list(phrases: list[str]) -> str:
    """``a``, ``a and b``, ``a, b and c``: a list as a message says it."""
    return phrases[0] if len(phrases) == 1 else ", ".join(phrases[:-1]) + " and " + phrases[-1]
