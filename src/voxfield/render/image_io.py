"""Image output: sRGB PNG for looking at, linear EXR for measuring; both written atomically."""

from __future__ import annotations

import errno
import io
import os
import warnings
from pathlib import Path

import numpy as np
from PIL import Image

from voxfield.atomic import atomic_path, check_writable, named_for
from voxfield.errors import VoxfieldError
from voxfield.scene.voxel_scene import linear_to_srgb


def save_png(image: np.ndarray, path: str | os.PathLike, *, encode_srgb: bool = True) -> Path:
    """Write a linear [0, 1] image (H×W×3 or H×W) as 8-bit PNG, sRGB-encoded by default."""
    path = named_for(path, ".png", "save_png")
    pixels = png_pixels(image, encode_srgb=encode_srgb)
    with atomic_path(path) as tmp:
        Image.fromarray(pixels).save(tmp, format="PNG")
    return path


def png_pixels(image: np.ndarray, *, encode_srgb: bool = True) -> np.ndarray:
    """The 8-bit pixels ``save_png`` writes for a linear [0, 1] image."""
    data = np.asarray(image, dtype=np.float32)
    if (data.ndim not in (2, 3) or (data.ndim == 3 and data.shape[2] not in (3, 4))
            or 0 in data.shape[:2]):
        raise VoxfieldError(f"cannot write an image of shape {data.shape} as PNG")
    not_a_number = np.isnan(data).reshape(data.shape[0], data.shape[1], -1).any(axis=2)
    if not_a_number.any():
        # A renderer never writes NaN; an array that holds some is broken upstream, and a
        # black pixel alone would pass for a miss or a shadow.
        warnings.warn(f"{int(not_a_number.sum()):,} of {not_a_number.size:,} pixels are "
                      "not a number (NaN) and are written black", UserWarning, stacklevel=3)
    data = np.nan_to_num(data, nan=0.0, posinf=1.0, neginf=0.0)
    data = linear_to_srgb(data) if encode_srgb else np.clip(data, 0.0, 1.0)
    return np.round(data * 255.0).astype(np.uint8)


def png_bytes(image: np.ndarray, *, encode_srgb: bool = True) -> bytes:
    """``save_png``'s file as bytes (for notebooks and embedded pages)."""
    buffer = io.BytesIO()
    Image.fromarray(png_pixels(image, encode_srgb=encode_srgb)).save(buffer, format="PNG")
    return buffer.getvalue()


def save_exr(channels: dict[str, np.ndarray], path: str | os.PathLike) -> Path:
    """Write float32 channels (``{"RGB": H×W×3, "Z": H×W}``) to an EXR file, linear."""
    # optional: OpenEXR loads only when an EXR file is read or written
    import OpenEXR

    path = named_for(path, ".exr", "save_exr")
    data = {k: np.ascontiguousarray(v, dtype=np.float32) for k, v in channels.items()}
    sizes = [v.shape[:2] if v.ndim in (2, 3) else None for v in data.values()]
    if not sizes or None in sizes or len(set(sizes)) != 1 or 0 in sizes[0]:
        raise VoxfieldError("an EXR needs at least one channel, every one an H×W or H×W×C "
                            f"array of one shared, non-empty size; got {_shapes(data)}")
    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
    try:
        with atomic_path(path) as tmp, OpenEXR.File(header, data) as f:
            f.write(str(tmp))
    except RuntimeError as exc:  # OpenEXR's only failure type, a full disk included
        raise _write_failure(exc, path) from exc
    return path


def _shapes(data: dict[str, np.ndarray]) -> str:
    return ", ".join(f"{k} {v.shape}" for k, v in data.items()) or "no channels"


def _write_failure(exc: RuntimeError, path: Path) -> OSError:
    """The ``OSError`` a library's text-only write failure stands for: its errno where the
    text carries the system's message for one (the command line names those plainly)."""
    text = str(exc)
    for code in (errno.ENOSPC, errno.EDQUOT, errno.EROFS, errno.EACCES, errno.EIO):
        if os.strerror(code) in text:
            return OSError(code, os.strerror(code), str(path))
    return OSError(None, text.splitlines()[0] if text else type(exc).__name__, str(path))


def load_exr(path: str | os.PathLike) -> dict[str, np.ndarray]:
    """Read every channel of an EXR file (RGB kept together)."""
    # optional: OpenEXR loads only when an EXR file is read or written
    import OpenEXR

    with OpenEXR.File(str(path), separate_channels=True) as f:
        channels = {name: np.array(ch.pixels) for name, ch in f.channels().items()}
    if {"R", "G", "B"} <= set(channels):
        channels["RGB"] = np.stack([channels.pop(c) for c in "RGB"], axis=-1)
    return channels


def image_format(path: str | os.PathLike) -> str:
    """``".png"`` or ``".exr"``, from the path's suffix in any case; anything else is bad
    input."""
    suffix = Path(path).suffix.lower()
    if suffix not in (".png", ".exr"):
        raise VoxfieldError(f"unsupported image format {suffix!r} in {os.fspath(path)!r}; "
                            "use .png or .exr")
    return suffix


def check_image_output(path: str | os.PathLike) -> Path:
    """An image path ``save_result_image`` will accept and can write, checked before the
    render rather than after it."""
    image_format(path)
    return check_writable(path)


def save_result_image(result, path: str | os.PathLike) -> Path:
    """Save a RenderResult: ``.png`` gives the sRGB image, ``.exr`` linear RGB plus depth Z."""
    if image_format(path) == ".png":
        return save_png(result.image, path)
    return save_exr({"RGB": result.image, "Z": result.depth}, path)


#: Display shading: a fixed key light (normalised) and a weak side light on the face normals.
_KEY_LIGHT = np.array([0.45, 0.8, 0.4]) / np.linalg.norm([0.45, 0.8, 0.4])
_SIDE_LIGHT = np.array([0.8, 0.0, -0.6])


def shade_for_display(result) -> np.ndarray:
    """Albedo times a fixed key light on the face normals: easier on the eye, not for metrics.
    A pixel without a normal (a miss, a probe's environment answer) keeps its colour."""
    lambert = np.clip(result.normal @ _KEY_LIGHT, 0.0, 1.0)
    side = np.abs(result.normal @ _SIDE_LIGHT)
    factor = 0.35 + 0.55 * lambert + 0.1 * side
    factor = np.where(np.any(result.normal != 0.0, axis=-1), factor, 1.0)
    return (result.image * factor[..., None]).astype(np.float32)
