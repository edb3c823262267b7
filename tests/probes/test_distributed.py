"""Dask baking gives exactly the plain loop's probes, on local threads and on a cluster."""

from __future__ import annotations

import numpy as np
import pytest

from voxfield.probes.bake import bake_probes
from voxfield.probes.distributed import SchedulerError, bake_probes_dask
from voxfield.probes.folder_bake import bake_to_folder
from voxfield.probes.grid import ProbeGrid
from voxfield.probes.probe_folder import open_probe_set
from voxfield.probes.probe_set import BakeOptions

# Error-aware radiance: the renderer with the most branching, so a scheduler that changed
# anything (seeds, thread count, probe order) would show.
OPTIONS = BakeOptions(resolution=8, renderer="error-aware", seed=3)


@pytest.fixture(scope="module")
def grid(octree):
    lo, hi = octree.voxel_bounds
    enabled = np.ones(8, bool)
    enabled[5] = False
    return ProbeGrid.fit(lo, hi, (2, 2, 2)).with_enabled(enabled)


@pytest.fixture(scope="module")
def local(octree, grid):
    return bake_probes(octree, grid, OPTIONS)


def assert_same(a, b) -> None:
    for name in ("radiance", "distance", "normal", "enabled", "positions"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name), err_msg=name)
    for key in a.cost:
        if not key.endswith("seconds"):
            np.testing.assert_array_equal(a.cost[key], b.cost[key], err_msg=key)
    assert a.fingerprint == b.fingerprint


@pytest.mark.parametrize("scheduler", ["threads", "serial"])
def test_local_schedulers_equal_the_loop(octree, grid, local, scheduler):
    assert_same(bake_probes_dask(octree, grid, OPTIONS, scheduler=scheduler), local)


def test_distributed_cluster_equals_the_loop(octree, grid, local, dask_client):
    assert_same(bake_probes_dask(octree, grid, OPTIONS, scheduler=dask_client), local)


def test_cluster_bake_to_folder_resumes_to_the_same_set(tmp_path, octree, grid, local, dask_client):
    bake_to_folder(octree, grid, OPTIONS, tmp_path, scheduler=dask_client)
    (tmp_path / "probe_00003.npz").unlink()
    assert_same(bake_to_folder(octree, grid, OPTIONS, tmp_path, scheduler="threads"), local)
    assert_same(open_probe_set(tmp_path), local)


@pytest.mark.parametrize("scheduler", [42, "thread", "tcp://"])
def test_unknown_scheduler_is_a_clear_error(octree, grid, scheduler):
    with pytest.raises(SchedulerError, match="scheduler"):
        bake_probes_dask(octree, grid, OPTIONS, scheduler=scheduler)
