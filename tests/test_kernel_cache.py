"""Where Numba caches voxfield's kernels: a folder keyed on the source, inside whichever
cache folder is chosen, so no edit or upgrade ever runs a stale inlined kernel."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import voxfield


def _cache_dir(env: dict, first: str = "voxfield") -> Path:
    """Numba's cache folder in a fresh interpreter that imports ``first``, then voxfield and
    Numba, with ``env``."""
    script = f"import {first}, voxfield, numba; print(numba.config.CACHE_DIR)"
    base = {k: v for k, v in os.environ.items() if k not in ("NUMBA_CACHE_DIR", "XDG_CACHE_HOME")}
    out = subprocess.run([sys.executable, "-c", script], env={**base, **env}, check=True,
                         capture_output=True, text=True).stdout
    return Path(out.strip())


def test_a_chosen_cache_folder_gets_a_folder_keyed_on_the_source(tmp_path):
    # Numba checks a cached kernel against its own file only: a folder the user names,
    # unkeyed, served stale kernels after an edit to code they inline from elsewhere.
    assert _cache_dir({"NUMBA_CACHE_DIR": str(tmp_path)}) == (
        tmp_path / voxfield.KERNEL_CACHE_KEY)


def test_a_folder_already_keyed_is_kept_as_child_processes_inherit_it(tmp_path):
    keyed = tmp_path / voxfield.KERNEL_CACHE_KEY
    assert _cache_dir({"NUMBA_CACHE_DIR": str(keyed)}) == keyed


def test_without_a_choice_the_cache_is_in_the_users_cache_folder(tmp_path):
    assert _cache_dir({"XDG_CACHE_HOME": str(tmp_path)}) == (
        tmp_path / "voxfield" / "numba" / voxfield.KERNEL_CACHE_KEY)



def test_numba_imported_before_voxfield_takes_the_keyed_folder(tmp_path):
    assert _cache_dir({"NUMBA_CACHE_DIR": str(tmp_path)}, first="numba") == (
        tmp_path / voxfield.KERNEL_CACHE_KEY)
