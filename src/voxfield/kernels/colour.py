"""Node colours as kernels read them: float32 linear RGB, 8-bit sRGB decoded by a table, or
shared-exponent RGB9E5.

Octrees store the albedo as 8-bit sRGB by default (3 bytes a node instead of 12: the
traversal's colour fetches then touch a quarter of the memory). Channels that can exceed 1
(lit colours) are kept as RGB9E5 by default: the packed HDR format of OpenGL's
``EXT_texture_shared_exponent``, one uint32 a node (9-bit mantissas and a 5-bit exponent
shared by the three channels), so a 2048² terrain's four lit channels take 330 MB instead of
a gigabyte, and an octree file a third of the bytes to write. Each channel comes back within
a 511th of ``max(r, g, b)``, less than one step of an 8-bit image. Emission and a
user's own channels stay float32. ``node_rgb`` reads every storage.

The render kernels take a channel as ``StoredColours``: every storage in one Numba type, so
each of them compiles once for all three, where a plain array made Numba compile each
kernel again per storage (the primary-ray and error-aware kernels, a minute or more each).
Reading a colour then costs one branch, the same way for every node of a render.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit, prange, types
from numba.extending import overload

from voxfield.kernels.memory_hints import prefetch

#: Storage of a colour channel: 8-bit sRGB (decoded exactly as the loaders decode 8-bit
#: inputs) or float32 linear.
SRGB8 = "srgb8"
FLOAT32 = "float32"
STORAGES = (SRGB8, FLOAT32)
#: Storage of an HDR channel (lit colours): packed shared-exponent RGB, one uint32 a node.
RGB9E5 = "rgb9e5"
HDR_STORAGES = (RGB9E5, FLOAT32)

_MANTISSA_BITS = 9
_EXPONENT_BIAS = 15
#: The largest value RGB9E5 holds (65408); larger channels are clamped to it.
RGB9E5_MAX = float((1 << _MANTISSA_BITS) - 1) / (1 << _MANTISSA_BITS) * 2.0 ** (
    31 - _EXPONENT_BIAS)
#: The scale of a mantissa step for each of the 32 shared exponents.
RGB9E5_STEP = np.ldexp(1.0, np.arange(32) - _EXPONENT_BIAS - _MANTISSA_BITS)
# Per exponent the power of two that scales a channel to its mantissa, float32 (one more
# for the exponent a round-up may reach), and the largest value as a float32 and its bits.
_RGB9E5_SCALE32 = np.ldexp(np.float32(1.0), _EXPONENT_BIAS + _MANTISSA_BITS - np.arange(33))
_RGB9E5_MAX32 = np.float32(RGB9E5_MAX)
_RGB9E5_MAX_BITS = np.array([RGB9E5_MAX], np.float32).view(np.int32)[0]


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


def srgb8_by_formula(linear: np.ndarray) -> np.ndarray:
    """``rint(srgb_encode(linear) · 255)``: the 8-bit sRGB codes ``to_srgb8`` gives, worked
    out value by value (what its thresholds are found from, and the tests' oracle)."""
    return np.rint(srgb_encode(linear) * 255.0).astype(np.uint8)


def _srgb8_thresholds() -> np.ndarray:
    """Per code ``k`` = 1..255, the smallest float32 that ``srgb8_by_formula`` takes to ``k``
    or more: a bisection over the bit patterns of [0, 1] (non-negative floats order as their
    bits do), all codes at once."""
    codes = np.arange(1, 256)
    low = np.zeros(255, np.int64)  # code of 0.0: 0, below every k
    high = np.full(255, np.float32(1.0).view(np.int32), np.int64)  # code of 1.0: 255
    while np.any(high - low > 1):
        middle = (low + high) // 2
        reached = srgb8_by_formula(middle.astype(np.int32).view(np.float32)) >= codes
        high = np.where(reached, middle, high)
        low = np.where(reached, low, middle)
    return high.astype(np.int32).view(np.float32)


#: Where each 8-bit sRGB code starts: a value's code is the number of thresholds at or below
#: it. The formula is monotonic, so counting gives its codes exactly; checked for every float32
#: in [0, 1] (no mismatch in 1,065,353,217) and, by the tests, around every threshold.
SRGB8_THRESHOLDS = _srgb8_thresholds()
#: Buckets of [0, 1] with the thresholds at or below each one's lower end, where counting
#: starts: a bucket holds at most a few thresholds, so the count takes a step or two.
_SRGB8_BUCKETS = 4096
_SRGB8_BUCKET_START = np.searchsorted(
    SRGB8_THRESHOLDS, (np.arange(_SRGB8_BUCKETS) / _SRGB8_BUCKETS).astype(np.float32),
    side="right").astype(np.int64)


@njit(cache=True, nogil=True)
def _srgb8_codes(linear: np.ndarray, out: np.ndarray) -> None:
    """``out[i]`` = the number of ``SRGB8_THRESHOLDS`` at or below ``linear[i]`` (NaN: 0).
    Serial: the streamed build calls it from several threads at once."""
    thresholds = SRGB8_THRESHOLDS
    starts = _SRGB8_BUCKET_START
    for i in range(linear.shape[0]):
        value = linear[i]
        if not value > 0.0:  # zero, negative or NaN
            out[i] = 0
            continue
        if value >= 1.0:  # (infinity included, which has no bucket)
            out[i] = 255
            continue
        code = starts[int(value * _SRGB8_BUCKETS)]
        while code < 255 and thresholds[code] <= value:
            code += 1
        out[i] = code


def to_srgb8(linear: np.ndarray) -> np.ndarray:
    """Linear colours (any shape, as float32) to the nearest 8-bit sRGB codes, as
    ``srgb8_by_formula`` rounds them (NaN to 0): decoding an 8-bit input and encoding it
    again gives back the same byte. A table lookup, 16× faster than the formula."""
    linear = np.ascontiguousarray(linear, np.float32)
    out = np.empty(linear.shape, np.uint8)
    _srgb8_codes(linear.reshape(-1), out.reshape(-1))
    return out


def from_srgb8(codes: np.ndarray) -> np.ndarray:
    return SRGB8_TO_LINEAR[np.asarray(codes, np.uint8)]


@njit(cache=True, nogil=True, inline="always")
def _clamped(value: np.float32, bits: np.int32) -> tuple[np.float32, np.int32]:
    """A float32 channel clamped to ``[0, RGB9E5_MAX]`` (NaN to 0) and the bits of the result:
    non-negative floats order as their bits do."""
    if not value > 0.0:
        return np.float32(0.0), np.int32(0)  # zero, negative or NaN
    if value > _RGB9E5_MAX32:
        return _RGB9E5_MAX32, _RGB9E5_MAX_BITS
    return value, bits


@njit(parallel=True, cache=True, nogil=True)
def _pack_rows(linear: np.ndarray, bits: np.ndarray, out: np.ndarray) -> None:
    """Float32 ``(n, 3)`` colours (``bits``: the same memory as int32) as RGB9E5 codes,
    rounded to nearest as the format's specification rounds: channels clamped, the shared
    exponent ``max(-16, floor(log2(largest))) + 16``, raised by one when the largest
    mantissa would round up to 512. The float's own exponent bits give ``floor(log2)``, and
    the scales are powers of two, so every product and rounding is exact: the codes are the
    specification's."""
    for i in prange(linear.shape[0]):
        r, r_bits = _clamped(linear[i, 0], bits[i, 0])
        g, g_bits = _clamped(linear[i, 1], bits[i, 1])
        b, b_bits = _clamped(linear[i, 2], bits[i, 2])
        largest = max(r, g, b)
        exponent = max(((max(r_bits, g_bits, b_bits) >> 23) & 255) - 127,
                       -_EXPONENT_BIAS - 1) + _EXPONENT_BIAS + 1
        # Truncating a non-negative value floors it, as a conversion LLVM vectorizes.
        exponent += np.int64(np.uint32(largest * _RGB9E5_SCALE32[exponent] + np.float32(0.5))
                             == 512)
        scale = _RGB9E5_SCALE32[exponent]
        red = np.uint32(r * scale + np.float32(0.5))
        green = np.uint32(g * scale + np.float32(0.5))
        blue = np.uint32(b * scale + np.float32(0.5))
        out[i] = red | (green << 9) | (blue << 18) | (np.uint32(exponent) << 27)


def to_rgb9e5(linear: np.ndarray) -> np.ndarray:
    """``(n, 3)`` linear colours (as float32) as ``(n,)`` uint32 RGB9E5 codes."""
    linear = np.ascontiguousarray(linear, np.float32)
    if linear.ndim != 2 or linear.shape[1] != 3:
        raise ValueError(f"expected (n, 3) colours, got shape {linear.shape}")
    out = np.empty(linear.shape[0], np.uint32)
    _pack_rows(linear, linear.view(np.int32), out)
    return out


def from_rgb9e5(codes: np.ndarray) -> np.ndarray:
    """``(n,)`` RGB9E5 codes as ``(n, 3)`` float32 linear colours (exactly: every code's
    value is a float32)."""
    codes = np.asarray(codes, np.uint32)
    step = RGB9E5_STEP[codes >> 27].astype(np.float32)
    mantissas = (codes[:, None] >> np.array([0, 9, 18], np.uint32)) & np.uint32(511)
    return mantissas.astype(np.float32) * step[:, None]


def encode_channel(linear: np.ndarray, storage: str) -> np.ndarray:
    """A float channel in ``storage`` (``SRGB8``, ``FLOAT32`` or ``RGB9E5``)."""
    if storage == SRGB8:
        return to_srgb8(linear)
    if storage == RGB9E5:
        return to_rgb9e5(linear)
    return np.asarray(linear, np.float32)


def decode_channel(stored: np.ndarray) -> np.ndarray:
    """A stored channel as float32 linear RGB."""
    if stored.dtype == np.uint8:
        return from_srgb8(stored)
    if stored.dtype == np.uint32:
        return from_rgb9e5(stored)
    return np.asarray(stored, np.float32)


def storage_of(stored: np.ndarray) -> str:
    """The storage a stored channel is in."""
    if stored.dtype == np.uint8:
        return SRGB8
    if stored.dtype == np.uint32:
        return RGB9E5
    return FLOAT32


class StoredColours(NamedTuple):
    """A stored channel as the render kernels take it: the array of its storage, the other
    two empty (``stored_colours``)."""

    srgb8: np.ndarray  # uint8 (nodes, 3)
    rgb9e5: np.ndarray  # uint32 (nodes,)
    linear: np.ndarray  # float32 (nodes, 3)

    @property
    def stored(self) -> np.ndarray:
        """The channel as stored."""
        if len(self.srgb8):
            return self.srgb8
        return self.rgb9e5 if len(self.rgb9e5) else self.linear


_NO_SRGB8 = np.zeros((0, 3), np.uint8)
_NO_RGB9E5 = np.zeros(0, np.uint32)
_NO_LINEAR = np.zeros((0, 3), np.float32)


def stored_colours(stored: np.ndarray) -> StoredColours:
    """A stored channel (``encode_channel``'s output) as ``StoredColours``."""
    storage = storage_of(stored)
    if storage == SRGB8:
        return StoredColours(np.ascontiguousarray(stored), _NO_RGB9E5, _NO_LINEAR)
    if storage == RGB9E5:
        return StoredColours(_NO_SRGB8, np.ascontiguousarray(stored), _NO_LINEAR)
    return StoredColours(_NO_SRGB8, _NO_RGB9E5, np.ascontiguousarray(stored, np.float32))


@njit(cache=True, nogil=True, inline="always")
def stored_bytes(colors: StoredColours) -> int:
    """Bytes of the channel a ``StoredColours`` holds."""
    return colors.srgb8.nbytes + colors.rgb9e5.nbytes + colors.linear.nbytes


@njit(cache=True, nogil=True, inline="always")
def prefetch_stored(colors: StoredColours, node: int) -> None:
    """Start loading ``node``'s stored colour (``memory_hints.prefetch``)."""
    if colors.srgb8.shape[0] > 0:
        prefetch(colors.srgb8, (node, 0))
    elif colors.rgb9e5.shape[0] > 0:
        prefetch(colors.rgb9e5, node)
    else:
        prefetch(colors.linear, (node, 0))


def node_rgb(colors, node):
    """Linear ``(r, g, b)`` of ``node`` in a stored channel or ``StoredColours`` (Python
    fallback)."""
    if isinstance(colors, StoredColours):
        colors = colors.stored
    rgb = decode_channel(colors[node : node + 1])[0]
    return float(rgb[0]), float(rgb[1]), float(rgb[2])


@overload(node_rgb, inline="always")
def _node_rgb(colors, node):
    if isinstance(colors, types.BaseNamedTuple) and colors.instance_class is StoredColours:

        def read_stored(colors, node):
            if colors.srgb8.shape[0] > 0:
                return node_rgb(colors.srgb8, node)
            if colors.rgb9e5.shape[0] > 0:
                return node_rgb(colors.rgb9e5, node)
            return node_rgb(colors.linear, node)

        return read_stored

    if isinstance(colors, types.Array) and colors.dtype == types.uint8:
        table = SRGB8_TO_LINEAR.astype(np.float64)

        def decode(colors, node):
            return (table[colors[node, 0]], table[colors[node, 1]], table[colors[node, 2]])

        return decode

    if isinstance(colors, types.Array) and colors.dtype == types.uint32:
        steps = RGB9E5_STEP.copy()

        def unpack(colors, node):
            code = colors[node]
            step = steps[code >> 27]
            return ((code & 511) * step, ((code >> 9) & 511) * step,
                    ((code >> 18) & 511) * step)

        return unpack

    def direct(colors, node):
        return float(colors[node, 0]), float(colors[node, 1]), float(colors[node, 2])

    return direct
