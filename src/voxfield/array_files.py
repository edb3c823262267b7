"""Reading NumPy array files (``.npz``, ``.npy``) that may be something else entirely.

Handed a file that is neither, ``np.load`` takes it for a pickle and, with pickles refused,
says the file "contains pickled (object) data" and that it can be loaded "unsafely" with
``allow_pickle``: advice to run code from a file that was most likely only misnamed or cut
short. Every reader of user-supplied array files goes through ``load_arrays`` instead.
"""

from __future__ import annotations

import os

import numpy as np

#: How a ``.npz`` (a zip archive: a local file header, or an empty archive's end record)
#: and a ``.npy`` file begin.
_ZIP_STARTS = (b"PK\x03\x04", b"PK\x05\x06")
_NPY_START = b"\x93NUMPY"


def load_arrays(path: str | os.PathLike, kind: str = "npz"):
    """``np.load(path, allow_pickle=False)``, after refusing (``ValueError``) a file that
    does not begin as a ``.npz`` (``kind="npz"``: an archive of named arrays, as the
    callers' ``with`` blocks need) or a ``.npy`` (``kind="npy"``: one array) does."""
    starts = {"npz": _ZIP_STARTS, "npy": (_NPY_START,)}[kind]
    with open(path, "rb") as f:
        head = f.read(len(_NPY_START))
    if not head:
        raise ValueError("the file is empty")
    if not head.startswith(starts):
        other = "a single-array .npy file" if head.startswith(_NPY_START) else (
            "an .npz archive" if head.startswith(_ZIP_STARTS) else
            "damaged, or another kind of file")
        raise ValueError(f"not a NumPy .{kind} file ({other})")
    return np.load(path, allow_pickle=False)
