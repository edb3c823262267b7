"""Probe grids (probes/grid.py): lattice order and positions, fitting a box, the CLI's --grid
forms, the JSON round trip, hand-set offsets, and relocation out of and away from voxels.

Relocation is checked against a brute-force oracle: the exact Euclidean distance from a point to
the nearest solid voxel (point-to-box distance over every voxel of a small scene).
"""

from __future__ import annotations

import json
import warnings

import numpy as np
import pytest

from voxfield.errors import VoxfieldError
from voxfield.probes.grid import (
    CLEAR,
    ESCAPED,
    INSIDE,
    MAX_OFFSET_FRACTION,
    PUSHED,
    SKIPPED,
    TOO_CLOSE,
    ProbeGrid,
    fibonacci_directions,
    parse_grid,
    placement_problem,
    probes_inside,
    relocate,
)
from voxfield.scene.voxel_scene import VoxelScene
from voxfield.svo import build_octree

# --- lattice ------------------------------------------------------------------------------


def test_positions_follow_x_fastest_then_y_then_z():
    grid = ProbeGrid(origin=(1.0, 2.0, 3.0), spacing=(2.0, 3.0, 5.0), counts=(3, 2, 4))
    assert grid.count == len(grid) == 24
    pos = grid.positions
    assert pos.shape == (24, 3)
    for k in range(4):
        for j in range(2):
            for i in range(3):
                index = i + 3 * (j + 2 * k)
                assert grid.probe_index(i, j, k) == index
                assert np.array_equal(pos[index], [1 + 2 * i, 2 + 3 * j, 3 + 5 * k])
                assert np.array_equal(grid.lattice_coords[index], [i, j, k])
    # Arrays of coordinates give arrays of indices.
    idx = grid.probe_index(np.array([0, 2]), np.array([1, 1]), np.array([3, 0]))
    assert idx.tolist() == [grid.probe_index(0, 1, 3), grid.probe_index(2, 1, 0)]
    with pytest.raises(VoxfieldError, match="out of range"):
        grid.probe_index(3, 0, 0)
    with pytest.raises(VoxfieldError, match="integers"):
        grid.probe_index(0.5, 0, 0)


def test_anisotropic_spacing_and_offsets_move_positions():
    grid = ProbeGrid(origin=(0.0, 0.0, 0.0), spacing=(4.0, 16.0, 1.0), counts=(2, 2, 2))
    base = grid.base_positions
    assert np.array_equal(np.unique(base[:, 0]), [0, 4])
    assert np.array_equal(np.unique(base[:, 1]), [0, 16])
    assert np.array_equal(np.unique(base[:, 2]), [0, 1])
    offsets = np.zeros((8, 3))
    offsets[5] = (2.0, -8.0, 0.5)  # exactly half a cell on every axis is allowed
    moved = grid.with_offsets(offsets)
    assert np.array_equal(moved.positions, base + offsets)
    assert np.array_equal(moved.base_positions, base)
    assert np.array_equal(grid.offsets, np.zeros((8, 3)))  # the original is unchanged


def test_offsets_by_hand_are_refused_when_too_large():
    grid = ProbeGrid(origin=(0.0, 0.0, 0.0), spacing=(4.0, 16.0, 1.0), counts=(2, 2, 2))
    offsets = np.zeros((8, 3))
    offsets[3, 2] = 0.51  # more than half of the 1-voxel z spacing
    with pytest.raises(VoxfieldError, match="probe 3's offset"):
        grid.with_offsets(offsets)
    offsets[3, 2] = 0.0
    offsets[3, 1] = 7.9  # fine on y (spacing 16)
    assert grid.with_offsets(offsets).offsets[3, 1] == 7.9
    with pytest.raises(VoxfieldError, match="8×3"):
        grid.with_offsets(np.zeros((7, 3)))
    with pytest.raises(VoxfieldError, match="NaN"):
        grid.with_offsets(np.full((8, 3), np.nan))


def test_grid_is_read_only_and_compares_by_value():
    grid = ProbeGrid((0, 0, 0), (1, 1, 1), (2, 2, 2))
    with pytest.raises(ValueError):
        grid.offsets[0, 0] = 0.1
    with pytest.raises(ValueError):
        grid.enabled[0] = False
    assert grid == ProbeGrid((0.0, 0.0, 0.0), (1.0, 1.0, 1.0), (2, 2, 2))
    assert grid != grid.with_enabled(np.array([False] + [True] * 7))


@pytest.mark.parametrize("origin, spacing, counts, match", [
    ((0, 0), (1, 1, 1), (1, 1, 1), "origin"),
    ((0, 0, np.nan), (1, 1, 1), (1, 1, 1), "NaN"),
    ((0, 0, 0), (1, 0, 1), (1, 1, 1), "positive"),
    ((0, 0, 0), (1, 1, 1), (1, 0, 1), ">= 1"),
    ((0, 0, 0), (1, 1, 1), (1, 2.5, 1), "whole"),
    ((0, 0, 0), (1, 1, 1), (1000, 1000, 1000), "more than"),
    # Positions past float64's reach, or too far out to resolve a voxel: a probe header
    # edited so rendered with NumPy overflow notes and a camera at infinity, or silently.
    ((1e308, 1e308, 1e308), (16, 16, 16), (2, 2, 2), "must lie within"),
    ((8, 8, 8), (1e308, 16, 16), (2, 2, 2), "must lie within"),
    ((8, 8, 8), (1e308, 16, 16), (3, 2, 2), "must lie within"),  # overflows to infinity
    ((-2.0**51, 0, 0), (1, 1, 1), (1, 1, 1), "must lie within"),
    # Probes a rounding step apart: 1e-310, or 16 next to 1e12.
    ((8, 8, 8), (1e-310, 16, 16), (2, 2, 2), "too small"),
    ((1e12, 0, 0), (16, 16, 16), (2, 2, 2), "too small"),
])
def test_bad_grids_are_refused(origin, spacing, counts, match):
    with np.errstate(over="raise", invalid="raise"):  # refused before anything overflows
        with pytest.raises(VoxfieldError, match=match):
            ProbeGrid(origin, spacing, counts)


def test_grids_far_out_or_of_one_probe_with_any_spacing_are_kept():
    far = ProbeGrid((1e9, -1e9, 2.0**49), (8, 8, 1), (2, 2, 1))  # z: one probe
    assert np.all(np.diff(np.unique(far.positions[:, 0])) == 8)
    lone = ProbeGrid((1e6, 0, 0), (1e-300, 1e-300, 1e-300), (1, 1, 1))
    assert lone.positions.tolist() == [[1e6, 0.0, 0.0]]


def test_cell_of_points_clamps_to_cells_with_eight_probes():
    grid = ProbeGrid(origin=(0.0, 0.0, 0.0), spacing=(2.0, 4.0, 8.0), counts=(4, 3, 1))
    points = np.array([[0.0, 0.0, 0.0], [2.5, 4.1, 3.0], [5.99, 7.9, -9.0], [100.0, -5.0, 50.0]])
    cells = grid.cell_of(points)
    assert cells.tolist() == [[0, 0, 0], [1, 1, 0], [2, 1, 0], [2, 0, 0]]
    with pytest.raises(VoxfieldError, match="M×3"):
        grid.cell_of(np.zeros(3))


def test_fit_puts_probes_at_cell_centres_of_the_box():
    grid = ProbeGrid.fit((0, 0, 0), (32, 16, 64), (4, 2, 8))
    assert np.array_equal(grid.spacing, [8, 8, 8])
    assert np.array_equal(grid.origin, [4, 4, 4])
    pos = grid.positions
    assert np.array_equal(pos.min(axis=0), [4, 4, 4])
    assert np.array_equal(pos.max(axis=0), [28, 12, 60])
    # margin 0 puts the end probes on the box faces; one probe per axis sits at the centre.
    faces = ProbeGrid.fit((0, 0, 0), (30, 10, 10), (4, 1, 2), margin=0.0)
    assert np.array_equal(faces.positions.min(axis=0), [0, 5, 0])
    assert np.array_equal(faces.positions.max(axis=0), [30, 5, 10])
    with pytest.raises(VoxfieldError, match="empty"):
        ProbeGrid.fit((0, 0, 0), (10, 0, 10), (2, 2, 2))
    with pytest.raises(VoxfieldError, match="margin"):
        ProbeGrid.fit((0, 0, 0), (10, 10, 10), (2, 2, 2), margin=-1)


def test_parse_grid_counts_form_fits_the_bounds():
    bounds = (np.array([0, 0, 0]), np.array([32, 16, 32]))
    grid = parse_grid("4x2x4", bounds)
    assert grid == ProbeGrid.fit(*bounds, (4, 2, 4))
    assert parse_grid(" 4 X 2 × 4 ", bounds) == grid
    with pytest.raises(VoxfieldError, match="no scene box"):
        parse_grid("4x2x4", None)


def test_parse_grid_explicit_form():
    grid = parse_grid("origin=1,2,3;spacing=2,4,8;counts=3,2,1")
    assert grid == ProbeGrid((1, 2, 3), (2, 4, 8), (3, 2, 1))
    # Keys in any order, spaces allowed, one spacing for all axes.
    same = parse_grid(" counts = 3,2,1 ; spacing=2,4,8; origin=1,2,3 ;")
    assert same == grid
    iso = parse_grid("origin=0,0,0;spacing=5;counts=2,2,2")
    assert np.array_equal(iso.spacing, [5, 5, 5])


@pytest.mark.parametrize("text, match", [
    ("", "empty"),
    ("4x4", "cannot read"),
    ("4x4x0", ">= 1"),
    ("axbxc", "cannot read"),
    ("origin=0,0,0;spacing=1,1,1", "lacks counts"),
    ("origin=0,0,0;spacing=1,1,1;counts=2,2,2;origin=1,1,1", "twice"),
    ("origin=0,0;spacing=1,1,1;counts=2,2,2", "origin"),
    ("origin=0,0,0;spacing=1,-1,1;counts=2,2,2", "positive"),
    ("origin=0,0,0;spacing=one;counts=2,2,2", "must be numbers"),
    ("origin=0,0,0;size=1;counts=2,2,2", "cannot read"),
    ("origin=0,0,0;spacing=1;counts=2,2.5,2", "whole"),
])
def test_parse_grid_refuses_bad_text(text, match):
    with pytest.raises(VoxfieldError, match=match):
        parse_grid(text, (np.zeros(3), np.full(3, 16)))


@pytest.mark.parametrize("text", ["0x2x2", "origin=0,0,0;spacing=1;counts=0,2,2"])
def test_refused_counts_read_as_they_were_written(text):
    """They read "got [0.0, 2.0, 2.0]", the floats the counts were parsed as."""
    with pytest.raises(VoxfieldError, match=r"whole numbers >= 1, got 0x2x2$"):
        parse_grid(text, (np.zeros(3), np.full(3, 16)))


def test_dict_round_trip_is_exact_through_json():
    rng = np.random.default_rng(0)
    grid = ProbeGrid(origin=(0.1, -2 / 3, 1e-17), spacing=(np.pi, 1 / 7, 3.0), counts=(3, 2, 2))
    offsets = rng.uniform(-0.5, 0.5, (12, 3)) * grid.spacing
    enabled = rng.random(12) > 0.3
    grid = grid.with_offsets(offsets).with_enabled(enabled)
    back = ProbeGrid.from_dict(json.loads(json.dumps(grid.to_dict())))
    assert back == grid
    assert back.counts.dtype == np.int64 and back.enabled.dtype == bool
    # A header without offsets or flags means zeros and all enabled.
    plain = ProbeGrid.from_dict({"origin": [0, 0, 0], "spacing": [1, 1, 1], "counts": [2, 1, 1]})
    assert plain == ProbeGrid((0, 0, 0), (1, 1, 1), (2, 1, 1))


@pytest.mark.parametrize("data, match", [
    ({"origin": [0, 0, 0], "spacing": [1, 1, 1]}, "lacks counts"),
    ([1, 2, 3], "mapping"),
    ({"origin": [0, 0, 0], "spacing": [1, 1, 1], "counts": [2, 1, 1], "enabled": [1, 0]},
     "true or false"),
    ({"origin": [0, 0, 0], "spacing": [1, 1, 1], "counts": [2, 1, 1],
      "offsets": [[0, 0, 0], [0, 0]]}, "offsets"),
])
def test_from_dict_refuses_bad_headers(data, match):
    with pytest.raises(VoxfieldError, match=match):
        ProbeGrid.from_dict(data)


# --- relocation ---------------------------------------------------------------------------


def _box_voxels(lo, hi) -> np.ndarray:
    axes = [np.arange(a, b) for a, b in zip(lo, hi, strict=True)]
    return np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)


def _octree(*boxes):
    """An octree of solid boxes (lo inclusive, hi exclusive, voxel units); the first box
    must touch the origin so the octree does not shift the scene."""
    coords = np.unique(np.concatenate([_box_voxels(lo, hi) for lo, hi in boxes]), axis=0)
    assert np.array_equal(coords.min(axis=0), [0, 0, 0])
    return build_octree(VoxelScene(coords, np.full((len(coords), 3), 0.5, np.float32)))


def _distance_to_solid(octree, points) -> np.ndarray:
    """Oracle: exact distance from each point to the nearest solid voxel (0 inside)."""
    voxels = octree.node_coords(octree.depth).astype(np.float64)
    p = np.asarray(points, np.float64)[:, None, :]
    gap = np.maximum(np.maximum(voxels - p, p - (voxels + 1)), 0.0)
    return np.linalg.norm(gap, axis=2).min(axis=1)


def _single_probe(position, spacing=8.0) -> ProbeGrid:
    return ProbeGrid(origin=position, spacing=(spacing,) * 3, counts=(1, 1, 1))


@pytest.fixture(scope="module")
def block():
    """A solid 16³ block at the origin."""
    return _octree(((0, 0, 0), (16, 16, 16)))


@pytest.mark.parametrize("which", ["grid", "octree"])
def test_relocate_names_what_it_was_given_instead(block, which):
    """``relocate(grid, None)`` failed on the octree's first attribute (AttributeError)."""
    grid = _single_probe((30.0, 25.0, 8.0))
    args = (None, block) if which == "grid" else (grid, None)
    with pytest.raises(VoxfieldError, match="relocate needs a "
                       + ("ProbeGrid" if which == "grid" else "voxfield Octree")):
        relocate(*args)


@pytest.mark.parametrize("rays", [5, 4097, 10**7, 64.5, "64"])
def test_relocate_refuses_a_ray_count_it_cannot_hold(block, rays):
    """Ten million rays a probe were held at once and the process was killed for memory."""
    with pytest.raises(VoxfieldError, match=r"relocation takes 6\.\.4096 rays per probe"):
        relocate(_single_probe((30.0, 25.0, 8.0)), block, rays=rays)


def test_probe_in_open_space_is_untouched(block):
    grid = _single_probe((30.0, 25.0, 8.0))
    out, report = relocate(grid, block)
    assert out == grid
    assert report.reasons == (CLEAR,)
    assert report.moved.size == 0 and report.disabled.size == 0


def test_probe_just_inside_a_solid_moves_out_within_max_shift(block):
    grid = _single_probe((15.3, 8.2, 7.6))  # 0.7 inside the +x face
    out, report = relocate(grid, block, max_shift=0.45, clearance=1.6)
    assert report.reasons == (ESCAPED,)
    assert report.moved.tolist() == [0] and out.enabled.all()
    assert np.all(np.abs(out.offsets) <= 0.45 * grid.spacing)
    assert np.array_equal(out.offsets, report.offsets)
    # Out through the nearest face, straight along its normal, to the clearance.
    assert _distance_to_solid(block, out.positions)[0] >= 1.6
    assert out.positions[0, 0] == pytest.approx(16 + 1.6, abs=1e-3)
    assert np.allclose(out.positions[0, 1:], grid.positions[0, 1:])


def test_probe_deep_inside_a_solid_is_disabled(block):
    grid = _single_probe((8.0, 8.5, 7.5))  # 7.5 voxels from every face, 3.6 allowed
    out, report = relocate(grid, block)
    assert report.reasons == (INSIDE,)
    assert report.disabled.tolist() == [0] and report.moved.size == 0
    assert not out.enabled[0]
    assert np.array_equal(out.offsets, grid.offsets)  # disabled probes keep their offsets


def test_probe_near_a_wall_is_pushed_to_the_clearance(block):
    grid = _single_probe((16.5, 8.3, 7.7))  # 0.5 off the +x face
    out, report = relocate(grid, block, clearance=2.0)
    assert report.reasons == (PUSHED,)
    assert _distance_to_solid(block, out.positions)[0] >= 2.0
    assert out.offsets[0] == pytest.approx([1.5, 0, 0], abs=1e-3)  # along the normal only


def test_probe_near_an_edge_is_pushed_on_both_axes(block):
    grid = _single_probe((16.4, 16.7, 8.0))  # next to the block's top +x edge
    out, report = relocate(grid, block, clearance=1.5)
    assert report.reasons == (PUSHED,)
    off = out.offsets[0]
    assert off[0] > 0 and off[1] > 0 and abs(off[2]) < 1e-9
    assert _distance_to_solid(block, out.positions)[0] >= 1.5 * 0.97  # rays sample an edge


def test_probe_exactly_on_a_face_or_corner_is_pushed_out(block):
    """Rays from a point on a voxel face start on the solid and report no face; the push
    comes from the voxels around the point and is exactly along the axes touched."""
    for position, want in [((16.0, 8.0, 8.0), (1.0, 0, 0)), ((16.0, 16.0, 16.0), (1, 1, 1))]:
        grid = _single_probe(position)
        out, report = relocate(grid, block, clearance=1.0)
        assert report.reasons == (PUSHED,), position
        assert out.offsets[0] == pytest.approx(want, abs=1e-3)
        assert _distance_to_solid(block, out.positions)[0] >= 1.0


def test_probe_in_a_corridor_narrower_than_twice_the_clearance_is_disabled():
    # Two slabs with a 3-voxel gap (x in [8, 11)); clearance 2 cannot be kept from both.
    corridor = _octree(((0, 0, 0), (8, 16, 16)), ((11, 0, 0), (19, 16, 16)))
    grid = _single_probe((8.9, 8.0, 8.0))
    out, report = relocate(grid, corridor, clearance=2.0)
    assert report.reasons == (TOO_CLOSE,)
    assert not out.enabled[0] and np.array_equal(out.offsets, grid.offsets)
    # With a clearance that fits, the probe settles between the walls.
    out, report = relocate(grid, corridor, clearance=1.2)
    assert report.reasons == (PUSHED,)
    assert _distance_to_solid(corridor, out.positions)[0] >= 1.2


def test_a_wall_beyond_max_shift_disables_rather_than_overshoots(block):
    grid = _single_probe((16.5, 8.0, 8.0), spacing=4.0)  # may move at most 1.8
    out, report = relocate(grid, block, clearance=3.0)
    assert report.reasons == (TOO_CLOSE,)
    assert not out.enabled[0]


def test_relocating_a_whole_grid_matches_the_oracle():
    """A room (floor, thick walls) with a pillar, a 6×3×6 grid (spacing 6⅔, so at most 3
    voxels of shift), clearance 1.5: every enabled probe ends at least ~the clearance from any
    voxel (exactly for flat walls); disabled ones really were stuck; probes that were fine are
    untouched; and the result is deterministic."""
    room = _octree(
        ((0, 0, 0), (40, 1, 40)), ((0, 0, 0), (2, 20, 40)), ((38, 0, 0), (40, 20, 40)),
        ((0, 0, 0), (40, 20, 1)), ((12, 0, 12), (24, 20, 24)),
    )
    grid = ProbeGrid.fit(*room.voxel_bounds, (6, 3, 6))
    out, report = relocate(grid, room, clearance=1.5)
    again_out, again = relocate(grid, room, clearance=1.5)
    assert again_out == out and again.reasons == report.reasons
    assert np.array_equal(again.offsets, report.offsets)
    before = _distance_to_solid(room, grid.positions)
    after = _distance_to_solid(room, out.positions)
    reasons = np.array(report.reasons)
    ok = out.enabled
    assert np.all(after[ok] >= 1.5 * 0.97), after[ok].min()
    assert np.all(np.abs(out.offsets) <= 0.45 * grid.spacing * (1 + 1e-12))
    clear = reasons == CLEAR
    assert np.all(before[clear] >= 1.5 * 0.97)
    assert np.array_equal(out.offsets[clear], grid.offsets[clear])
    moved = (reasons == PUSHED) | (reasons == ESCAPED)
    assert np.all(before[moved] < 1.5)
    assert np.array_equal(report.moved, np.flatnonzero(moved))
    assert np.array_equal(report.disabled, np.flatnonzero(~out.enabled))
    assert np.array_equal(out.offsets[~ok], grid.offsets[~ok])
    # What happens where: probes 1⅓ from the thick walls are pushed; pillar probes 2/3 from
    # its face escape; those 4⅔ or more inside it cannot get out within 3 voxels.
    pos = grid.positions
    near_wall = (np.abs(pos[:, 0] - 3.33) < 0.01) & ~((pos[:, 2] > 11) & (pos[:, 2] < 25))
    assert np.all(reasons[near_wall] == PUSHED)
    assert np.allclose(out.positions[near_wall, 0], 2 + 1.5, atol=1e-3)
    in_pillar = np.all((pos[:, [0, 2]] > 12) & (pos[:, [0, 2]] < 24), axis=1)
    deep = in_pillar & np.all(np.abs(pos[:, [0, 2]] - 16.67) < 0.01, axis=1)
    assert np.all(reasons[deep] == INSIDE) and deep.sum() == 3
    assert np.all(reasons[in_pillar & ~deep] == ESCAPED) and (in_pillar & ~deep).sum() == 9
    json.dumps(report.to_dict())
    assert "disabled" in report.summary()


def test_already_disabled_probes_are_skipped(block):
    grid = ProbeGrid((8.0, 8.0, 8.0), (20.0, 20.0, 20.0), (2, 1, 1))
    grid = grid.with_enabled(np.array([False, True]))
    out, report = relocate(grid, block)
    assert report.reasons == (SKIPPED, CLEAR)
    assert out.enabled.tolist() == [False, True] and report.disabled.size == 0


def test_relocation_seed_turns_the_rays_but_keeps_flat_walls_exact(block):
    grid = _single_probe((16.5, 8.3, 7.7))
    for seed in range(3):
        out, _ = relocate(grid, block, clearance=2.0, seed=seed)
        assert out.offsets[0] == pytest.approx([1.5, 0, 0], abs=1e-3)
    a, b = fibonacci_directions(64, 0), fibonacci_directions(64, 1)
    assert np.allclose(np.linalg.norm(a, axis=1), 1) and not np.allclose(a, b)
    assert np.array_equal(a, fibonacci_directions(64, 0))
    # Evenly spread: the mean of the directions is near zero.
    assert np.linalg.norm(a.mean(axis=0)) < 0.02


@pytest.mark.parametrize("kwargs, match", [
    ({"max_shift": 0.6}, "max_shift"),
    ({"max_shift": -0.1}, "max_shift"),
    ({"clearance": -1.0}, "clearance"),
    ({"clearance": float("nan")}, "clearance"),
    ({"rays": 3}, "rays"),
    ({"iterations": 0}, "iteration"),
    ({"seed": -1}, "seed"),
])
def test_relocate_refuses_bad_settings(block, kwargs, match):
    with pytest.raises(VoxfieldError, match=match):
        relocate(_single_probe((30.0, 30.0, 30.0)), block, **kwargs)


def test_max_offset_fraction_keeps_probes_in_order():
    assert MAX_OFFSET_FRACTION <= 0.5


# --- placement checks before a bake ----------------------------------------------------------


def test_probes_inside_match_the_voxels_they_stand_in(block):
    """Against the brute-force distance oracle: zero distance is inside (faces belong to
    the voxel above them, so a probe on the block's top face is outside)."""
    grid = ProbeGrid(origin=(2.5, 2.5, 2.5), spacing=(5.0, 5.0, 5.0), counts=(5, 5, 5))
    inside = probes_inside(grid, block)
    strictly_in = np.all((grid.positions > 0) & (grid.positions < 16), axis=1)
    assert np.array_equal(inside, strictly_in)
    assert inside.any() and not inside.all()
    assert np.array_equal(inside, _distance_to_solid(block, grid.positions) == 0)


def test_a_slab_s_fitted_grid_is_all_inside_and_has_nothing_to_bake():
    """A counted grid fits the voxel box: on a thin terrain every probe lands in the
    ground, and the bake wrote all-zero distance maps without a word."""
    slab = _octree(((0, 0, 0), (32, 2, 32)))
    grid = ProbeGrid.fit(*slab.voxel_bounds, (3, 2, 3))
    problem, nothing = placement_problem(grid, slab)
    assert nothing and "all 18 probes stand inside solid voxels" in problem
    assert "--relocate" in problem and "surface:" in problem
    moved, _ = relocate(grid, slab)
    problem, nothing = placement_problem(moved, slab, relocated=True)
    assert nothing and "every probe is disabled" in problem and "--relocate" not in problem


def test_placement_notes_a_grid_partly_inside_or_wholly_outside(block):
    part = ProbeGrid(origin=(8.0, 8.0, 8.0), spacing=(20.0,) * 3, counts=(2, 1, 1))
    problem, nothing = placement_problem(part, block)
    assert not nothing and problem.startswith("1 of 2 probes stand inside")
    far = ProbeGrid(origin=(500.0, 500.0, 500.0), spacing=(4.0,) * 3, counts=(2, 2, 2))
    problem, nothing = placement_problem(far, block)
    assert not nothing and "farther from the scene than its own size" in problem
    dense = ProbeGrid(origin=(20.0, 8.0, 8.0), spacing=(0.25, 4.0, 4.0), counts=(8, 1, 2))
    problem, nothing = placement_problem(dense, block)
    assert not nothing and "less than a voxel apart along x (0.25 voxels)" in problem
    both = ProbeGrid(origin=(15.0, 8.0, 8.0), spacing=(0.5, 4.0, 4.0), counts=(4, 1, 1))
    problem, nothing = placement_problem(both, block)  # every problem, not the first alone
    assert not nothing and "2 of 4 probes stand inside" in problem
    assert "less than a voxel apart along x" in problem
    for beside in ((20.0, 8.0, 8.0), (24.0, 24.0, 24.0)):  # around an object: welcome
        assert placement_problem(_single_probe(beside), block) == (None, False)


@pytest.mark.parametrize("height", ["1e308", "1e16", "0", "-3"])
def test_a_surface_layer_height_out_of_reach_is_refused_before_any_ray(height):
    """``surface:2x2@1e308`` overflowed to infinity (NumPy's warning leaked as a note) and
    was then blamed on the grid's origin, printed as a NumPy repr; the height is now
    refused by name, as explicit grids' positions are, before any ray is cast."""
    text = f"surface:2x2@{height}"
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no overflow warning on the way
        with pytest.raises(VoxfieldError, match="layer height must be a distance above 0 "
                           "and within 1.1259e\\+15 voxels") as refused:
            parse_grid(text, octree=_NO_RAYS)
    assert "array(" not in str(refused.value) and text in str(refused.value)
    with pytest.warns(UserWarning, match="above the scene.s box"):  # a slab: its top is the box
        layer = parse_grid("surface:1x1@1e12", octree=_flat_ground())
    assert layer.positions[0, 1] == pytest.approx(1e12 + 1)


class _NoRays:
    """An octree stand-in that fails if a ray is ever cast against it."""

    @property
    def voxel_bounds(self):
        raise AssertionError("the scene was touched before the height was checked")


_NO_RAYS = _NoRays()


def _flat_ground():
    return _octree(((0, 0, 0), (4, 1, 4)))
