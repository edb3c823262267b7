"""Error-aware renderer against independent facts (issue: EA §5.1.3–5.1.4).

- a scene whose error is zero everywhere needs no refinement;
- refinement forced everywhere with 2 refinements reproduces the 4×4 reference;
- a larger threshold never casts more rays;
- an infinite threshold is the plain LOD render.
"""

from __future__ import annotations

import copy

import numpy as np
import pytest
from tests.random_scenes import random_scene

from voxfield.error_table import build_error_table, save_error_table
from voxfield.errors import VoxfieldError
from voxfield.render import Camera, render_lod, render_reference
from voxfield.render.error_aware import (
    REPEATING_AXES,
    colour_error,
    colour_spread,
    neighbour_context,
    render_error_aware,
)
from voxfield.scene.builtin import pillars
from voxfield.scene.voxel_scene import VoxelScene
from voxfield.svo import build_octree


@pytest.fixture(scope="module")
def table():
    return build_error_table(n_directions=64, resolution=64, oct_resolution=16, seed=0)


@pytest.fixture(scope="module")
def terrain():
    """Rolling heightfield filling a top-down view completely (no background pixels)."""
    return build_octree(pillars(64))


def _top(octree, size=32):
    lo, hi = octree.voxel_bounds
    c = (lo + hi) / 2
    return Camera.orthographic((c[0], hi[1] + 2, c[2]), (0, -1, 0), (0, 0, -1),
                               view_height=float(hi[0] - lo[0]) * 0.9, width=size)


def _psnr(a, b):
    mse = float(np.mean((a.astype(np.float64) - b) ** 2))
    return np.inf if mse == 0 else 10 * np.log10(1 / mse)


def test_solid_block_has_zero_error_and_needs_no_refinement(table):
    # A solid 16³ block: every inner node has all 8 children (error 0 from every direction).
    coords = np.argwhere(np.ones((16, 16, 16), bool))
    octree = build_octree(VoxelScene(coords, np.full((len(coords), 3), 0.5)))
    cam = Camera.look_at((30, 25, 40), (8, 8, 8), fov_deg=40, width=32)
    result = render_error_aware(octree, cam, table, threshold=0.01, decay=0.5)
    assert result.maps["refined"].max() == 0
    assert np.array_equal(result.ray_count, np.ones_like(result.ray_count))


def test_forced_refinement_reproduces_the_reference(table, terrain):
    cam = _top(terrain)
    reference = render_reference(terrain, cam, side=4, seed=3)
    forced = render_error_aware(terrain, cam, table, threshold=-1.0, decay=0.2, base_lod=2,
                                max_refinements=2, seed=3)
    assert _psnr(reference.image, forced.image) >= 50.0
    assert np.all(forced.ray_count == 21)  # 1 + 4 discarded, 16 kept
    assert np.all(forced.finest_lod == 0)


def test_larger_threshold_never_casts_more_rays(table, terrain):
    lo, hi = terrain.voxel_bounds
    cam = Camera.look_at((70, 60, 90), (32, 10, 32), fov_deg=50, width=48)
    counts = [render_error_aware(terrain, cam, table, threshold=t).total_rays
              for t in (0.0, 0.05, 0.1, 0.2, 0.4, 0.8)]
    assert all(a >= b for a, b in zip(counts, counts[1:], strict=False)), counts
    assert counts[0] > counts[-1]


def test_infinite_threshold_is_the_lod_render(table, terrain):
    cam = _top(terrain)
    never = render_error_aware(terrain, cam, table, threshold=np.inf, base_lod=2)
    lod = render_lod(terrain, cam, lod=2)
    assert np.array_equal(never.image, lod.image)
    assert np.array_equal(never.steps, lod.steps)


def test_decay_adds_the_childrens_error(table, terrain):
    cam = _top(terrain)
    without = render_error_aware(terrain, cam, table, threshold=0.3, decay=0.0)
    with_decay = render_error_aware(terrain, cam, table, threshold=0.3, decay=1.0)
    assert with_decay.total_rays >= without.total_rays


def test_one_and_two_threads_agree(table, terrain, small_jobs_in_parallel):
    cam = _top(terrain)
    a = render_error_aware(terrain, cam, table, threshold=0.1, threads=1)
    b = render_error_aware(terrain, cam, table, threshold=0.1, threads=2)
    assert np.array_equal(a.image, b.image) and np.array_equal(a.steps, b.steps)


def test_bad_options_raise(table, terrain):
    cam = _top(terrain, 8)
    with pytest.raises(VoxfieldError):
        render_error_aware(terrain, cam, table, max_refinements=9)
    with pytest.raises(VoxfieldError):
        render_error_aware(terrain, cam, table, encoding="wavelet")
    with pytest.raises(VoxfieldError):
        render_error_aware(terrain, cam, table, decay=-1)
    with pytest.raises(VoxfieldError, match="ErrorTable or a path"):
        render_error_aware(terrain, cam, 0.05)  # a threshold where the table goes
    with pytest.raises(VoxfieldError, match="bright ratio"):
        render_error_aware(terrain, cam, table, bright_ratio=None)
    with pytest.raises(VoxfieldError, match="LightingErrorTable or a path"):
        render_error_aware(terrain, cam, table, lighting_aware=True, lighting_table=table)


@pytest.mark.parametrize("name", ["reuse_parent", "lighting_aware", "context_aware",
                                  "colour_to_voxels"])
def test_a_switch_takes_a_bool_not_any_truthy_object(table, terrain, name):
    """``reuse_parent="no"`` turned reuse on (a non-empty string is true)."""
    cam = _top(terrain, 8)
    for value in ("no", 1, None):
        with pytest.raises(VoxfieldError, match=f"{name} must be True or False"):
            render_error_aware(terrain, cam, table, **{name: value})
    as_numpy = render_error_aware(terrain, cam, table, threads=1, **{name: np.bool_(False)})
    plain = render_error_aware(terrain, cam, table, threads=1, **{name: False})
    assert np.array_equal(as_numpy.image, plain.image)


def test_a_table_can_be_named_by_its_path(table, terrain, tmp_path):
    path = save_error_table(table, tmp_path / "table.npz")
    cam = _top(terrain, 8)
    by_path = render_error_aware(terrain, cam, str(path), threshold=0.1, threads=1)
    given = render_error_aware(terrain, cam, table, threshold=0.1, threads=1)
    assert np.array_equal(by_path.image, given.image) and np.array_equal(by_path.steps,
                                                                         given.steps)


def test_parent_reuse_reproduces_the_reference_with_16_rays(table, terrain):
    # Refined everywhere, every finest cell ends with one ray through its CMJ sample at
    # LOD 0, whether new or continued from its parent: the reference, at 16 rays not 21.
    cam = _top(terrain)
    reference = render_reference(terrain, cam, side=4, seed=3)
    reused = render_error_aware(terrain, cam, table, threshold=-1.0, base_lod=2,
                                max_refinements=2, reuse_parent=True, seed=3)
    fresh = render_error_aware(terrain, cam, table, threshold=-1.0, base_lod=2,
                               max_refinements=2, seed=3)
    assert np.allclose(reused.image, reference.image, atol=1e-6)
    assert np.allclose(reused.depth, reference.depth)
    assert np.all(reused.ray_count == 16)  # 1 + 3 + 4·3
    assert np.all(reused.maps["refined"] == 5)
    assert reused.total_steps < fresh.total_steps


def test_parent_reuse_costs_three_new_rays_per_refinement(table, terrain):
    cam = Camera.look_at((70, 60, 90), (32, 10, 32), fov_deg=50, width=48)
    for threshold in (0.05, 0.2):
        reused = render_error_aware(terrain, cam, table, threshold=threshold, reuse_parent=True)
        refined = reused.maps["refined"]
        assert np.array_equal(reused.ray_count, 1 + 3 * refined)
        assert refined.max() > 0
        # Without reuse every refined ray is discarded; with it only continued rays that miss.
        fresh = render_error_aware(terrain, cam, table, threshold=threshold)
        assert np.array_equal(fresh.maps["discarded"], fresh.maps["refined"])
        assert np.all(reused.maps["discarded"] <= refined)


def test_parent_reuse_is_thread_count_independent(table, terrain, small_jobs_in_parallel):
    cam = _top(terrain)
    a = render_error_aware(terrain, cam, table, threshold=0.1, reuse_parent=True, threads=1)
    b = render_error_aware(terrain, cam, table, threshold=0.1, reuse_parent=True, threads=2)
    assert np.array_equal(a.image, b.image) and np.array_equal(a.steps, b.steps)


def test_from_base_lod_0_parent_reuse_changes_nothing(table, terrain):
    """From LOD 0 no ray is refined, so there is no parent to reuse: the rays went through
    hashed cells' samples instead of the pixel centres, a jittered image (741 of 4,096
    pixels of builtin:pillars changed) from a switch that had nothing to do."""
    cam = _top(terrain)
    plain = render_error_aware(terrain, cam, table, base_lod=0, seed=3)
    reused = render_error_aware(terrain, cam, table, base_lod=0, reuse_parent=True, seed=3)
    for name in ("image", "depth", "normal", "ray_count", "steps"):
        assert np.array_equal(getattr(reused, name), getattr(plain, name)), name
    assert reused.params["reuse_parent"] is False
    # From LOD 1 the reused cells still place the first rays off the pixel centres.
    one = [render_error_aware(terrain, cam, table, base_lod=1, threshold=np.inf,
                              reuse_parent=reuse, seed=3) for reuse in (False, True)]
    assert not np.array_equal(one[0].depth, one[1].depth)
    assert one[1].params["reuse_parent"] is True


def _lit_block():
    """A solid 16³ block (no geometric error anywhere) whose top layer is bright, coloured
    as the EA thesis colours LODs (children's mean: the dark interior shows at LOD 1)."""
    coords = np.argwhere(np.ones((16, 16, 16), bool))
    color = np.where((coords[:, 1] == 15)[:, None], 0.9, 0.1) * np.ones(3)
    return build_octree(VoxelScene(coords, color), lod_colour="mean")


def test_lighting_aware_refines_where_only_colour_differs(table):
    octree = _lit_block()
    cam = Camera.orthographic((8, 20, 8), (0, -1, 0), (0, 0, -1), view_height=15.0, width=16)
    plain = render_error_aware(octree, cam, table, threshold=0.2, decay=0.0, base_lod=1)
    lit = render_error_aware(octree, cam, table, threshold=0.2, decay=0.0, base_lod=1,
                             lighting_aware=True)
    reference = render_reference(octree, cam)
    assert plain.maps["refined"].max() == 0
    # LOD 1 nodes on top: 4 bright children over 4 dark ones, colour error 0.5 from above.
    assert np.all(lit.maps["refined"] >= 1)
    assert _psnr(reference.image, lit.image) > _psnr(reference.image, plain.image) + 10


def test_lighting_aware_never_casts_fewer_rays(table, terrain):
    cam = Camera.look_at((70, 60, 90), (32, 10, 32), fov_deg=50, width=48)
    for threshold in (0.1, 0.3):
        plain = render_error_aware(terrain, cam, table, threshold=threshold)
        lit = render_error_aware(terrain, cam, table, threshold=threshold, lighting_aware=True)
        assert np.all(lit.ray_count >= plain.ray_count)


def test_lighting_aware_on_one_colour_is_the_plain_renderer(table):
    coords = np.argwhere(np.indices((12, 12, 12)).sum(axis=0) % 3 != 0)
    octree = build_octree(VoxelScene(coords, np.full((len(coords), 3), 0.4)))
    cam = Camera.look_at((25, 20, 30), (6, 6, 6), fov_deg=45, width=32)
    plain = render_error_aware(octree, cam, table, threshold=0.1)
    lit = render_error_aware(octree, cam, table, threshold=0.1, lighting_aware=True)
    assert np.array_equal(plain.image, lit.image) and np.array_equal(plain.steps, lit.steps)
    with pytest.raises(VoxfieldError):
        render_error_aware(octree, cam, table, lighting_aware=True, bright_ratio=-1)


def test_precomputed_sh_children_term_matches_the_per_child_sum(table, terrain):
    # SH is linear: E_N from the per-node mean coefficients equals e(N) + d·mean_c e(c)
    # evaluated child by child through the table's public interface.
    from voxfield.kernels.error_aware import node_error_precomputed
    from voxfield.render.error_aware import children_sh_means

    means = children_sh_means(terrain, table)
    rng = np.random.default_rng(5)
    inner = int(terrain.level_offsets[terrain.depth])
    for node in rng.integers(0, inner, 40):
        level = int(np.searchsorted(terrain.level_offsets, node, side="right") - 1)
        first = int(terrain.first_child[node])
        n_children = int(np.unpackbits(np.uint8(terrain.child_mask[node])).sum())
        children = terrain.child_mask[first:first + n_children]
        d = rng.normal(size=3)
        d /= np.linalg.norm(d)
        own = float(np.dot(table.sh[terrain.child_mask[node]],
                           _sh_basis(d)))
        kids = np.mean([np.dot(table.sh[m], _sh_basis(d)) for m in children])
        got = node_error_precomputed(int(node), level, terrain.depth, terrain.inner_nodes, 0.3,
                                     table.sh.astype(np.float64), means, *d)
        expected = own + 0.3 * (kids if level + 1 < terrain.depth else 0.0)
        assert got == pytest.approx(expected, abs=1e-9)


@pytest.mark.parametrize("encoding", ["oct", "sh"])
def test_node_error_is_its_masks_table_errors(table, terrain, encoding):
    # ``node_error`` encodes the direction once for all its masks: it must give what a
    # lookup per mask gives, e(N) + d·mean_c e(c), at every level (none for children that
    # are voxels) and with no decay.
    from voxfield.kernels.error_aware import ENCODING_OCT, ENCODING_SH, node_error
    from voxfield.kernels.error_lookup import oct_error, sh_error

    oct_map = np.ascontiguousarray(table.oct_map, np.float64)
    sh = table.sh.astype(np.float64)
    code = ENCODING_SH if encoding == "sh" else ENCODING_OCT

    def lookup(mask, d):
        if encoding == "sh":
            return sh_error(sh, int(mask), *d)
        return oct_error(oct_map, int(mask), *d)

    rng = np.random.default_rng(11)
    inner = int(terrain.level_offsets[terrain.depth])
    above_voxels = terrain.level_slice(terrain.depth - 1)
    nodes = np.concatenate([rng.integers(0, inner, 40),
                            rng.integers(above_voxels.start, above_voxels.stop, 5)])
    for node in nodes:
        level = int(terrain.node_level(node))
        first = int(terrain.first_child[node])
        n_children = int(np.unpackbits(np.uint8(terrain.child_mask[node])).sum())
        children = terrain.child_mask[first:first + n_children]
        d = rng.normal(size=3)
        d /= np.linalg.norm(d)
        own = lookup(terrain.child_mask[node], d)
        kids = np.mean([lookup(m, d) for m in children])
        for decay in (0.0, 0.3):
            got = node_error(int(node), level, terrain.depth, terrain.inner_nodes, decay, code,
                             oct_map, sh, *d)
            has_kids = decay > 0 and level + 1 < terrain.depth
            expected = own + decay * (kids if has_kids else 0.0)
            assert got == pytest.approx(expected, rel=1e-12, abs=1e-15), (node, decay)


def test_sh_renders_of_one_octree_work_out_the_childrens_means_once(table, monkeypatch):
    """The children's mean SH coefficients cover every inner node (426 MiB on the 2048²
    mountain terrain): they are kept with the octree for its table, recoloured copies
    included, and worked out again for another table."""
    from voxfield.render import error_aware

    calls = []
    original = error_aware.children_sh_means
    monkeypatch.setattr(error_aware, "children_sh_means",
                        lambda octree, t: calls.append(t) or original(octree, t))
    octree = build_octree(pillars(32))
    cam = _top(octree, 8)
    first = render_error_aware(octree, cam, table, encoding="sh", threshold=0.1)
    again = render_error_aware(octree.recoloured(name="copy"), cam, table, encoding="sh",
                               threshold=0.1)
    assert len(calls) == 1
    assert np.array_equal(first.image, again.image)
    other = build_error_table(n_directions=32, resolution=32, oct_resolution=8, seed=1)
    render_error_aware(octree, cam, other, encoding="sh", threshold=0.1)
    assert len(calls) == 2


def _sh_basis(d):
    from voxfield.error_table.spherical_harmonics import sh_basis

    return sh_basis(d[None, :])[0]


def test_the_hybrid_refines_colour_edges_the_geometric_error_cannot_see(table):
    """A flat slab, half dark and half bright: no geometric error anywhere, so EA keeps one
    ray a pixel; the hybrid refines the pixels along the colour edge, and only those."""
    coords = np.argwhere(np.ones((32, 1, 32), bool))
    color = np.where((coords[:, 0] < 15)[:, None], 0.05, 0.9) * np.ones(3)
    octree = build_octree(VoxelScene(coords, color))
    cam = Camera.orthographic((16, 10, 16), (0, -1, 0), (0, 0, -1), view_height=32.0, width=32)
    plain = render_error_aware(octree, cam, table, threshold=0.2, base_lod=1)
    hybrid = render_error_aware(octree, cam, table, threshold=0.2, base_lod=1,
                                colour_variance=0.08)
    assert plain.total_rays == 32 * 32
    redone = hybrid.maps["variance_refined"].astype(bool)
    columns = np.flatnonzero(redone.any(axis=0))
    assert len(columns) > 0 and columns.min() >= 12 and columns.max() <= 18  # at the edge
    assert hybrid.total_rays > plain.total_rays
    reference = render_reference(octree, cam)
    assert _psnr(reference.image, hybrid.image) > _psnr(reference.image, plain.image) + 3
    with pytest.raises(VoxfieldError, match="colour variance"):
        render_error_aware(octree, cam, table, colour_variance=0.0)


def test_the_hybrid_refines_from_the_bounds_its_first_pass_started_at(table, monkeypatch):
    """From base LOD 0 the error-aware pass's start bounds are those its variance
    refinements would search for, counted already: the refinements start there and search
    for none of their own, so a pixel they leave keeps the plain render's steps, and every
    pixel is what refinements from bounds of their own give."""
    from voxfield.render import adaptive, orbit_camera

    octree = build_octree(random_scene(seed=4, n=2500, size=24))
    lo, hi = octree.voxel_bounds
    cam = orbit_camera(lo, hi, size=48)
    options = dict(threshold=0.1, base_lod=0)
    plain = render_error_aware(octree, cam, table, **options)
    own = {}
    for saving in (0, 10**9):  # every pass from the block beam; every pass drawing
        monkeypatch.setattr(adaptive, "DRAWN_BOUND_SAVING", saving)
        own[saving] = copy.deepcopy(plain)
        adaptive.refine_by_variance(octree, cam, own[saving], 0.08, 0,
                                    octree.kernel_colours("albedo"))

    def no_search(*args, **kwargs):
        raise AssertionError("a refinement searched for start bounds of its own")

    monkeypatch.setattr(adaptive, "raster_beam", no_search)
    monkeypatch.setattr(adaptive, "primary_beam", no_search)
    hybrid = render_error_aware(octree, cam, table, colour_variance=0.08, **options)
    redone = hybrid.maps["variance_refined"].astype(bool)
    assert redone.any() and (~redone & (plain.hit_count > 0)).any()
    assert np.array_equal(hybrid.steps[~redone], plain.steps[~redone])
    for other in own.values():
        for name in ("image", "depth", "normal", "ray_count", "hit_count", "finest_lod"):
            assert np.array_equal(getattr(hybrid, name), getattr(other, name)), name
    # (Bounds of their own cost the block beam's search or the drawing's cells, which
    # every pixel shares.)
    assert (own[10**9].steps[~redone] > plain.steps[~redone]).any()


def test_colour_spread_is_the_luminance_deviation_of_the_visible_children():
    """A 2×1×2 slab, two black and two white voxels, equally exposed: the LOD-1 node's
    children have luminance 0 and 1 in equal shares, a standard deviation of 0.5."""
    coords = np.array([[0, 0, 0], [1, 0, 0], [0, 0, 1], [1, 0, 1]])
    color = np.array([[0, 0, 0], [1, 1, 1], [0, 0, 0], [1, 1, 1]], np.float32)
    octree = build_octree(VoxelScene(coords, color), colour_storage="float32")
    spread = colour_spread(octree)
    assert spread[octree.level_slice(octree.depth - 1)] == pytest.approx([0.5])
    assert colour_error(octree, 0.5) == pytest.approx(spread)  # voxel children add nothing
    # Stripes over a 4×4 slab: the root adds decay × the mean of its children's spreads.
    slab = np.argwhere(np.ones((4, 1, 4), bool))
    stripes = (slab[:, :1] % 2 * np.ones(3)).astype(np.float32)
    octree = build_octree(VoxelScene(slab, stripes), colour_storage="float32")
    spread = colour_spread(octree)
    children = spread[octree.level_slice(1)]
    assert np.all(children > 0.3)
    assert colour_error(octree, 0.5)[0] == pytest.approx(spread[0] + 0.5 * children.mean())


def test_the_colour_term_refines_a_colour_edge_and_is_off_at_zero(table):
    coords = np.argwhere(np.ones((32, 1, 32), bool))
    color = np.where((coords[:, 0] < 15)[:, None], 0.05, 0.9) * np.ones(3)
    octree = build_octree(VoxelScene(coords, color))
    cam = Camera.orthographic((16, 10, 16), (0, -1, 0), (0, 0, -1), view_height=32.0, width=32)
    plain = render_error_aware(octree, cam, table, threshold=0.2, base_lod=1)
    off = render_error_aware(octree, cam, table, threshold=0.2, base_lod=1, colour_term=0.0)
    on = render_error_aware(octree, cam, table, threshold=0.2, base_lod=1, colour_term=1.0)
    assert np.array_equal(plain.image, off.image) and plain.total_rays == off.total_rays
    refined_columns = np.flatnonzero((on.maps["refined"] > 0).any(axis=0))
    assert len(refined_columns) and refined_columns.min() >= 12 and refined_columns.max() <= 18
    reference = render_reference(octree, cam)
    assert _psnr(reference.image, on.image) > _psnr(reference.image, plain.image) + 3


def test_colour_refinement_can_go_straight_to_the_voxels(table):
    """A 32-wide stripe pattern of one-voxel stripes: from LOD 2, the colour term asks for
    refinement everywhere; one LOD finer still averages the stripes, the voxels do not."""
    coords = np.argwhere(np.ones((32, 1, 32), bool))
    color = (coords[:, :1] % 2 * 0.8 + 0.1) * np.ones(3)
    octree = build_octree(VoxelScene(coords, color))
    cam = Camera.orthographic((16, 10, 16), (0, -1, 0), (0, 0, -1), view_height=32.0, width=16)
    # Decay 1: the LOD-1 children's own stripes count in full, so colour alone decides.
    options = {"threshold": 0.1, "decay": 1.0, "base_lod": 2, "colour_term": 1.0,
               "max_refinements": 1}
    stepwise = render_error_aware(octree, cam, table, **options)
    straight = render_error_aware(octree, cam, table, colour_to_voxels=True, **options)
    hit = straight.hit_count > 0
    assert np.all(stepwise.finest_lod[hit] == 1)
    assert np.all(straight.finest_lod[hit] == 0)
    assert stepwise.total_rays == straight.total_rays  # same refinements, finer samples
    reference = render_reference(octree, cam)
    assert _psnr(reference.image, straight.image) > _psnr(reference.image, stepwise.image) + 3


def test_neighbour_context_marks_same_shaped_neighbours():
    """A 4×1×4 slab of 1×1 voxels at depth 2: its four LOD-1 nodes all hold a half slab, so
    each borders same-shaped neighbours across its inner x and z faces, none above or below."""
    slab = np.argwhere(np.ones((4, 1, 4), bool))
    octree = build_octree(VoxelScene(slab, np.full((16, 3), 0.5, np.float32)))
    context = neighbour_context(octree)[octree.level_slice(1)]
    coords = octree.node_coords(1)
    for (x, _, z), bits in zip(coords.tolist(), context.tolist(), strict=True):
        expected = ((x == 1) << 0) | ((x == 0) << 1) | ((z == 1) << 4) | ((z == 0) << 5)
        assert bits == expected
    assert neighbour_context(octree)[0] == 0  # the root has no neighbours


def test_repeating_axes_of_child_masks():
    assert REPEATING_AXES[0b00110011].tolist() == [True, False, True]  # lower half in y
    assert REPEATING_AXES[0xFF].tolist() == [True, True, True]
    assert REPEATING_AXES[0b00000001].tolist() == [False, False, False]


def test_context_aware_error_stops_flat_ground_refining(table):
    ground = np.argwhere(np.ones((64, 2, 64), bool))
    octree = build_octree(VoxelScene(ground, np.full((len(ground), 3), 0.5, np.float32)))
    cam = Camera.look_at((32, 30, 90), (32, 0, 20), fov_deg=50, width=32)
    plain = render_error_aware(octree, cam, table, threshold=0.1, base_lod=2)
    aware = render_error_aware(octree, cam, table, threshold=0.1, base_lod=2,
                               context_aware=True)
    assert plain.maps["refined"].sum() > 100
    # What still refines is the ground's edge, where neighbours end.
    assert aware.maps["refined"].sum() < plain.maps["refined"].sum() / 3
    # It only ever drops errors: on a scattered scene no pixel refines more than before.
    scattered = build_octree(random_scene(5, n=900, size=16))
    cam = Camera.look_at((30, 25, 40), (8, 8, 8), fov_deg=50, width=24)
    before = render_error_aware(scattered, cam, table, threshold=0.1, base_lod=1)
    after = render_error_aware(scattered, cam, table, threshold=0.1, base_lod=1,
                               context_aware=True)
    assert np.all(after.maps["refined"] <= before.maps["refined"])


def _refine_pixel_by_pixel(octree, camera, table, *, columns, threshold, decay, base_lod,
                           max_refinements, reuse_parent, seed):
    """The error-aware render as the thesis states it, one pixel at a time: a stack of the
    pixel's pending rays, each traced on its own when popped (``trace_over_columns``, or
    ``trace_ray`` without the pyramid), refined 2×2 where ``E_N(r)`` exceeds the threshold,
    kept samples added as they come. Written without the renderer's batches, records and
    lanes, as an oracle for them."""
    import math

    from voxfield.kernels.beam import start_distance
    from voxfield.kernels.bundles import octree_view, view_colours
    from voxfield.kernels.camera_rays import camera_ray
    from voxfield.kernels.error_aware import (
        ENCODING_OCT,
        cell_sample,
        designated_cell,
        node_error,
    )
    from voxfield.kernels.facing_colour import seen_rgb
    from voxfield.kernels.primary import normal_from_code, store_pixel
    from voxfield.kernels.sampling import cmj_sample, pixel_pattern
    from voxfield.kernels.surface_approach import trace_over_columns
    from voxfield.kernels.traversal import MISS, new_scratch, trace_ray
    from voxfield.render.beam import pixel_start_bounds
    from voxfield.svo.column_tops import no_column_tops, octree_column_tops

    depth, inner = octree.depth, octree.inner_nodes
    colors, facing = octree.kernel_colours("albedo")
    stored = view_colours(octree_view(inner, depth, colors, facing))
    pyramid = octree_column_tops(octree) if columns else no_column_tops()
    beam = pixel_start_bounds(octree, camera, pyramid, stop_level=depth - base_lod,
                              whole_pixel=True)
    oct_map = np.ascontiguousarray(table.oct_map, np.float64)
    sh = np.ascontiguousarray(table.sh, np.float64)
    scratch = new_scratch(depth)
    h, w = camera.height, camera.width
    color, depth_map = np.zeros((h, w, 3), np.float32), np.zeros((h, w), np.float32)
    normal = np.zeros((h, w, 3), np.float32)
    counts = [np.zeros((h, w), kind) for kind in (np.int32, np.int32, np.int64, np.int8)]
    refined_map, discarded_map = np.zeros((h, w), np.int32), np.zeros((h, w), np.int32)
    fine = 1 << max_refinements
    for row in range(h):
        for col in range(w):
            pattern = pixel_pattern(row * w + col, seed)
            t_start = start_distance(beam.bound[row // beam.block, col // beam.block])
            sums = dict(r=0.0, g=0.0, b=0.0, nx=0.0, ny=0.0, nz=0.0, t=0.0, weight=0.0)
            rays = hits = steps_sum = refined = discarded = 0
            finest = 127
            # (cell x, cell y, refinement, stop level, resume time or None, finest cell,
            # parent's entry face)
            pending = [(0, 0, 0, depth - base_lod, None,
                        designated_cell(0, 0, 0, fine, pattern) if reuse_parent else None,
                        -1)]
            while pending:
                cx, cy, k, stop, resume, cell, parent_face = pending.pop()
                cells = 1 << k
                if reuse_parent:
                    fx, fy = cell_sample(cell[0], cell[1], fine, pattern)
                elif cells == 4:
                    fx, fy = cmj_sample(cy * 4 + cx, 4, 4, pattern)
                else:
                    fx, fy = (cx + 0.5) / cells, (cy + 0.5) / cells
                ox, oy, oz, dx, dy, dz = camera_ray(camera.params, col + fx, row + fy, w, h)
                tmin = t_start if resume is None else max(resume, t_start)
                if columns:
                    node, level, t, face, steps = trace_over_columns(
                        ox, oy, oz, dx, dy, dz, tmin, math.inf, inner, depth, stop, scratch,
                        pyramid)
                else:
                    node, level, t, face, steps = trace_ray(
                        ox, oy, oz, dx, dy, dz, tmin, math.inf, inner, depth, stop, 0.0, 0.0,
                        scratch)
                steps_sum += steps
                if resume is None:
                    rays += 1
                elif face < 0 and t == resume:
                    face = parent_face
                if node == MISS:
                    discarded += resume is not None
                    continue
                if k < max_refinements and level < depth and node_error(
                        node, level, depth, inner, decay, ENCODING_OCT, oct_map, sh,
                        dx, dy, dz) > threshold:
                    refined += 1
                    discarded += not reuse_parent
                    for sub in range(4):
                        sx, sy = 2 * cx + (sub & 1), 2 * cy + (sub >> 1)
                        span = fine >> (k + 1)
                        if reuse_parent and (cell[0] // span, cell[1] // span) == (sx, sy):
                            pending.append((sx, sy, k + 1, level + 1, t, cell, face))
                        else:
                            pending.append((sx, sy, k + 1, level + 1, None, designated_cell(
                                sx, sy, k + 1, fine, pattern) if reuse_parent else None, -1))
                    continue
                weight = 1.0 / (cells * cells)
                hits += 1
                cr, cg, cb = seen_rgb(stored, facing, node, dx, dy, dz)
                ax, ay, az = normal_from_code(face)
                for key, value in (("r", cr), ("g", cg), ("b", cb), ("t", t), ("nx", ax),
                                   ("ny", ay), ("nz", az)):
                    sums[key] += weight * value
                sums["weight"] += weight
                finest = min(finest, depth - level)
            refined_map[row, col], discarded_map[row, col] = refined, discarded
            store_pixel(color[row], depth_map[row], normal[row], counts[0][row],
                        counts[1][row], counts[2][row], counts[3][row], col, sums["r"],
                        sums["g"], sums["b"], sums["t"], sums["weight"], sums["nx"],
                        sums["ny"], sums["nz"], rays, hits, steps_sum, finest)
    counts[2] += beam.image_steps(h, w)  # the beam's own steps, shared out over its pixels
    return color, depth_map, normal, counts, refined_map, discarded_map


@pytest.mark.parametrize(("reuse_parent", "columns"), [(False, True), (True, True),
                                                      (False, False)])
def test_the_batched_render_is_the_pixel_by_pixel_refinement(table, terrain, reuse_parent,
                                                             columns):
    """The renderer traces 8×8 tiles of pixels, refinement level by level, in batches (rays
    to voxels walking the pyramid in SIMD lanes where they pay): a 150×24 view (three bands
    of 19 tiles, the last 6 pixels wide: a partial chunk of 48 pixels) with sky, pillar
    tops and sides, where refinement stops at every level, must come out as each pixel
    refined on its own does, to the last bit of every output."""
    cam = Camera.look_at((60, 40, 60), (32, 6, 32), fov_deg=40, width=150, height=24)
    options = dict(threshold=0.08, decay=0.2, base_lod=2, max_refinements=2,
                   reuse_parent=reuse_parent, seed=5)
    result = render_error_aware(terrain, cam, table, columns=columns, encoding="oct",
                                **options)
    color, depth, normal, (rays, hits, steps, lod), refined, discarded = (
        _refine_pixel_by_pixel(terrain, cam, table, columns=columns, **options))
    refinements = np.bincount(result.maps["refined"].ravel(), minlength=6)
    assert np.all(refinements > 0)  # refinement stops at every level,
    assert (result.hit_count == 0).any()  # and there is sky
    assert np.array_equal(result.image, color)
    assert np.array_equal(result.depth, depth)
    assert np.array_equal(result.normal, normal)
    assert np.array_equal(result.ray_count, rays)
    assert np.array_equal(result.hit_count, hits)
    assert np.array_equal(result.steps, steps)
    assert np.array_equal(result.finest_lod, lod)
    assert np.array_equal(result.maps["refined"], refined)
    assert np.array_equal(result.maps["discarded"], discarded)
