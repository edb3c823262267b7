"""Single-probe marching: octant pieces, the probe-at-camera identity, loss of visibility,
agreement with the octree's own ray cast, and the hierarchical trace's savings."""

from __future__ import annotations

import math

import numpy as np
import pytest
from lf_helpers import CORNELL_PROBE, one_probe

from voxfield.errors import VoxfieldError
from voxfield.kernels.octahedral import oct_decode, texel_directions
from voxfield.kernels.probe_march import EPS_ADAPTIVE, epsilon_at, piece_setup, piece_t
from voxfield.lightfield import (
    HIT,
    MISS,
    UNKNOWN,
    LightFieldOptions,
    PackedProbes,
    trace_light_field,
    trace_single,
)
from voxfield.lightfield.trace import EPSILON_MODES, EPSILON_READERS, _rays
from voxfield.probes.bake import bake_probes
from voxfield.probes.probe_set import BakeOptions
from voxfield.render.ray_query import trace

MARCHERS = ("march3d", "dda", "hierarchical")


def _unit(v):
    v = np.asarray(v, np.float64)
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def test_octant_pieces_are_straight_great_circle_segments():
    """Between axis-plane crossings a ray's image in octahedral space is a straight segment:
    every interpolated point decodes to a direction on the ray's great circle (the plane
    through the probe and the ray), and ``piece_t`` finds the ray point seen there."""
    rng = np.random.default_rng(7)
    r = 64
    checked = 0
    for _ in range(60):
        a = rng.uniform(-5, 5, 3)  # ray origin relative to the probe
        w = _unit(rng.normal(size=3))
        normal = _unit(np.cross(a, w))
        splits = sorted(s for s in (-a / w) if s > 0)
        ends = [0.0, *splits, math.inf]
        for t0, t1 in zip(ends[:-1], ends[1:], strict=True):
            xa, ya, ex, ey, a0, b, scale = piece_setup(*a, *w, t0, t1, r)
            for lam in np.linspace(0.02, 0.98, 9):
                direction = np.array(oct_decode((xa + lam * ex) / r, (ya + lam * ey) / r))
                assert abs(direction @ normal) < 1e-9
                t = piece_t(lam, t0, t1, a0, b, scale)
                assert t0 <= t <= t1
                np.testing.assert_allclose(_unit(a + t * w), direction, atol=1e-9)
                checked += 1
    assert checked > 60 * 9


@pytest.mark.parametrize("marcher", MARCHERS)
def test_probe_at_the_camera_reproduces_the_direct_render(cornell, marcher):
    """Rays from the probe centre through its texel centres hit exactly what the bake saw:
    the stored distance (to rounding for the 2D marchers, within a step for the 3D march) and
    the texel's own radiance; directions where the bake saw nothing are misses."""
    r = 32
    packed = one_probe(cornell, CORNELL_PROBE, r)
    dirs = texel_directions(r)
    origins = np.repeat(CORNELL_PROBE[None], len(dirs), axis=0)
    stored = packed.distance[0].ravel().astype(np.float64)
    seen = np.isfinite(stored)
    hits = trace_single(packed, 0, origins, dirs, LightFieldOptions(marcher=marcher),
                        tmax=200.0)
    assert np.array_equal(hits.kind == HIT, seen)
    assert np.all(hits.kind[~seen] == MISS)
    texel = np.arange(r * r)
    assert np.array_equal(hits.row[seen] * r + hits.col[seen], texel[seen])
    np.testing.assert_array_equal(hits.radiance[seen],
                                  packed.radiance[0].reshape(-1, 3)[seen])
    if marcher == "march3d":
        assert np.all(np.abs(hits.t[seen] - stored[seen]) <= 0.5 + 1e-9)
    else:
        # The hit is where the ray meets the stored plane: the stored distance, to rounding.
        np.testing.assert_allclose(hits.t[seen], stored[seen], rtol=1e-12)
        np.testing.assert_array_equal(hits.distance[seen], packed.distance[0].ravel()[seen])


@pytest.mark.parametrize("marcher", MARCHERS)
def test_a_ray_behind_a_wall_the_probe_faces_is_unknown(walled_room, marcher):
    """A probe left of the wall cannot see the right half: a ray starting there (towards a
    surface the probe does see through the wall's direction) is UNKNOWN at its start, never
    a hit on the wall."""
    packed = one_probe(walled_room, [8.5, 16.2, 16.3], 32)
    origins = np.array([[24.3, 16.1, 16.2], [20.5, 8.3, 10.1], [28.2, 25.5, 5.5]])
    dirs = np.array([[0.0, 0.0, 1.0], [-0.3, 0.2, 0.9], [0.0, -1.0, 0.1]])
    hits = trace_single(packed, 0, origins, dirs, LightFieldOptions(marcher=marcher))
    assert np.all(hits.kind == UNKNOWN)
    np.testing.assert_array_equal(hits.t, 0.0)
    truth = trace(walled_room, origins, dirs, lod=0)
    assert truth.hit.all()  # the rays do hit something; the probe just cannot tell what


def _clear_visible_rays(octree, probe, count, seed):
    """Rays near ``probe`` with finite length, the octree's answer, and a mask of those the
    probe sees entirely (every point up to the hit is visible from the probe) that stay at
    least 2 voxels from every surface until they end or hit, and do not end within a voxel
    of a surface: there the probe's texels and ε decide, not the geometry."""
    rng = np.random.default_rng(seed)
    origins = probe + rng.uniform(-1.5, 1.5, (count, 3))
    dirs = _unit(rng.normal(size=(count, 3)))
    tmax = rng.uniform(2.0, 30.0, count)
    truth = trace(octree, origins, dirs, lod=0)
    end = np.minimum(truth.t, tmax)
    s = (np.arange(48) + 0.5) / 48
    points = (origins[:, None] + dirs[:, None] * (end[:, None] * s)[..., None]).reshape(-1, 3)
    view = points - probe
    length = np.linalg.norm(view, axis=1)
    seen = trace(octree, np.repeat(probe[None], len(view), 0), view / length[:, None], lod=0)
    visible = (seen.t >= length - 1e-6).reshape(count, -1).all(axis=1)
    axes = np.vstack([np.eye(3), -np.eye(3)])
    near = points.reshape(count, -1, 3)[:, :40].reshape(-1, 3)  # up to ~5/6 of the way
    gaps = trace(octree, np.repeat(near, 6, 0), np.tile(axes, (len(near), 1)), lod=0)
    clear = gaps.t.reshape(count, -1).min(axis=1) >= 2.0
    away = np.abs(truth.t - tmax) > 1.0
    return origins, dirs, tmax, truth.t < tmax, visible & clear & away


def test_all_marchers_agree_with_the_octree_on_rays_the_probe_sees(cornell, cornell_probe64):
    """On rays the probe sees whole (and that neither graze a surface nor end right at one,
    where texel size and ε decide), HIT/MISS is the octree's own ray cast's answer."""
    origins, dirs, tmax, truth_hit, usable = _clear_visible_rays(cornell, CORNELL_PROBE,
                                                                 3000, seed=3)
    assert usable.sum() > 1000 and truth_hit[usable].any() and (~truth_hit[usable]).any()
    kinds = {}
    for marcher in MARCHERS:
        hits = trace_single(cornell_probe64, 0, origins, dirs,
                            LightFieldOptions(marcher=marcher, epsilon_value=0.3, step=0.1),
                            tmax=tmax)
        kinds[marcher] = hits.kind[usable]
    expected = np.where(truth_hit[usable], HIT, MISS)
    assert np.array_equal(kinds["dda"], kinds["hierarchical"])
    for marcher, kind in kinds.items():
        # No wrong answer ever. A texel stores its centre's distance only, so where a surface
        # slopes steeply across a texel a ray can enter it already behind that sample by more
        # than ε and the probe gives up (UNKNOWN); the 3D march, one texel per point, a little
        # more often. Both stay rare on these rays.
        known = kind != UNKNOWN
        assert np.array_equal(kind[known], expected[known]), marcher
        assert np.count_nonzero(~known) <= 0.005 * len(known), marcher


def test_hierarchical_trace_fetches_fewer_texels_than_the_dda(cornell, cornell_probe64):
    """Same answers, fewer distance fetches, over many rays in the room."""
    rng = np.random.default_rng(11)
    n = 4000
    origins = rng.uniform(3.0, 28.0, (n, 3))
    dirs = _unit(rng.normal(size=(n, 3)))
    dda = trace_single(cornell_probe64, 0, origins, dirs, LightFieldOptions(marcher="dda"))
    hier = trace_single(cornell_probe64, 0, origins, dirs,
                        LightFieldOptions(marcher="hierarchical"))
    assert np.array_equal(dda.kind, hier.kind)
    np.testing.assert_allclose(hier.t, dda.t, rtol=0, atol=1e-9)
    assert hier.fetches.sum() < 0.5 * dda.fetches.sum()


def test_the_3d_march_proves_a_miss_once_past_every_surface(cornell_probe64):
    """Rays from the probe out of the box's open side, unbounded: the 3D march answers MISS,
    as the 2D walks do, and stops soon after the farthest surface the probe stores (moving
    away, no later point can meet one). Without that bound it spent its whole point budget
    on each and handed it on UNKNOWN, for the fallback to answer."""
    r = 64
    stored = cornell_probe64.distance[0].ravel()
    escaping = ~np.isfinite(stored)
    assert escaping.sum() > 100
    dirs = texel_directions(r)[escaping]
    origins = np.repeat(CORNELL_PROBE[None], len(dirs), axis=0)
    options = LightFieldOptions(marcher="march3d")
    hits = trace_single(cornell_probe64, 0, origins, dirs, options)
    assert np.all(hits.kind == MISS) and np.all(hits.t == math.inf)
    points = math.ceil(stored[~escaping].max() / options.step) + 1
    walk = 4 * (2 * r + 4)  # the 2D walk of one octant piece fetches at most this many
    assert hits.fetches.max() <= points + walk < options.max_steps


def test_what_the_dda_proves_empty_the_3d_march_finds_empty(cornell_probe64):
    """Each point of the march reads one texel the DDA crosses, at a radial distance inside
    the range the DDA tests there, so where the DDA finds every texel in front of its surface
    (MISS), so does the march, up to the farthest surface and past it."""
    rng = np.random.default_rng(5)
    n = 3000
    origins = CORNELL_PROBE + rng.uniform(-4.0, 4.0, (n, 3))
    dirs = _unit(rng.normal(size=(n, 3)))
    dda = trace_single(cornell_probe64, 0, origins, dirs, LightFieldOptions(marcher="dda"))
    march = trace_single(cornell_probe64, 0, origins, dirs,
                         LightFieldOptions(marcher="march3d"))
    proved = dda.kind == MISS
    assert proved.sum() > 300
    assert np.all(march.kind[proved] == MISS)


def test_backface_rejection_turns_a_hit_from_inside_a_wall_into_unknown(cornell):
    """A ray starting just inside the floor and leaving it upwards meets the floor's top
    face from behind: accepted as a hit within ε without normals, lost with them (§7.2)."""
    packed = one_probe(cornell, CORNELL_PROBE, 32)
    origin = np.array([[20.4, 0.8, 24.3]])
    up = np.array([[0.05, 1.0, 0.02]])
    plain = trace_single(packed, 0, origin, up, LightFieldOptions(marcher="dda"))
    rejected = trace_single(packed, 0, origin, up,
                            LightFieldOptions(marcher="dda", backface=True))
    assert plain.kind[0] == HIT and plain.normal[0] @ up[0] > 0
    assert rejected.kind[0] == UNKNOWN and rejected.t[0] == 0.0
    # From the probe's side, no rejection changes anything.
    dirs = texel_directions(32)
    origins = np.repeat(CORNELL_PROBE[None], len(dirs), 0)
    a = trace_single(packed, 0, origins, dirs, LightFieldOptions(marcher="dda"))
    b = trace_single(packed, 0, origins, dirs, LightFieldOptions(marcher="dda", backface=True))
    assert np.array_equal(a.kind, b.kind) and np.array_equal(a.t, b.t)


def test_adaptive_epsilon_is_the_thesis_formula():
    """ε = k · tan θ · d(X, Y) · |α·β| · (1 - β·ν), α = S²(X - Y), β = S²(X - P)."""
    params = LightFieldOptions(epsilon="adaptive", epsilon_k=2.0).params(0.01)
    x, p, y = np.array([1.0, 2.0, 3.0]), np.array([4.0, 1.0, 0.5]), np.array([9.0, -2.0, 7.0])
    nu = _unit([0.2, 0.9, -0.1])
    alpha, beta = _unit(x - y), _unit(x - p)
    expected = 2.0 * math.tan(0.01) * np.linalg.norm(x - y) * abs(alpha @ beta) * (1 - beta @ nu)
    got = epsilon_at(EPS_ADAPTIVE, params, *x, *p, *y, *nu)
    assert got == pytest.approx(expected, rel=1e-12)


@pytest.mark.parametrize("epsilon", ["adaptive", "angular"])
def test_pixel_angle_epsilons_accept_the_probes_own_rays(cornell, epsilon):
    """From the probe centre the stored point lies exactly on the ray, so both the adaptive ε
    and the angular criterion accept every texel the bake saw."""
    r = 32
    packed = one_probe(cornell, CORNELL_PROBE, r)
    dirs = texel_directions(r)
    origins = np.repeat(CORNELL_PROBE[None], len(dirs), 0)
    options = LightFieldOptions(marcher="hierarchical", epsilon=epsilon, epsilon_k=1.0)
    hits = trace_single(packed, 0, origins, dirs, options, pixel_angle=math.radians(0.5))
    seen = np.isfinite(packed.distance[0].ravel())
    assert np.array_equal(hits.kind == HIT, seen)
    np.testing.assert_allclose(hits.t[seen], packed.distance[0].ravel()[seen], rtol=1e-12)


def test_slope_thickness_is_half_the_texels_depth_span():
    from voxfield.kernels.probe_march import SLOPE_TAN_MAX, slope_thickness, texel_angle

    angle = texel_angle(64)
    assert slope_thickness(10.0, 0, 0, 1, 0, 0, 1, 64) == pytest.approx(0.0)  # head-on
    c45 = math.sqrt(0.5)
    assert slope_thickness(10.0, 0, 0, 1, 0, c45, c45, 64) == pytest.approx(5.0 * angle)
    grazing = slope_thickness(10.0, 0, 0, 1, 0, 1, 1e-6, 64)
    assert grazing == pytest.approx(5.0 * angle * SLOPE_TAN_MAX)
    assert slope_thickness(10.0, 0, 0, 1, 0, 0, 0, 64) == pytest.approx(grazing)  # no normal


def test_slope_epsilon_gives_up_less_and_is_never_wrong(cornell, cornell_probe64):
    """The slope ε widens acceptance where a stored surface spans more depth than ε across a
    texel: on the same visible rays it answers at least as many, and still never wrongly."""
    origins, dirs, tmax, truth_hit, usable = _clear_visible_rays(cornell, CORNELL_PROBE,
                                                                 3000, seed=3)
    expected = np.where(truth_hit[usable], HIT, MISS)
    unknown = {}
    for epsilon in ("constant", "slope"):
        options = LightFieldOptions(marcher="hierarchical", epsilon=epsilon, epsilon_value=0.3)
        kind = trace_single(cornell_probe64, 0, origins, dirs, options, tmax=tmax).kind[usable]
        known = kind != UNKNOWN
        assert np.array_equal(kind[known], expected[known]), epsilon
        unknown[epsilon] = np.count_nonzero(~known)
    assert unknown["slope"] <= unknown["constant"]


#: A value far from each epsilon parameter's default, so that where it is read it shows.
_FAR = {"epsilon_value": 3.0, "epsilon_k": 40.0, "epsilon_front": 0.0}


@pytest.mark.parametrize("epsilon", sorted(EPSILON_MODES))
def test_each_epsilon_reads_the_parameters_the_command_line_says_it_reads(
        cornell_probe64, epsilon):
    """``EPSILON_READERS`` decides which epsilon options the command line notes as ignored;
    here the trace decides: a parameter the table says this mode ignores leaves every ray's
    answer as it was, one it says the mode reads changes some."""
    rng = np.random.default_rng(5)
    origins = rng.uniform(3.0, 28.0, (3000, 3))
    dirs = _unit(rng.normal(size=(3000, 3)))

    def answers(**change):
        options = LightFieldOptions(marcher="hierarchical", epsilon=epsilon, **change)
        hits = trace_single(cornell_probe64, 0, origins, dirs, options,
                            pixel_angle=math.radians(0.5))
        return hits.kind, np.nan_to_num(hits.t, posinf=-1.0)

    kind, t = answers()
    for name, readers in EPSILON_READERS.items():
        other_kind, other_t = answers(**{name: _FAR[name]})
        same = np.array_equal(kind, other_kind) and np.array_equal(t, other_t)
        assert same == (epsilon not in readers), (name, epsilon)


@pytest.mark.parametrize("name", ["consensus", "ring", "backface", "fallback"])
def test_a_light_field_switch_takes_a_bool_not_any_truthy_object(name):
    with pytest.raises(VoxfieldError, match=f"{name} must be True or False"):
        LightFieldOptions(**{name: "no"})
    assert getattr(LightFieldOptions(**{name: np.bool_(True)}), name)


@pytest.mark.parametrize("front", [0.0, 0.25, 1e6, float("inf")])
def test_hierarchical_and_dda_agree_whatever_the_front_epsilon(cornell, cornell_probe64, front):
    """The hierarchical skip bound reads the capped front ε: it must stay conservative for
    no cap, the default, none at all and a cap wider than the texels."""
    rng = np.random.default_rng(12)
    origins = rng.uniform(3.0, 28.0, (1500, 3))
    dirs = _unit(rng.normal(size=(1500, 3)))
    options = {"epsilon_front": front}
    dda = trace_single(cornell_probe64, 0, origins, dirs,
                       LightFieldOptions(marcher="dda", **options))
    hier = trace_single(cornell_probe64, 0, origins, dirs,
                        LightFieldOptions(marcher="hierarchical", **options))
    assert np.array_equal(dda.kind, hier.kind)
    np.testing.assert_allclose(hier.t, dda.t, rtol=0, atol=1e-9)


@pytest.mark.parametrize(("origins", "dirs", "bounds", "message"), [
    ([[1.0, 2.0, 3.0]], [[0.0, 0.0, 0.0]], {}, "zero vector"),
    ([[1.0, 2.0, math.nan]], [[1.0, 0.0, 0.0]], {}, "NaN or infinity"),
    ([[1.0, 2.0]], [[1.0, 0.0]], {}, "N×3"),
    ([[1.0, 2.0, 3.0]], [[1.0, 0.0, 0.0]], {"tmin": math.nan}, "tmin must be finite"),
    ([[1.0, 2.0, 3.0]], [[1.0, 0.0, 0.0]], {"tmax": math.nan}, "tmax not NaN"),
])
def test_bad_rays_are_refused(cornell_probe64, origins, dirs, bounds, message):
    with pytest.raises(VoxfieldError, match=message):
        trace_single(cornell_probe64, 0, origins, dirs, **bounds)


def test_an_empty_segment_is_a_miss_and_leaves_the_other_rays_alone(cornell_probe64):
    """tmax <= tmin holds no point: a miss (as the octree's trace answers), at tmax, with no
    probe asked; the batch's other rays are answered as they are alone."""
    rng = np.random.default_rng(8)
    origins = rng.uniform(6.0, 26.0, (40, 3))
    dirs = rng.normal(size=(40, 3))
    tmin = np.zeros(40)
    tmax = np.full(40, np.inf)
    tmin[::4], tmax[::4] = 10.0, 5.0  # tmin above tmax
    tmax[1::4] = 0.0
    tmin[2::4] = tmax[2::4] = 3.0
    empty = np.zeros(40, bool)
    empty[0::4] = empty[1::4] = empty[2::4] = True
    alone = ~empty
    single = trace_single(cornell_probe64, 0, origins, dirs, tmin=tmin, tmax=tmax)
    whole = trace_light_field(cornell_probe64, origins, dirs, tmin=tmin, tmax=tmax)
    for hits in (single, whole):
        assert np.all(hits.kind[empty] == MISS)
        np.testing.assert_array_equal(hits.t[empty], tmax[empty])
        assert np.all(hits.fetches[empty] == 0) and np.all(hits.steps[empty] == 0)
    assert np.all(whole.probe[empty] == -1) and np.all(whole.probes_tried[empty] == 0)
    by_itself = trace_light_field(cornell_probe64, origins[alone], dirs[alone])
    np.testing.assert_array_equal(whole.kind[alone], by_itself.kind)
    np.testing.assert_array_equal(whole.t[alone], by_itself.t)
    assert cornell_probe64.count == 1 and np.any(whole.kind[alone] == HIT)


def _probe_arrays(n=8, r=8):
    positions = np.array([[x, y, z] for z in (8.0, 24.0) for y in (8.0, 24.0)
                          for x in (8.0, 24.0)])
    normals = np.zeros((n, r, r, 3), np.float32)
    normals[..., 1] = 1.0
    return dict(positions=positions, enabled=np.ones(n, bool),
                radiance=np.full((n, r, r, 3), 0.5, np.float32),
                distance=np.full((n, r, r), 5.0, np.float32), normals=normals,
                grid_origin=(8, 8, 8), grid_spacing=(16, 16, 16), grid_counts=(2, 2, 2))


@pytest.mark.parametrize(("change", "message"), [
    ({"grid_spacing": (0, 0, 0)}, "spacing"),
    ({"grid_spacing": (16, -16, 16)}, "spacing"),
    ({"grid_origin": (8, math.nan, 8)}, "origin"),
    ({"positions": "nan"}, "position"),
    ({"distance": -1.0}, "lengths >= 0"),
    ({"distance": math.nan}, "lengths >= 0"),
    ({"radiance": math.nan}, "radiance holds NaN"),
    ({"normals": math.inf}, "normals hold NaN"),
    ({"resolution": 3}, "even 4..2048 texels a side"),
    ({"resolution": 2}, "even 4..2048 texels a side"),
])
def test_packed_probes_refuse_a_grid_or_maps_the_trace_cannot_use(change, message):
    """Zero spacing crashed the trace (a SystemError from its kernel); a NaN position gave
    NaN distances back as hits, as NaN radiance or normals did colours and normals; an odd
    side puts a texel in two octants, which the marchers do not allow for."""
    arrays = _probe_arrays()
    for key, value in change.items():
        if key == "positions":
            arrays[key][3] = np.nan
        elif key == "resolution":
            for name in ("radiance", "distance", "normals"):
                arrays[name] = arrays[name][:, :value, :value]
        elif key in ("distance", "radiance", "normals"):
            arrays[key][2, 1, 1] = value
        else:
            arrays[key] = value
    with pytest.raises(VoxfieldError, match=message):
        PackedProbes.from_arrays(**arrays)


def test_packed_probes_refuse_no_probes_in_plain_words():
    """Zero probes said "grid counts [1, 1, 1] do not hold 0 probes" (or, with the grid
    emptied too, "[0, 1, 1]"), which reads as a grid mistake rather than an empty set."""
    arrays = _probe_arrays()
    for name in ("positions", "enabled", "radiance", "distance", "normals"):
        arrays[name] = arrays[name][:0]
    for counts in ((2, 2, 2), (0, 1, 1)):
        with pytest.raises(VoxfieldError, match="^a probe set needs at least one probe; "
                           "got 0 positions$"):
            PackedProbes.from_arrays(**{**arrays, "grid_counts": counts})


def test_per_ray_bounds_and_probe_indices_are_checked(cornell_probe64):
    """A two-value tmin for one ray raised NumPy's broadcasting error; a probe index "1"
    a TypeError."""
    with pytest.raises(VoxfieldError, match="one number a ray"):
        trace_light_field(cornell_probe64, [CORNELL_PROBE], [[1.0, 0.0, 0.0]],
                          tmin=np.array([0.5, 1.0]))
    with pytest.raises(VoxfieldError, match="not an integer"):
        trace_single(cornell_probe64, "1", [CORNELL_PROBE], [[1.0, 0.0, 0.0]])


def test_a_disabled_probe_needs_no_place_or_lengths():
    arrays = _probe_arrays()
    arrays["enabled"][3] = False
    arrays["positions"][3] = np.nan
    arrays["distance"][3] = -1.0
    packed = PackedProbes.from_arrays(**arrays)
    hits = trace_light_field(packed, [[16.0, 16.0, 16.0]], [[0.0, -1.0, 0.0]])
    assert np.isfinite(hits.t).all()


def test_the_march_refuses_a_point_budget_that_would_run_for_hours():
    LightFieldOptions(marcher="march3d", step=1 / 65536, max_steps=65536)
    with pytest.raises(VoxfieldError, match="max_steps must be an integer in 1..65536"):
        LightFieldOptions(marcher="march3d", step=1e-9, max_steps=10**9)


@pytest.mark.parametrize("direction", [[1e-200, 0.0, 0.0], [1e200, 1e200, 0.0],
                                       [5e-324, -5e-324, 1e-320], [1e308, -1e308, 1e308]])
def test_a_direction_of_any_finite_length_is_normalised(cornell_probe64, direction):
    """Its square underflows to 0 or overflows to infinity: the ray is still the unit one."""
    origin = [CORNELL_PROBE - [3.0, 2.0, 1.0]]
    unit = np.sign(direction)[None, :]
    got = trace_single(cornell_probe64, 0, origin, [direction])
    want = trace_single(cornell_probe64, 0, origin, unit)
    assert got.kind[0] == want.kind[0]
    assert got.t[0] == pytest.approx(want.t[0], abs=1e-9)


@pytest.mark.parametrize("marcher", ["hierarchical", "dda", "march3d"])
@pytest.mark.parametrize("axis", range(6))
def test_a_ray_through_the_probe_centre_answers_as_one_from_it(cornell_probe64, marcher,
                                                                axis):
    """An axis-aligned ray through the centre has an octant piece that ends there exactly,
    a single texel (every point of it lies along -ω): its answer past the centre is that of
    the ray starting at the centre, a hit two voxels further on (the probe sees the two
    voxels before it empty). Rays out of the open side miss or leave what it sees."""
    direction = np.zeros((1, 3))
    direction[0, axis // 2] = 1.0 if axis % 2 == 0 else -1.0
    options = LightFieldOptions(marcher=marcher)
    through = trace_single(cornell_probe64, 0, CORNELL_PROBE - 2.0 * direction, direction,
                           options)
    start = trace_single(cornell_probe64, 0, CORNELL_PROBE[None, :], direction, options)
    assert through.kind[0] == start.kind[0]
    if start.kind[0] == HIT:
        assert through.t[0] == pytest.approx(start.t[0] + 2.0, abs=1e-6)


def test_options_none_are_the_defaults_and_another_type_is_refused(cornell_probe64):
    origin, direction = [CORNELL_PROBE], [[0.3, -0.2, 0.9]]
    default = trace_single(cornell_probe64, 0, origin, direction, LightFieldOptions())
    none = trace_single(cornell_probe64, 0, origin, direction, None)
    assert none.kind[0] == default.kind[0] and none.t[0] == default.t[0]
    with pytest.raises(VoxfieldError, match="LightFieldOptions"):
        trace_single(cornell_probe64, 0, origin, direction, {"marcher": "dda"})



@pytest.mark.parametrize("count", [0, 1, 5])
def test_rays_reach_the_kernels_as_one_type_whatever_their_count(count):
    """For 0 or 1 rays the broadcast tmin and tmax were read-only views, another type to
    Numba: a probe render's untimed empty band compiled one kernel and its first band
    another, inside the timing (4.7 s reported for a 33×33 render taking 0.02 s)."""
    origins, dirs = np.zeros((count, 3)), np.tile([0.3, -0.2, 0.9], (count, 1))
    for array in _rays(origins, dirs, 0.0, math.inf):
        assert array.flags.writeable and array.flags.c_contiguous and array.dtype == np.float64


def test_a_baked_probe_set_traces_as_its_packing_and_anything_else_is_named(cornell):
    """A ProbeSet straight from a bake is what a user has in hand: it is packed for the
    trace, with the packed set's answers; other objects got an AttributeError from deep
    inside ('ProbeSet' object has no attribute 'mips', 'Octree' … 'enabled')."""
    from voxfield.lightfield.probe_render import render_from_probes
    from voxfield.probes.grid import ProbeGrid
    from voxfield.render.camera import room_camera

    probe_set = bake_probes(cornell, ProbeGrid(CORNELL_PROBE, [1, 1, 1], [1, 1, 1]),
                            BakeOptions(resolution=8, renderer="lod", lod=0))
    packed = PackedProbes.from_probe_set(probe_set)
    origins, dirs = [CORNELL_PROBE] * 3, np.eye(3)
    for trace_it in (lambda p: trace_light_field(p, origins, dirs),
                     lambda p: trace_single(p, 0, origins, dirs)):
        from_set, from_packed = trace_it(probe_set), trace_it(packed)
        assert np.array_equal(from_set.kind, from_packed.kind)
        assert np.array_equal(from_set.t, from_packed.t)
    for wrong in (None, cornell, probe_set.positions):
        with pytest.raises(VoxfieldError, match="needs probes"):
            trace_light_field(wrong, origins, dirs)
    with pytest.raises(VoxfieldError, match="render_from_probes needs probes"):
        render_from_probes(cornell, room_camera(*cornell.voxel_bounds, size=4))
    with pytest.raises(VoxfieldError, match="needs a probe grid"):
        bake_probes(cornell, [CORNELL_PROBE.tolist()], BakeOptions(resolution=8))


def test_a_probe_index_counts_from_either_end_and_the_refusal_says_both(cornell):
    """``trace_single`` takes -1 as the last probe, Python's way, where its refusal named
    only 0..N-1."""
    packed = one_probe(cornell, CORNELL_PROBE, 8)
    origin, direction = CORNELL_PROBE[None] + 0.5, np.array([[0.0, -1.0, 0.0]])
    last = trace_single(packed, -1, origin, direction)
    first = trace_single(packed, 0, origin, direction)
    assert np.array_equal(last.t, first.t) and np.array_equal(last.kind, first.kind)
    for probe in (1, -2, 0.5):
        with pytest.raises(VoxfieldError, match=r"in 0\.\.0 \(or -1\.\.-1, counted from "):
            trace_single(packed, probe, origin, direction)
