"""Node colours as kernels read them: float32 linear RGB, or 8-bit sRGB decoded by a table.

Octrees store the albedo as 8-bit sRGB by default (3 bytes a node instead of 12: the
traversal's colour fetches then touch a quarter of the memory). Channels that can exceed 1
(emission, lit colours) stay float32. ``node_rgb`` reads either; Numba compiles one version
per storage type, so a kernel never branches on it.
"""

from __future__ import annotations

import numpy as np
from numba import types
from numba.extending import overload

#: Storage of a colour channel: 8-bit sRGB (decoded exactly as the loaders decode 8-bit
#: inputs) or float32 linear.
SRGB8 = "srgb8"
FLOAT32 = "float32"
STORAGES = (SRGB8, FLOAT32)


def srgb_decode(srgb: np.ndarray) -> np.ndarray:
    """sRGB-encoded values in [0, 1] (any shape) to linear float32."""
    c = np.asarray(srgb, dtype=np.float32)
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4).astype(np.float32)


def srgb_encode(linear: np.ndarray) -> np.ndarray:
    """Linear values (any shape, clipped to [0, 1]) to sRGB-encoded float32."""
    c = np.clip(np.asarray(linear, dtype=np.float32), 0.0, 1.0)
    return np.where(c <= 0.0031308, c * 12.92, 1.055 * c ** (1 / 2.4) - 0.055).astype(np.float32)


#: Linear value of each 8-bit sRGB code.
SRGB8_TO_LINEAR = srgb_decode(np.arange(256) / 255.0)


def to_srgb8(linear: np.ndarray) -> np.ndarray:
    """Linear colours to the nearest 8-bit sRGB codes: decoding an 8-bit input and encoding
    it again gives back the same byte."""
    return np.rint(srgb_encode(linear) * 255.0).astype(np.uint8)


def from_srgb8(codes: np.ndarray) -> np.ndarray:
    return SRGB8_TO_LINEAR[np.asarray(codes, np.uint8)]


def encode_channel(linear: np.ndarray, storage: str) -> np.ndarray:
    """A float channel in ``storage`` (``SRGB8`` or ``FLOAT32``)."""
    if storage == SRGB8:
        return to_srgb8(linear)
    return np.asarray(linear, np.float32)


def decode_channel(stored: np.ndarray) -> np.ndarray:
    """A stored channel as float32 linear RGB."""
    if stored.dtype == np.uint8:
        return from_srgb8(stored)
    return np.asarray(stored, np.float32)


def node_rgb(colors, node):
    """Linear ``(r, g, b)`` of ``node`` in a stored channel (Python fallback)."""
    rgb = decode_channel(colors[node : node + 1])[0]
    return float(rgb[0]), float(rgb[1]), float(rgb[2])


@overload(node_rgb, inline="always")
def _node_rgb(colors, node):
    if isinstance(colors, types.Array) and colors.dtype == types.uint8:
        table = SRGB8_TO_LINEAR.astype(np.float64)

        def decode(colors, node):
            return (table[colors[node, 0]], table[colors[node, 1]], table[colors[node, 2]])

        return decode

    def direct(colors, node):
        return float(colors[node, 0]), float(colors[node, 1]), float(colors[node, 2])

    return direct
