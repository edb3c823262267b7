"""Real spherical harmonics, bands 0–2 (9 coefficients), the EA thesis's error encoding."""

from __future__ import annotations

import numpy as np
from numba import njit

SH_COUNT = 9
_C0 = 0.28209479177387814
_C1 = 0.4886025119029199
_C2 = 1.0925484305920792
_C3 = 0.31539156525252005
_C4 = 0.5462742152960396


def sh_basis(directions: np.ndarray) -> np.ndarray:
    """(n, 9) orthonormal real SH basis at unit directions (standard order, z polar axis)."""
    d = np.asarray(directions, dtype=np.float64)
    x, y, z = d[:, 0], d[:, 1], d[:, 2]
    return np.stack(
        [
            np.full_like(x, _C0),
            _C1 * y,
            _C1 * z,
            _C1 * x,
            _C2 * x * y,
            _C2 * y * z,
            _C3 * (3.0 * z * z - 1.0),
            _C2 * x * z,
            _C4 * (x * x - y * y),
        ],
        axis=1,
    )


@njit(cache=True, nogil=True)
def sh_evaluate(coeffs: np.ndarray, x: float, y: float, z: float) -> float:
    """Sum of 9 coefficients times the basis at one unit direction (kernel form)."""
    return (
        coeffs[0] * _C0
        + coeffs[1] * _C1 * y
        + coeffs[2] * _C1 * z
        + coeffs[3] * _C1 * x
        + coeffs[4] * _C2 * x * y
        + coeffs[5] * _C2 * y * z
        + coeffs[6] * _C3 * (3.0 * z * z - 1.0)
        + coeffs[7] * _C2 * x * z
        + coeffs[8] * _C4 * (x * x - y * y)
    )


def fit_sh(directions: np.ndarray, values: np.ndarray) -> np.ndarray:
    """Least-squares SH coefficients, (k, 9), for values (k, n) sampled at n directions."""
    basis = sh_basis(directions)
    coeffs, *_ = np.linalg.lstsq(basis, np.asarray(values, np.float64).T, rcond=None)
    return coeffs.T
