"""The two encodings of an ErrorTable (SH, octahedral map) and its ``error`` interface.

Pins: ``sh_basis`` is the orthonormal real SH basis (checked by quadrature); the stored SH
coefficients evaluate to the least-squares fit of the raw errors computed here with a
monomial basis of the same span; the octahedral map's interior holds the ray-cast errors at the
texel-centre directions and a lookup there gives them back; values stay in [0, 1]; the kernel
forms agree with ``error``; broadcasting and bad input; the packaged table's fit quality
(``fit_report``) and EA fig. 3.2's top-vs-side contrast.

Small tables (128 directions, 128², 16² texels) suffice for the encoding claims: they concern
how values are stored and looked up, not the ray-cast accuracy (test_raycast.py).
"""

from __future__ import annotations

import numpy as np
import pytest

from voxfield.error_table import (
    build_error_table,
    fit_report,
    load_error_table,
    raycast_errors,
)
from voxfield.error_table.spherical_harmonics import sh_basis
from voxfield.errors import VoxfieldError
from voxfield.kernels.error_lookup import oct_error, sh_error
from voxfield.kernels.octahedral import texel_directions

SMALL = {"n_directions": 128, "resolution": 128, "oct_resolution": 16, "seed": 0}


@pytest.fixture(scope="module")
def small():
    return build_error_table(**SMALL)


@pytest.fixture(scope="module")
def packaged():
    return load_error_table()


def _random_dirs(n: int, seed: int) -> np.ndarray:
    d = np.random.default_rng(seed).normal(size=(n, 3))
    return d / np.linalg.norm(d, axis=1, keepdims=True)


def _fibonacci(n: int) -> np.ndarray:
    i = np.arange(n) + 0.5
    z = 1 - 2 * i / n
    r = np.sqrt(1 - z * z)
    phi = i * np.pi * (3 - np.sqrt(5))
    return np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=1)


def test_sh_basis_is_orthonormal_real_sh():
    dirs = _fibonacci(40000)
    basis = sh_basis(dirs)
    gram = basis.T @ basis * (4 * np.pi / len(dirs))
    assert np.allclose(gram, np.eye(9), atol=2e-3), np.abs(gram - np.eye(9)).max()
    # Band 0 is the constant 1/(2√π); band 1 is √(3/4π)·(y, z, x) (standard real SH order).
    assert np.allclose(basis[:, 0], 0.5 / np.sqrt(np.pi))
    assert np.allclose(basis[:, 1:4], np.sqrt(3 / (4 * np.pi)) * dirs[:, [1, 2, 0]])


def _monomials(d: np.ndarray) -> np.ndarray:
    """A basis of polynomials of degree ≤ 2 on the sphere (9 functions, same span as SH)."""
    x, y, z = d.T
    return np.stack([np.ones_like(x), x, y, z, x * y, y * z, x * z, x * x - y * y, z * z], axis=1)


def _independent_sh_fit(table, dirs: np.ndarray) -> np.ndarray:
    coeffs, *_ = np.linalg.lstsq(
        _monomials(table.directions), table.raw.astype(np.float64).T, rcond=None
    )
    return (_monomials(dirs) @ coeffs).T  # (256, n)


@pytest.mark.parametrize(("which", "tol"), [("small", 1e-5), ("packaged", 1e-3)])
def test_sh_is_the_least_squares_fit_of_raw(which, tol, request):
    """The packaged ``raw`` is stored as float16 (±2.4e-4 on [0, 1]); the fit of those values
    moves by at most that times the projection's Lebesgue constant (a few), hence 1e-3."""
    table = request.getfixturevalue(which)
    dirs = _random_dirs(300, 1)
    want = _independent_sh_fit(table, dirs)
    kernel = np.array([[sh_error(table.sh, m, *d) for d in dirs] for m in range(256)])
    assert np.abs(kernel - want).max() < tol, np.abs(kernel - want).max()
    got = table.error(np.arange(256)[:, None], dirs[None, :, :], "sh")
    assert np.abs(got - np.clip(want, 0, 1)).max() < tol


def test_oct_map_interior_holds_raycast_errors_at_texel_centres(small):
    r = SMALL["oct_resolution"]
    truth = raycast_errors(texel_directions(r), SMALL["resolution"], SMALL["seed"])
    interior = small.oct_map[:, 1:-1, 1:-1].reshape(256, -1)
    assert small.oct_map.shape == (256, r + 2, r + 2)
    assert np.abs(interior - truth).max() < 1e-6  # float32 storage


def test_oct_lookup_reproduces_raycast_at_texel_centres(small):
    r = SMALL["oct_resolution"]
    texels = texel_directions(r)
    truth = raycast_errors(texels, SMALL["resolution"], SMALL["seed"])
    got = small.error(np.arange(256)[:, None], texels[None, :, :], "oct")
    worst = np.abs(got - truth).max()
    assert worst < 1e-6, worst


@pytest.mark.parametrize("which", ["small", "packaged"])
def test_values_stay_in_unit_interval(which, request):
    table = request.getfixturevalue(which)
    assert table.raw.min() >= 0.0 and table.raw.max() <= 1.0
    assert table.oct_map.min() >= 0.0 and table.oct_map.max() <= 1.0
    dirs = _random_dirs(200, 2)
    for encoding in ("sh", "oct"):
        values = table.error(np.arange(256)[:, None], dirs[None, :, :], encoding)
        assert values.shape == (256, 200)
        assert values.min() >= 0.0 and values.max() <= 1.0
        assert np.all(values[0] == 0.0)  # e(0, ·) = 0: raw, fit and map are all zero


@pytest.mark.parametrize("which", ["small", "packaged"])
def test_kernel_forms_agree_with_error(which, request):
    table = request.getfixturevalue(which)
    dirs = _random_dirs(60, 3)
    masks = np.arange(256)
    oct_k = np.array([[oct_error(table.oct_map, m, *d) for d in dirs] for m in masks])
    sh_k = np.array([[sh_error(table.sh, m, *d) for d in dirs] for m in masks])
    oct_v = table.error(masks[:, None], dirs[None], "oct")
    sh_v = table.error(masks[:, None], dirs[None], "sh")
    # error() clips to [0, 1]; the kernels do not. Compare exactly inside, clipped outside.
    for kernel, vec in ((oct_k, oct_v), (sh_k, sh_v)):
        inside = (kernel > 0) & (kernel < 1)
        assert inside.mean() > 0.5
        assert np.abs(kernel[inside] - vec[inside]).max() < 1e-12
        assert np.abs(np.clip(kernel, 0, 1) - vec).max() < 1e-12
    # The default encoding is the octahedral map.
    assert table.default_encoding == "oct"
    assert np.array_equal(table.error(masks[:, None], dirs[None]), oct_v)


def test_error_normalises_direction_length(small):
    d = _random_dirs(10, 4)
    for encoding in ("sh", "oct"):
        a = small.error(37, d, encoding)
        b = small.error(37, d * 7.25, encoding)
        assert np.allclose(a, b, atol=1e-12)


def test_error_broadcasting(small):
    dirs = _random_dirs(7, 5)
    masks = np.array([3, 17, 51, 200, 255])
    for encoding in ("sh", "oct"):
        one = {(m, i): float(small.error(int(m), dirs[i], encoding)) for m in masks
               for i in range(7)}
        assert np.shape(small.error(17, dirs[0], encoding)) == ()
        scalar_mask = small.error(17, dirs, encoding)
        assert scalar_mask.shape == (7,)
        assert np.allclose(scalar_mask, [one[17, i] for i in range(7)])
        one_dir = small.error(masks, dirs[2], encoding)
        assert one_dir.shape == (5,)
        assert np.allclose(one_dir, [one[m, 2] for m in masks])
        grid = small.error(masks[:, None], dirs[None], encoding)
        assert grid.shape == (5, 7)
        assert np.allclose(grid, [[one[m, i] for i in range(7)] for m in masks])
        paired = small.error(masks, dirs[:5], encoding)  # elementwise
        assert np.allclose(paired, [one[m, i] for i, m in enumerate(masks)])


@pytest.mark.parametrize(
    ("mask", "direction", "encoding"),
    [
        (300, (0, 0, 1), "oct"),
        (256, (0, 0, 1), "sh"),
        (-1, (0, 0, 1), "oct"),
        ([1, 2, 999], (0, 0, 1), "oct"),
        (5, (np.nan, 0, 1), "oct"),
        (5, (np.nan, 0, 1), "sh"),
        (5, (np.inf, 0, 1), "sh"),
        (5, (0, 0, 0), "oct"),
        (5, [(0, 1, 0), (0, 0, 0)], "sh"),
        (5, (0, 1), "oct"),
        (5, (0, 0, 1), "wavelet"),
        (5, (0, 0, 1), "OCT"),
    ],
)
def test_bad_input_raises(small, mask, direction, encoding):
    with pytest.raises(VoxfieldError):
        small.error(mask, direction, encoding)


def test_packaged_fit_report(packaged):
    """EA §6.2's suggestion measured: the octahedral map should fit the held-out ray-cast errors
    better than 9 SH coefficients (the evidence for ``default_encoding = "oct"``)."""
    report = fit_report(packaged, n_holdout=128)
    sh, oct_ = report["sh"], report["oct"]
    msg = (
        f"oct: max {oct_['max_abs']:.4f} rms {oct_['rms']:.4f} mean {oct_['mean_abs']:.4f}; "
        f"sh: max {sh['max_abs']:.4f} rms {sh['rms']:.4f} mean {sh['mean_abs']:.4f}"
    )
    assert report["n_holdout"] == 128
    assert oct_["rms"] < sh["rms"], msg
    assert oct_["max_abs"] < 0.1, msg
    assert sh["max_abs"] < 0.25, msg  # 9 coefficients cannot follow the kinks; still bounded
    assert 0 < oct_["mean_abs"] <= oct_["rms"] <= oct_["max_abs"], msg


def test_packaged_table_shows_fig_3_2_contrast(packaged):
    """EA fig. 3.1/3.2: the bottom layer (mask 0b00110011) loses ~nothing seen from the top
    and half seen from the side; one child loses ¾ from anywhere; a full node loses nothing."""
    top, side = np.array([0.0, -1.0, 0.0]), np.array([1.0, 0.0, 0.0])
    for encoding, tol in (("oct", 0.1), ("sh", 0.25)):
        e_top = float(packaged.error(0b00110011, top, encoding))
        e_side = float(packaged.error(0b00110011, side, encoding))
        assert e_top < tol and abs(e_side - 0.5) < tol and e_top < e_side, (encoding, e_top)
        singles = packaged.error(np.array([1 << c for c in range(8)])[:, None],
                                 _random_dirs(20, 6)[None], encoding)
        assert np.abs(singles - 0.75).max() < tol, encoding
        assert np.abs(packaged.error(255, _random_dirs(20, 7), encoding)).max() < tol
