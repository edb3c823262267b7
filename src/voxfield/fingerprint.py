"""Content hashes that name inputs in cache keys and files: the same arrays give the same
fingerprint on any machine, any array change gives another."""

from __future__ import annotations

import hashlib

import numpy as np


def array_fingerprint(*arrays: np.ndarray) -> str:
    """A hash of array contents, shapes and types: identifies a scene or camera in item keys."""
    digest = hashlib.blake2b(digest_size=16)
    for a in arrays:
        a = np.ascontiguousarray(a)
        digest.update(f"{a.dtype.str}{a.shape}".encode())
        digest.update(memoryview(a).cast("B"))
    return digest.hexdigest()
