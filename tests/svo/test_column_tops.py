"""The column-top pyramid against a column-by-column scan of the voxels."""

from __future__ import annotations

import numpy as np
import pytest

from random_scenes import hollow_shell_terrain, overhanging_terrain, random_scene
from voxfield.kernels.column_walk import TOP_RUN_NODES
from voxfield.svo import build_octree
from voxfield.svo.column_tops import (
    GAP_OPEN,
    GAP_OPEN_16,
    RECORD_FIELD_BITS,
    column_tops,
    gap_open,
    octree_column_tops,
    tops_ahead,
)


def voxels_of(scene) -> np.ndarray:
    octree = build_octree(scene)
    return octree.node_coords(octree.depth)


def scanned_columns(voxels: np.ndarray):
    """Per column ``(x, z)``: the top, the lowest ``y`` of the run that ends at it, and the
    top of the highest voxel under that run (0 when none)."""
    found = {}
    for x, z in {(int(x), int(z)) for x, _, z in voxels}:
        ys = set(voxels[(voxels[:, 0] == x) & (voxels[:, 2] == z), 1].tolist())
        bottom = max(ys)
        while bottom - 1 in ys:
            bottom -= 1
        under = max((y + 1 for y in ys if y < bottom), default=0)
        found[x, z] = (max(ys) + 1, bottom, under)
    return found


def test_tops_top_runs_and_what_lies_under_them_match_a_scan_of_each_column():
    for scene in (overhanging_terrain(seed=1), random_scene(seed=2, n=500, size=13)):
        voxels = voxels_of(scene)
        pyramid = column_tops(voxels)
        width, depth = int(pyramid.level_width[0]), int(pyramid.level_depth[0])
        assert (width, depth) == (voxels[:, 0].max() + 1, voxels[:, 2].max() + 1)
        tops = pyramid.tops[:width * depth].reshape(width, depth)
        bottoms = pyramid.run_bottom[:width * depth].reshape(width, depth)
        expected = np.zeros((3, width, depth), int)
        for (x, z), found in scanned_columns(voxels).items():
            expected[:, x, z] = found
        assert np.array_equal(tops, expected[0])
        assert np.array_equal(bottoms, expected[1])
        assert np.array_equal(pyramid.under_top.reshape(width, depth), expected[2])
        assert np.any(expected[2] > 0)
        # Some columns have voxels below a gap, so the run bottom is not the lowest voxel.
        lowest = {(x, z): voxels[(voxels[:, 0] == x) & (voxels[:, 2] == z), 1].min()
                  for (x, z) in scanned_columns(voxels)}
        assert any(bottoms[x, z] > low for (x, z), low in lowest.items())


def test_every_level_holds_the_highest_top_of_the_columns_it_covers():
    voxels = voxels_of(random_scene(seed=3, n=400, size=11))
    pyramid = column_tops(voxels)
    base = pyramid.tops[:pyramid.level_width[0] * pyramid.level_depth[0]].reshape(
        pyramid.level_width[0], pyramid.level_depth[0])
    assert pyramid.level_width[-1] == pyramid.level_depth[-1] == 1
    assert pyramid.tops[-1] == voxels[:, 1].max() + 1
    for level in range(len(pyramid.level_width)):
        w, d = int(pyramid.level_width[level]), int(pyramid.level_depth[level])
        start = int(pyramid.level_offset[level])
        cells = pyramid.tops[start:start + w * d].reshape(w, d)
        side = 1 << level
        for x in range(w):
            for z in range(d):
                block = base[x * side:(x + 1) * side, z * side:(z + 1) * side]
                assert cells[x, z] == block.max()


def test_every_node_of_a_cells_known_run_holds_a_voxel():
    """A coarser cell's run bottom: every node of its side from there up to the cell's top
    node holds a voxel (checked against the voxels), and the run reaches below the top node
    in many cells of every scene, up to the levels of 4 and 8 voxels."""
    for scene in (overhanging_terrain(seed=1), hollow_shell_terrain(seed=2),
                  random_scene(seed=3, n=500, size=20)):
        voxels = voxels_of(scene)
        pyramid = column_tops(voxels)
        occupied = np.zeros(tuple(voxels.max(axis=0) + 1), bool)
        occupied[tuple(voxels.T)] = True
        longer = np.zeros(len(pyramid.level_width), int)
        for level in range(1, len(pyramid.level_width)):
            side = 1 << level
            w, d = int(pyramid.level_width[level]), int(pyramid.level_depth[level])
            start = int(pyramid.level_offset[level])
            for x in range(w):
                for z in range(d):
                    top = int(pyramid.tops[start + x * d + z])
                    bottom = int(pyramid.run_bottom[start + x * d + z])
                    if top == 0:
                        continue
                    assert bottom % side == 0 and bottom < top
                    block = occupied[x * side:(x + 1) * side, :, z * side:(z + 1) * side]
                    for y in range(bottom // side, -(-top // side)):
                        assert block[:, y * side:(y + 1) * side, :].any(), (level, x, z, y)
                    longer[level] += bottom // side < -(-top // side) - 1
        assert longer[1] > 0 and longer[2] > 0 and longer[3] > 0


@pytest.mark.parametrize("step_x, step_z", [(1, 1), (1, -1), (-1, 1), (-1, -1)])
def test_tops_ahead_are_the_highest_of_each_cell_and_the_three_ahead_of_it(step_x, step_z):
    voxels = voxels_of(random_scene(seed=4, n=450, size=13))
    pyramid = column_tops(voxels)
    ahead = tops_ahead(pyramid, step_x, step_z)
    assert ahead.shape == pyramid.tops.shape and ahead.dtype == pyramid.tops.dtype
    given = np.full_like(ahead, -7)
    assert tops_ahead(pyramid, step_x, step_z, out=given) is given
    assert np.array_equal(given, ahead)
    for level in range(len(pyramid.level_width)):
        w, d = int(pyramid.level_width[level]), int(pyramid.level_depth[level])
        start = int(pyramid.level_offset[level])
        cells = pyramid.tops[start:start + w * d].reshape(w, d)
        found = ahead[start:start + w * d].reshape(w, d)
        for x in range(w):
            for z in range(d):
                neighbours = [cells[a, b] for a in (x, x + step_x) for b in (z, z + step_z)
                              if 0 <= a < w and 0 <= b < d]
                assert found[x, z] == max(neighbours)


def test_tops_ahead_take_unit_steps_only():
    pyramid = column_tops(voxels_of(random_scene(seed=1, n=50, size=5)))
    with pytest.raises(ValueError, match="steps"):
        tops_ahead(pyramid, 0, 1)


def test_every_level_holds_the_gap_all_of_its_columns_leave_under_their_top_runs():
    seen_open = seen_floor = False
    for scene in (overhanging_terrain(seed=7, size=19), random_scene(seed=2, n=300, size=13)):
        voxels = voxels_of(scene)
        pyramid = column_tops(voxels)
        w0, d0 = int(pyramid.level_width[0]), int(pyramid.level_depth[0])
        floor = np.zeros((w0, d0), int)
        ceiling = np.full((w0, d0), gap_open(pyramid))  # an empty column: no run above its gap
        for (x, z), (_, bottom, under) in scanned_columns(voxels).items():
            floor[x, z], ceiling[x, z] = under, bottom
        seen_open |= bool(np.any(ceiling == gap_open(pyramid)))
        seen_floor |= bool(np.any(floor > 0))
        for level in range(len(pyramid.level_width)):
            w, d = int(pyramid.level_width[level]), int(pyramid.level_depth[level])
            start = int(pyramid.level_offset[level])
            floors = pyramid.gap_floor[start:start + w * d].reshape(w, d)
            ceilings = pyramid.gap_ceiling[start:start + w * d].reshape(w, d)
            side = 1 << level
            for x in range(w):
                for z in range(d):
                    cells = (slice(x * side, (x + 1) * side), slice(z * side, (z + 1) * side))
                    assert floors[x, z] == floor[cells].max()
                    assert ceilings[x, z] == ceiling[cells].min()
    assert seen_open and seen_floor


def test_heights_are_int16_below_32767_voxels_high_and_int32_above():
    """A top of 32,767 would be the empty cell's ceiling in int16: such worlds keep int32,
    with the same pyramid; lower ones int16."""
    low = np.array([[0, 3, 0], [0, 4, 0], [2, GAP_OPEN_16 - 2, 1]], np.int32)
    high = low + np.array([0, 1, 0], np.int32)  # the highest top reaches 32,767
    narrow, wide = column_tops(low), column_tops(high)
    assert narrow.tops.dtype == np.int16 and gap_open(narrow) == GAP_OPEN_16
    assert wide.tops.dtype == np.int32 and gap_open(wide) == GAP_OPEN
    assert int(narrow.tops.max()) == GAP_OPEN_16 - 1 and int(wide.tops.max()) == GAP_OPEN_16
    for pyramid in (narrow, wide):
        for heights in (pyramid.tops, pyramid.run_bottom, pyramid.gap_floor,
                        pyramid.gap_ceiling, pyramid.floors):
            assert heights.dtype == pyramid.tops.dtype
        # Column (1, 0) is empty: open above, nothing in it; (0, 0) has the run 3..4.
        assert pyramid.gap_ceiling[1 * 2 + 0] == gap_open(pyramid)
        assert pyramid.floors[1 * 2 + 0] == gap_open(pyramid)
        assert pyramid.tops[0] - (1 if pyramid is wide else 0) == 5
    floors = narrow.floors.astype(np.int64)
    shifted = wide.floors.astype(np.int64) - 1
    assert np.array_equal(np.where(floors == GAP_OPEN_16, GAP_OPEN, floors),
                          np.where(shifted == GAP_OPEN - 1, GAP_OPEN, shifted))


def test_no_pyramid_for_no_voxels_a_footprint_over_the_limit_or_a_world_too_high():
    voxels = voxels_of(random_scene(seed=4, n=100, size=9))
    assert len(column_tops(voxels).level_width) > 0
    assert len(column_tops(voxels, max_columns=8).level_width) == 0
    assert len(column_tops(voxels[:0]).level_width) == 0
    # A top of GAP_OPEN would be an empty cell's ceiling, and no record field holds more.
    tallest = np.array([[0, 0, 0], [1, GAP_OPEN - 2, 1]], np.int32)
    assert len(column_tops(tallest).level_width) > 0
    assert len(column_tops(tallest + [0, 1, 0]).level_width) == 0


def test_an_octrees_pyramid_keeps_the_nodes_of_each_columns_top_run():
    octree = build_octree(overhanging_terrain(seed=6))
    pyramid = octree_column_tops(octree)
    width, depth = int(pyramid.level_width[0]), int(pyramid.level_depth[0])
    tops = pyramid.tops[:width * depth].astype(np.int64)
    bottoms = pyramid.run_bottom[:width * depth].astype(np.int64)
    coords = octree.all_node_coords()
    nodes = pyramid.top_nodes.reshape(width * depth, TOP_RUN_NODES)
    assert pyramid.top_nodes.dtype == np.int32
    x, z = np.divmod(np.arange(width * depth), depth)
    filled = tops > 0
    assert filled.sum() > 100
    runs_seen = np.zeros(TOP_RUN_NODES, bool)
    for k in range(TOP_RUN_NODES):
        y = tops - 1 - k
        kept = filled & (y >= bottoms)  # voxel k under the top is in the top run
        runs_seen[k] = kept.any()
        assert np.all(nodes[~kept, k] == -1)
        assert np.all(octree.node_level(nodes[kept, k]) == octree.depth)
        np.testing.assert_array_equal(coords[nodes[kept, k]],
                                      np.column_stack([x, y, z])[kept])
    assert runs_seen.all() and (nodes[filled, -1] == -1).any()  # short runs end early
    assert len(column_tops(octree.node_coords(octree.depth)).top_nodes) == 0  # nodes unknown


def test_no_top_run_nodes_past_int32():
    voxels = voxels_of(random_scene(seed=2, n=60, size=6))
    first = 2**31 - 1 - len(voxels)  # the last voxel's node is the largest int32 but one
    kept = column_tops(voxels, first_node=first).top_nodes
    assert len(kept) > 0 and kept.max() <= 2**31 - 2 and kept[kept >= 0].min() >= first
    assert len(column_tops(voxels, first_node=2**31 - len(voxels) + 1).top_nodes) == 0


def test_cell_records_pack_each_cells_top_and_gap_as_signed_fields():
    """A cell's record unpacks (low field first, each sign-extended) to its top, gap floor
    and gap ceiling, the empty cells' open ceiling included, for int16 and int32 heights
    alike (up to ``GAP_OPEN``); a pyramid built without them keeps none."""
    voxels = voxels_of(overhanging_terrain(seed=3))
    tall = np.concatenate([voxels, [[0, GAP_OPEN - 2, 0]]]).astype(np.int32)
    for columns, open_value in ((column_tops(voxels, records=True), GAP_OPEN_16),
                                (column_tops(tall, records=True), GAP_OPEN)):
        records = columns.cell_records
        assert records.dtype == np.int64 and len(records) == len(columns.tops)
        bits = RECORD_FIELD_BITS

        def field(k, records=records, bits=bits):
            return ((records << (64 - (k + 1) * bits)) >> (64 - bits)).astype(np.int64)

        assert np.array_equal(field(0), columns.tops)
        assert np.array_equal(field(1), columns.gap_floor)
        assert np.array_equal(field(2), columns.gap_ceiling)
        assert np.any(columns.gap_ceiling == open_value)  # the largest value survives
        assert columns.tops.dtype == (np.int32 if open_value == GAP_OPEN else np.int16)
        assert np.all(records >> (3 * bits) == 0)
    assert column_tops(tall).tops.max() == GAP_OPEN - 1
    bare = column_tops(voxels, records=False)
    assert len(bare.cell_records) == 0 and np.array_equal(bare.tops, column_tops(voxels).tops)
