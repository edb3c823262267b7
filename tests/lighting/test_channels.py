"""Extra colour channels: propagation against an independent per-level computation."""

from __future__ import annotations

import numpy as np
import pytest

from random_scenes import random_scene
from voxfield.errors import VoxfieldError
from voxfield.kernels.colour import RGB9E5, from_rgb9e5, to_rgb9e5
from voxfield.render import Camera, render_reference
from voxfield.svo import build_octree
from voxfield.svo.channels import (
    new_channel_block,
    propagate_channel,
    with_channel,
    with_channel_block,
    with_channels,
)
from voxfield.svo.io import load_octree, save_octree


@pytest.fixture(scope="module")
def octree():
    return build_octree(random_scene(seed=3, n=500, size=16), colour_storage="float32")


def leaf_values(octree):
    return octree.node_coords(octree.depth)


def independent_levels(octree, values, weights=None):
    """Node values level by level from dictionaries keyed on node position: a parent is the
    (weighted) mean of the children whose position halves to its own."""
    coords = [tuple(c) for c in leaf_values(octree)]
    level_values = dict(zip(coords, np.asarray(values, np.float64), strict=True))
    level_weights = dict(zip(coords, np.ones(len(coords)) if weights is None else weights,
                             strict=True))
    out = {octree.depth: level_values}
    for level in range(octree.depth - 1, -1, -1):
        groups: dict[tuple, list] = {}
        for c in level_values:
            groups.setdefault(tuple(v >> 1 for v in c), []).append(c)
        parent_values, parent_weights = {}, {}
        for parent, children in groups.items():
            v = np.array([level_values[c] for c in children])
            w = np.array([level_weights[c] for c in children])
            plain = v.mean(axis=0)
            weighted = w.sum() > 0 and weights is not None
            parent_values[parent] = (v * w[:, None]).sum(0) / w.sum() if weighted else plain
            parent_weights[parent] = w.sum()
        level_values, level_weights = parent_values, parent_weights
        out[level] = level_values
    return out


def test_a_channel_made_from_the_albedo_reproduces_the_albedo_bit_for_bit(octree):
    leaves = octree.color[octree.level_slice(octree.depth)]
    copy = with_channel(octree, "copy", leaves)
    assert np.array_equal(copy.attributes["copy"], octree.color)
    assert copy.attributes["copy"].dtype == np.float32
    # Structure is shared, not copied; the original is untouched.
    assert copy.descriptors is octree.descriptors and "copy" not in octree.attributes


@pytest.mark.parametrize("weighted", [False, True])
def test_parent_levels_match_an_independent_computation(octree, weighted):
    rng = np.random.default_rng(7)
    values = rng.random((octree.voxel_count, 3)).astype(np.float32)
    weights = None
    if weighted:
        weights = rng.random(octree.voxel_count) * (rng.random(octree.voxel_count) < 0.6)
    lit = with_channel(octree, "k", values, weights=weights)
    expected = independent_levels(octree, values, weights)
    for level in range(octree.depth + 1):
        sl = octree.level_slice(level)
        want = np.array([expected[level][tuple(c)] for c in octree.node_coords(level)])
        assert np.allclose(lit.attributes["k"][sl], want, rtol=1e-5, atol=1e-6), level


def test_all_zero_weights_fall_back_to_the_plain_mean(octree):
    values = np.random.default_rng(1).random((octree.voxel_count, 3))
    plain = with_channel(octree, "a", values)
    zero = with_channel(octree, "a", values, weights=np.zeros(octree.voxel_count))
    assert np.array_equal(plain.attributes["a"], zero.attributes["a"])


def test_a_constant_factor_channel_renders_as_the_scaled_albedo(octree):
    factor = 0.37
    leaves = octree.color[octree.level_slice(octree.depth)]
    scaled = with_channel(octree, "k", factor * leaves)
    cam = Camera.look_at((30.0, 26.0, 34.0), (8.0, 8.0, 8.0), width=48)
    albedo = render_reference(scaled, cam, side=2, seed=1).image
    k = render_reference(scaled, cam, side=2, seed=1, channel="k").image
    assert albedo.max() > 0.1  # the camera sees the scene
    assert np.allclose(k, factor * albedo, rtol=1e-5, atol=1e-6)


def test_channels_survive_a_save_and_load(octree, tmp_path):
    values = np.full((octree.voxel_count, 3), 0.25)
    lit = with_channels(octree, {"noon": values, "evening": values / 2})
    loaded = load_octree(save_octree(lit, tmp_path / "lit.npz"))
    assert set(loaded.attributes) == {"color", "noon", "evening"}
    assert np.array_equal(loaded.channel("evening"), lit.channel("evening"))


@pytest.mark.parametrize(
    ("name", "values", "weights", "message"),
    [
        ("color", "ok", None, "albedo"),
        ("albedo", "ok", None, "albedo"),
        ("two words", "ok", None, "letters"),
        ("", "ok", None, "letters"),
        ("k", "short", None, "shape"),
        ("k", "nan", None, "NaN"),
        ("k", "ok", "negative", "negative"),
        ("k", "ok", "short", "shape"),
    ],
)
def test_bad_channels_are_refused(octree, name, values, weights, message):
    n = octree.voxel_count
    arrays = {"ok": np.ones((n, 3)), "short": np.ones((n - 1, 3)),
              "nan": np.full((n, 3), np.nan)}
    weight_arrays = {None: None, "negative": -np.ones(n), "short": np.ones(n - 1)}
    with pytest.raises(VoxfieldError, match=message):
        with_channel(octree, name, arrays[values], weights=weight_arrays[weights])


def test_a_channel_block_is_filled_in_place(octree):
    """The bake writes its voxels into a block and the octree keeps the block's rows: the
    channels equal ``propagate_channel``'s and no channel is a copy."""
    rng = np.random.default_rng(3)
    leaves = rng.random((2, octree.voxel_count, 3)).astype(np.float32)
    weights = rng.random(octree.voxel_count)
    block = new_channel_block(octree, 2)
    block[:, octree.level_slice(octree.depth)] = leaves
    lit = with_channel_block(octree, ["a", "b"], block, weights)
    for k, name in enumerate("ab"):
        assert np.shares_memory(lit.attributes[name], block)
        assert np.array_equal(lit.attributes[name], propagate_channel(octree, leaves[k], weights))


def test_a_block_kept_as_rgb9e5_packs_the_float32_levels_and_survives_a_file(octree, tmp_path):
    """Packed channels: the float32 levels (``propagate_channel``'s), each node packed once;
    loaded back code for code."""
    rng = np.random.default_rng(4)
    leaves = (rng.random((2, octree.voxel_count, 3)) * 8).astype(np.float32)
    weights = rng.random(octree.voxel_count)
    block = new_channel_block(octree, 2)
    block[:, octree.level_slice(octree.depth)] = leaves
    lit = with_channel_block(octree, ["a", "b"], block, weights, RGB9E5)
    for k, name in enumerate("ab"):
        expected = propagate_channel(octree, leaves[k], weights)
        assert lit.attributes[name].shape == (octree.node_count,)
        assert np.array_equal(lit.attributes[name], to_rgb9e5(expected))
        assert np.array_equal(lit.channel_linear(name), from_rgb9e5(to_rgb9e5(expected)))
    loaded = load_octree(save_octree(lit, tmp_path / "packed.npz"))
    assert np.array_equal(loaded.channel("b"), lit.channel("b"))
    assert loaded.channel("b").dtype == np.uint32
    with pytest.raises(VoxfieldError, match="channel storage"):
        with_channel_block(octree, ["a"], new_channel_block(octree, 1), None, "float16")
