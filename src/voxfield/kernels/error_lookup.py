"""Kernel forms of the error-table lookups (EA §3.1–3.2, §6.1): what a traversal reads per
hit node. The tables themselves (building, fitting, files) live in ``voxfield.error_table``;
only the per-ray lookups live here, so kernels never import the layer above them."""

from __future__ import annotations

import numpy as np
from numba import njit

from voxfield.kernels.octahedral import oct_bilinear, oct_encode

#: Coefficients of the real spherical harmonics of bands 0–2 (standard order, z polar axis).
SH_COUNT = 9
SH_C0 = 0.28209479177387814
SH_C1 = 0.4886025119029199
SH_C2 = 1.0925484305920792
SH_C3 = 0.31539156525252005
SH_C4 = 0.5462742152960396


@njit(cache=True, nogil=True)
def sh_evaluate(coeffs: np.ndarray, x: float, y: float, z: float) -> float:
    """Sum of 9 coefficients times the basis at one unit direction."""
    return (
        coeffs[0] * SH_C0
        + coeffs[1] * SH_C1 * y
        + coeffs[2] * SH_C1 * z
        + coeffs[3] * SH_C1 * x
        + coeffs[4] * SH_C2 * x * y
        + coeffs[5] * SH_C2 * y * z
        + coeffs[6] * SH_C3 * (3.0 * z * z - 1.0)
        + coeffs[7] * SH_C2 * x * z
        + coeffs[8] * SH_C4 * (x * x - y * y)
    )


@njit(cache=True, nogil=True)
def oct_error(oct_map: np.ndarray, mask: int, x: float, y: float, z: float) -> float:
    """``ErrorTable.error`` for one mask and direction, octahedral encoding."""
    u, v = oct_encode(x, y, z)
    return oct_bilinear(oct_map[mask], u, v)


@njit(cache=True, nogil=True)
def sh_error(sh: np.ndarray, mask: int, x: float, y: float, z: float) -> float:
    """``ErrorTable.error`` for one mask and direction, SH encoding."""
    return sh_evaluate(sh[mask], x, y, z)


@njit(cache=True)
def oct_error_many(oct_map, masks, dirs):
    """``oct_error`` over arrays of masks and directions (the table's vectorised path)."""
    out = np.empty(masks.shape[0])
    for i in range(masks.shape[0]):
        out[i] = oct_error(oct_map, masks[i], dirs[i, 0], dirs[i, 1], dirs[i, 2])
    return out


@njit(cache=True, nogil=True)
def colour_error(
    oct_map: np.ndarray, class_of: np.ndarray, symmetry_of: np.ndarray,
    symmetries: np.ndarray, mask: int, bright: int, x: float, y: float, z: float,
) -> float:
    """``LightingErrorTable.colour_error`` for one configuration and ray: the class's map,
    read through the cube symmetry that carries the configuration onto its representative."""
    index = mask | (bright << 8)
    cls = class_of[index]
    if cls < 0:
        return 0.0
    g = symmetries[symmetry_of[index]]
    u, v = oct_encode(
        g[0, 0] * x + g[0, 1] * y + g[0, 2] * z,
        g[1, 0] * x + g[1, 1] * y + g[1, 2] * z,
        g[2, 0] * x + g[2, 1] * y + g[2, 2] * z,
    )
    return max(0.0, oct_bilinear(oct_map[cls], u, v))


@njit(cache=True)
def colour_error_many(oct_map, class_of, symmetry_of, symmetries, masks, brights, x, y, z):
    """``colour_error`` over arrays of configurations and directions."""
    out = np.empty(masks.shape[0])
    for i in range(masks.shape[0]):
        out[i] = colour_error(oct_map, class_of, symmetry_of, symmetries,
                              masks[i], brights[i], x[i], y[i], z[i])
    return out
