"""Real spherical harmonics, bands 0–2 (9 coefficients), the EA thesis's error encoding."""

from __future__ import annotations

import numpy as np

from voxfield.kernels.error_lookup import SH_C0, SH_C1, SH_C2, SH_C3, SH_C4, SH_COUNT

__all__ = ["SH_COUNT", "fit_sh", "sh_basis"]


def sh_basis(directions: np.ndarray) -> np.ndarray:
    """(n, 9) orthonormal real SH basis at unit directions (standard order, z polar axis)."""
    d = np.asarray(directions, dtype=np.float64)
    x, y, z = d[:, 0], d[:, 1], d[:, 2]
    return np.stack(
        [
            np.full_like(x, SH_C0),
            SH_C1 * y,
            SH_C1 * z,
            SH_C1 * x,
            SH_C2 * x * y,
            SH_C2 * y * z,
            SH_C3 * (3.0 * z * z - 1.0),
            SH_C2 * x * z,
            SH_C4 * (x * x - y * y),
        ],
        axis=1,
    )


def fit_sh(directions: np.ndarray, values: np.ndarray) -> np.ndarray:
    """Least-squares SH coefficients, (k, 9), for values (k, n) sampled at n directions."""
    basis = sh_basis(directions)
    coeffs, *_ = np.linalg.lstsq(basis, np.asarray(values, np.float64).T, rcond=None)
    return coeffs.T
