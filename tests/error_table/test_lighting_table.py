"""Lighting-aware error tables (EA §6.1): bright-flag configurations, symmetry, files.

Pins: the colour error of configurations with an analytic answer (a bright octant seen from
above and from below, half-bright from any axis); no colour error with no or all children
bright; configuration classes carry each configuration onto its representative; table
lookups agree with fresh ray casts of the configuration itself (so the symmetry bookkeeping
is right); files round-trip, name their rebuild command and refuse corruption; the packaged
table is reproducible from its parameters on a slice of its texels.
"""

from __future__ import annotations

import numpy as np
import pytest

from voxfield.error_table.lighting_table import (
    configuration_classes,
    configuration_index,
    load_lighting_error_table,
    raycast_colour_errors,
    save_lighting_error_table,
)
from voxfield.error_table.symmetry import cube_symmetries, octant_permutation
from voxfield.error_table.table import ErrorTableError
from voxfield.kernels.octahedral import texel_directions

ALL = 0xFF
UPPER = sum(1 << c for c in range(8) if (c >> 1) & 1)  # octants on the high-y side
DOWN = (0.0, -1.0, 0.0)
UP = (0.0, 1.0, 0.0)


@pytest.fixture(scope="module")
def packaged():
    return load_lighting_error_table()


def _raycast(mask, bright, direction, resolution=256):
    return float(raycast_colour_errors([mask], [bright], [direction], resolution)[0, 0])


def test_one_bright_octant_seen_from_above_and_below():
    # Octant 7 (high x, y, z) bright among 8: the parent's luminance is 1/8.
    # From above a quarter of the rays meet it first (error 7/8), the rest a dark top child
    # (1/8): 1/4·7/8 + 3/4·1/8 = 5/16. From below every ray meets a dark bottom child: 1/8.
    assert _raycast(ALL, 1 << 7, DOWN) == pytest.approx(5 / 16, abs=0.01)
    assert _raycast(ALL, 1 << 7, UP) == pytest.approx(1 / 8, abs=1e-9)


def test_half_bright_is_half_wrong_from_every_axis():
    for direction in (DOWN, UP, (1, 0, 0), (0, 0, -1)):
        assert _raycast(ALL, UPPER, direction) == pytest.approx(0.5, abs=1e-9)


def test_one_luminance_class_has_no_colour_error(packaged):
    rng = np.random.default_rng(1)
    masks = rng.integers(1, 256, 50)
    dirs = rng.normal(size=(50, 3))
    assert np.all(packaged.colour_error(masks, 0, dirs) == 0)
    assert np.all(packaged.colour_error(masks, masks, dirs) == 0)
    assert np.all(raycast_colour_errors(masks, masks, dirs[:4], 32) == 0)


def test_classes_carry_configurations_onto_their_representative():
    class_of, symmetry_of, reps = configuration_classes()
    valid = np.flatnonzero(class_of >= 0)
    assert len(valid) == 3**8 - 2 * 256 + 1  # not none bright, not all (the empty mask once)
    assert 0 < len(reps) < len(valid) / 20  # symmetry shrinks the table a lot
    perms = np.stack([octant_permutation(g) for g in cube_symmetries()])
    for index in valid[::37]:
        perm = perms[symmetry_of[index]]
        moved = [sum(((bits >> c) & 1) << perm[c] for c in range(8))
                 for bits in (index & 0xFF, index >> 8)]
        assert configuration_index(*moved) == reps[class_of[index]]


def test_lookups_match_fresh_raycasts_of_the_configuration(packaged):
    rng = np.random.default_rng(7)
    class_of = packaged.class_of
    valid = np.flatnonzero(class_of >= 0)
    picks = valid[rng.integers(0, len(valid), 40)]
    dirs = rng.normal(size=(40, 3))
    truth = np.diag(raycast_colour_errors(picks & 0xFF, picks >> 8, dirs, 256))
    table = packaged.colour_error(picks & 0xFF, picks >> 8, dirs)
    # Bilinear over a 32² octahedral map: errors move by a few hundredths across a texel.
    assert np.max(np.abs(table - truth)) < 0.06
    assert np.mean(np.abs(table - truth)) < 0.015


def test_packaged_table_is_reproducible_from_its_parameters(packaged):
    params = packaged.params
    r = params["oct_resolution"]
    texels = texel_directions(r)
    rows = np.arange(0, r * r, 97)
    _, _, reps = configuration_classes()
    fresh = raycast_colour_errors(reps & 0xFF, reps >> 8, texels[rows], params["resolution"],
                                  params["seed"])
    stored = packaged.oct_map[:, 1:-1, 1:-1].reshape(len(reps), -1)[:, rows]
    assert np.allclose(stored, fresh, atol=1e-6)


def test_file_round_trip_and_corruption(packaged, tmp_path):
    path = save_lighting_error_table(packaged, tmp_path / "light.npz")
    again = load_lighting_error_table(path)
    assert np.array_equal(again.oct_map, packaged.oct_map)
    assert np.array_equal(again.class_of, packaged.class_of)
    with pytest.raises(ErrorTableError, match="missing"):
        load_lighting_error_table(tmp_path / "nope.npz")
    data = bytearray(path.read_bytes())
    data[len(data) // 2] ^= 0xFF
    (tmp_path / "bad.npz").write_bytes(bytes(data))
    with pytest.raises(ErrorTableError):
        load_lighting_error_table(tmp_path / "bad.npz")
    (tmp_path / "short.npz").write_bytes(bytes(data[:100]))
    with pytest.raises(ErrorTableError, match="build-lighting"):
        load_lighting_error_table(tmp_path / "short.npz")
