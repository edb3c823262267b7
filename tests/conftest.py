"""Shared fixtures: the real-data folder (skip when absent) and small scenes."""

from __future__ import annotations

import os
import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).parent))


# Compiled kernels stay in the checkout; voxfield keys a folder inside on its source, so an
# edited kernel (or code it inlines from another file) is compiled afresh.
os.environ.setdefault("NUMBA_CACHE_DIR", str(Path(__file__).parents[1] / ".numba_cache"))

from voxfield.data import data_root  # noqa: E402
from voxfield.scaleout import local_cluster  # noqa: E402


@pytest.fixture(scope="session")
def shared_data() -> Path:
    root = data_root()
    if not root.is_dir():
        pytest.skip(f"real scenes not found at {root} (set VOXFIELD_DATA to the data folder)")
    return root


@pytest.fixture(scope="session")
def dask_client():
    """A two-worker ``distributed`` cluster in this process: the scheduler tests run their
    tasks through a real client, scatter and all, without the cost of worker processes."""
    distributed = pytest.importorskip("distributed")
    with local_cluster(2, processes=False) as cluster, distributed.Client(cluster) as client:
        yield client



@pytest.fixture
def small_jobs_in_parallel(monkeypatch):
    """Spread even the smallest job over every thread it is given: the tests that compare one
    thread with two render small images, which would otherwise run on one thread both times
    (``parallel.MIN_PARALLEL_RAYS``)."""
    monkeypatch.setattr("voxfield.parallel.MIN_PARALLEL_RAYS", 1)
