"""voxfield's own stores, damaged: voxel-scene ``.npz`` files and probe-set folders load whole
or raise a ``VoxfieldError`` (one clean line on the command line), never another exception."""

from __future__ import annotations

import io
import json
import shutil

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from voxfield.errors import VoxfieldError
from voxfield.probes.folder_bake import bake_to_folder
from voxfield.probes.grid import ProbeGrid
from voxfield.probes.probe_folder import open_probe_set
from voxfield.probes.probe_set import BakeOptions
from voxfield.scene.builtin import cornell
from voxfield.svo.build import build_octree
from voxfield.svo.open import open_octree

# --------------------------------------------------------------------------- voxel scenes

DAMAGES = ["float", "nan", "inf", "negative", "huge", "bool", "text", "complex", "truncate",
           "empty", "flat", "transpose", "scalar", "drop"]


def damaged(array: np.ndarray, change: str) -> np.ndarray | None:
    """``array`` with one kind of damage; None removes the array from the file."""
    if change == "float":
        return array.astype(np.float64) + 0.5
    if change == "nan":
        out = array.astype(np.float64)
        out.flat[0] = np.nan
        return out
    if change == "inf":
        out = array.astype(np.float64)
        out.flat[-1] = np.inf
        return out
    if change == "negative":
        return -np.abs(array) - 1
    if change == "huge":
        return array.astype(np.int64) + 2**40
    if change == "bool":
        return array.astype(bool)
    if change == "text":
        return array.astype(str)
    if change == "complex":
        return array.astype(np.complex64)
    if change == "truncate":
        return array[: len(array) // 2]
    if change == "empty":
        return array[:0]
    if change == "flat":
        return array.reshape(-1)
    if change == "transpose":
        return np.ascontiguousarray(array.T)
    if change == "scalar":
        return np.array(array.flat[0])
    return None


@pytest.fixture(scope="module")
def scene_arrays():
    rng = np.random.default_rng(3)
    coords = np.unique(rng.integers(0, 12, (60, 3)), axis=0).astype(np.int32)
    n = len(coords)
    return {"coords": coords, "color": rng.random((n, 3), np.float32),
            "emission": np.zeros((n, 3), np.float32),
            "channel_noon": rng.random((n, 3), np.float32)}


@given(names=st.lists(st.sampled_from(["coords", "color", "emission", "channel_noon"]),
                      min_size=1, max_size=2, unique=True),
       changes=st.lists(st.sampled_from(DAMAGES), min_size=2, max_size=2))
def test_voxel_scene_files_with_damaged_arrays(tmp_path_factory, scene_arrays, names, changes):
    arrays = dict(scene_arrays)
    for name, change in zip(names, changes, strict=False):
        value = damaged(arrays[name], change)
        if value is None:
            del arrays[name]
        else:
            arrays[name] = value
    path = tmp_path_factory.mktemp("scene") / "voxels.npz"
    buffer = io.BytesIO()
    np.savez(buffer, **arrays)
    path.write_bytes(buffer.getvalue())
    try:
        octree = open_octree(str(path))
    except VoxfieldError:
        return
    # Whatever loads is a whole, finite octree of at least one voxel.
    assert octree.voxel_count >= 1
    assert np.isfinite(octree.color).all()


@given(cut=st.integers(0, 4000), flip=st.integers(0, 4000), value=st.integers(0, 255))
def test_voxel_scene_files_with_damaged_bytes(tmp_path_factory, scene_arrays, cut, flip, value):
    buffer = io.BytesIO()
    np.savez_compressed(buffer, **scene_arrays)
    data = bytearray(buffer.getvalue())
    data[flip % len(data)] = value
    path = tmp_path_factory.mktemp("bytes") / "voxels.npz"
    path.write_bytes(bytes(data[: max(1, len(data) - cut)]))
    try:
        octree = open_octree(str(path))
    except VoxfieldError:
        return
    assert np.isfinite(octree.color).all()


# --------------------------------------------------------------------------- probe sets

OPTIONS = BakeOptions(resolution=8, renderer="lod", lod=0)


@pytest.fixture(scope="module")
def baked_folder(tmp_path_factory):
    octree = build_octree(cornell(16))
    lo, hi = octree.voxel_bounds
    folder = tmp_path_factory.mktemp("probes") / "set"
    bake_to_folder(octree, ProbeGrid.fit(lo, hi, (2, 1, 2)), OPTIONS, folder, scheduler="serial")
    return folder


JSON_VALUES = st.recursive(
    st.none() | st.booleans() | st.integers(-2**70, 2**70)
    | st.floats(allow_nan=True, allow_infinity=True) | st.text(max_size=6),
    lambda children: st.lists(children, max_size=4)
    | st.dictionaries(st.text(max_size=4), children, max_size=3),
    max_leaves=8,
)


def header_paths(header, prefix=()):
    """Every key path into the header's nested objects and lists."""
    if isinstance(header, dict):
        for key, value in header.items():
            yield (*prefix, key)
            yield from header_paths(value, (*prefix, key))
    elif isinstance(header, list):
        for index, value in enumerate(header):
            yield (*prefix, index)
            yield from header_paths(value, (*prefix, index))


def _open_or_refuse(folder):
    try:
        probe_set = open_probe_set(folder)
    except VoxfieldError:
        return
    # Whatever opens is whole: no NaN distance (inf marks a direction that sees nothing).
    assert not np.isnan(probe_set.distance).any()
    assert np.isfinite(probe_set.radiance).all()


@given(data=st.data(), remove=st.booleans())
def test_probe_set_headers_with_one_field_changed(tmp_path_factory, baked_folder, data,
                                                  remove):
    folder = tmp_path_factory.mktemp("header") / "set"
    shutil.copytree(baked_folder, folder)
    header = json.loads((folder / "probes.json").read_text())
    path = data.draw(st.sampled_from(sorted(header_paths(header), key=repr)))
    parent = header
    for key in path[:-1]:
        parent = parent[key]
    if remove and isinstance(parent, dict):
        del parent[path[-1]]
    else:
        parent[path[-1]] = data.draw(JSON_VALUES)
    (folder / "probes.json").write_text(json.dumps(header))
    _open_or_refuse(folder)


@given(which=st.sampled_from(["probes.json", "probe_00000.npz", "probe_00003.npz"]),
       cut=st.integers(0, 3000), flip=st.integers(0, 3000), value=st.integers(0, 255))
def test_probe_set_files_with_damaged_bytes(tmp_path_factory, baked_folder, which, cut, flip,
                                            value):
    folder = tmp_path_factory.mktemp("bytes") / "set"
    shutil.copytree(baked_folder, folder)
    target = folder / which
    data = bytearray(target.read_bytes())
    data[flip % len(data)] = value
    target.write_bytes(bytes(data[: max(0, len(data) - cut)]))
    _open_or_refuse(folder)
