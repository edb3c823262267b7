"""ErrorTable: the error of sampling a node instead of its children, per child mask and
direction, in two encodings — 9 SH coefficients (EA §3.2) and a bordered octahedral map
(EA §6.2). Built by ``voxfield errors build``; one file ships with the package.
"""

from __future__ import annotations

import functools
import hashlib
import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from voxfield.array_files import load_arrays
from voxfield.atomic import atomic_path
from voxfield.error_table.directions import fibonacci_directions, random_directions
from voxfield.error_table.spherical_harmonics import fit_sh, sh_basis
from voxfield.errors import VoxfieldError
from voxfield.kernels.error_lookup import oct_error_many
from voxfield.kernels.error_raycast import (
    child_hit_histograms,
    errors_from_histograms,
    image_plane_samples,
)
from voxfield.kernels.octahedral import add_border, texel_directions
from voxfield.progress import progress_bar

ENCODINGS = ("sh", "oct")
#: The error model's calibration on the thesis's Desert terrain (EA §5.1.4): refine where
#: ``e(r, N) + THESIS_DECAY · mean_c e(r, c)`` exceeds ``THESIS_THRESHOLD``.
THESIS_THRESHOLD = 0.154
THESIS_DECAY = 0.2
FORMAT = "voxfield-error-table"
FORMAT_VERSION = 1
LIGHTING_FORMAT = "voxfield-lighting-error-table"
#: Each table file's kind by its format, so a file of one kind given for the other says so.
TABLE_KINDS = {FORMAT: "error table", LIGHTING_FORMAT: "lighting error table"}
DEFAULT_TABLE = Path(__file__).parent / "data" / "error_table.npz"
REBUILD_COMMAND = "voxfield errors build --out " + "src/voxfield/error_table/data/error_table.npz"


class ErrorTableError(VoxfieldError):
    """An error table file is missing, corrupt or was built differently than recorded."""


@dataclass(frozen=True)
class ErrorTable:
    """Per-mask error over the sphere; ``error(mask, direction)`` is the one interface.

    Directions are ray travel directions. ``raw`` holds the ray-cast errors at the Fibonacci
    ``directions`` the SH fit used; ``oct_map`` holds (256, R + 2, R + 2) bordered maps whose
    interior texels were ray-cast at the texel-centre directions.
    """

    directions: np.ndarray  # (n, 3) float64
    raw: np.ndarray  # (256, n) float32
    sh: np.ndarray  # (256, 9) float32
    oct_map: np.ndarray  # (256, R + 2, R + 2) float32
    params: dict = field(default_factory=dict)  # what determines the table, nothing more:
    # no build time, so rebuilding the packaged table rewrites its file byte for byte
    default_encoding: str = "oct"

    @property
    def oct_resolution(self) -> int:
        return self.oct_map.shape[-1] - 2

    @functools.cached_property
    def kernel_maps(self) -> tuple[np.ndarray, np.ndarray]:
        """(oct_map, sh) as the kernels read them, float64 and contiguous: converted once per
        table, where every render converting them (2.4 MB) cost a 32×32 probe 10 % of it."""
        return (np.ascontiguousarray(self.oct_map, np.float64),
                np.ascontiguousarray(self.sh, np.float64))

    def error(self, mask, direction, encoding: str | None = None) -> np.ndarray:
        """Error for masks (int or array) and unit directions (3 or N×3), broadcast."""
        encoding = encoding or self.default_encoding
        masks = np.asarray(mask, dtype=np.int64)
        dirs = np.asarray(direction, dtype=np.float64)
        if dirs.shape[-1] != 3:
            raise VoxfieldError(f"directions must end in 3 components, got shape {dirs.shape}")
        if np.any((masks < 0) | (masks > 255)):
            raise VoxfieldError("child masks must be between 0 and 255")
        norms = np.linalg.norm(dirs, axis=-1, keepdims=True)
        if np.any(norms == 0) or not np.all(np.isfinite(dirs)):
            raise VoxfieldError("directions must be finite and non-zero")
        dirs = dirs / norms
        masks, dirs_b = np.broadcast_arrays(masks[..., None], dirs)
        masks = masks[..., 0]
        flat_m = np.array(masks.reshape(-1))  # own copies: broadcast views are read-only
        flat_d = np.array(dirs_b.reshape(-1, 3))
        if encoding == "sh":
            out = np.einsum("ij,ij->i", sh_basis(flat_d), self.sh[flat_m].astype(np.float64))
        elif encoding == "oct":
            out = oct_error_many(self.oct_map, flat_m, flat_d)
        else:
            raise VoxfieldError(f"unknown encoding {encoding!r}; choose one of {ENCODINGS}")
        return np.clip(out, 0.0, 1.0).reshape(masks.shape)


#: Framebuffer sides (rays per direction) a ray-cast error table takes: two rays a side at
#: least to cover a node, 4096 (16.8M rays a direction) at most.
MIN_RESOLUTION, MAX_RESOLUTION = 2, 4096


def check_resolution(resolution) -> int:
    """``resolution`` as an int in ``MIN_RESOLUTION..MAX_RESOLUTION``."""
    if not MIN_RESOLUTION <= int(resolution) <= MAX_RESOLUTION:
        raise VoxfieldError(f"framebuffer resolution must be in {MIN_RESOLUTION}.."
                            f"{MAX_RESOLUTION}, got {resolution}")
    return int(resolution)


def raycast_errors(directions: np.ndarray, resolution: int = 512, seed: int = 0) -> np.ndarray:
    """(256, n) ray-cast errors at the given ray directions (EA Algorithm 1)."""
    resolution = check_resolution(resolution)
    dirs = np.ascontiguousarray(directions, dtype=np.float64)
    if dirs.ndim != 2 or dirs.shape[1] != 3 or len(dirs) == 0:
        raise VoxfieldError(f"directions must be N×3, got {dirs.shape}")
    norms = np.linalg.norm(dirs, axis=1)
    if not (np.all(np.isfinite(dirs)) and np.all(norms > 0)):
        raise VoxfieldError("directions must be finite and non-zero")
    dirs = dirs / norms[:, None]
    samples = image_plane_samples(resolution, int(seed))
    return errors_from_histograms(child_hit_histograms(dirs, samples))


def build_error_table(
    n_directions: int = 1024, resolution: int = 512, oct_resolution: int = 32, seed: int = 0,
    progress: bool = False,
) -> ErrorTable:
    """Ray-cast the errors and fit both encodings (deterministic for fixed parameters)."""
    if n_directions < 9:
        raise VoxfieldError("need at least 9 directions to fit 9 SH coefficients")
    if not 2 <= oct_resolution <= 256:
        raise VoxfieldError(f"octahedral map resolution must be in 2..256, got {oct_resolution}")
    directions = fibonacci_directions(n_directions)
    texels = texel_directions(oct_resolution)
    all_dirs = np.concatenate([directions, texels])
    chunk = 128
    parts = []
    with progress_bar(total=len(all_dirs), desc="error table", unit="dir", enabled=progress) as bar:
        for i in range(0, len(all_dirs), chunk):
            parts.append(raycast_errors(all_dirs[i : i + chunk], resolution, seed))
            bar.update(min(chunk, len(all_dirs) - i))
    errors = np.concatenate(parts, axis=1)
    raw = errors[:, :n_directions]
    oct_interior = errors[:, n_directions:].reshape(256, oct_resolution, oct_resolution)
    params = {
        "n_directions": int(n_directions),
        "resolution": int(resolution),
        "oct_resolution": int(oct_resolution),
        "seed": int(seed),
        "direction_set": "fibonacci",
    }
    return ErrorTable(
        directions=directions,
        raw=raw.astype(np.float32),
        sh=fit_sh(directions, raw).astype(np.float32),
        oct_map=add_border(oct_interior).astype(np.float32),
        params=params,
    )


def _checksum(arrays: dict[str, np.ndarray]) -> str:
    digest = hashlib.sha256()
    for name in sorted(arrays):
        digest.update(name.encode())
        digest.update(np.ascontiguousarray(arrays[name]).tobytes())
    return digest.hexdigest()


def save_error_table(table: ErrorTable, path: str | Path) -> Path:
    """Write the table with its parameters and a SHA-256 of its arrays (atomically)."""
    arrays = {
        "directions": table.directions.astype(np.float64),
        "raw": table.raw.astype(np.float16),  # for reports and refits; ±5e-4 is plenty
        "sh": table.sh,
        "oct_map": table.oct_map,
    }
    header = {
        "format": FORMAT,
        "version": FORMAT_VERSION,
        "params": table.params,
        "default_encoding": table.default_encoding,
        "sha256": _checksum(arrays),
    }
    path = Path(path)
    with atomic_path(path) as tmp, open(tmp, "wb") as f:
        np.savez_compressed(
            f, header=np.frombuffer(json.dumps(header).encode(), np.uint8), **arrays
        )
    _packaged_error_table.cache_clear()  # a rebuilt packaged table is read afresh
    return path


def read_table_file(path: Path, keys: tuple[str, ...], fmt: str, version: int, what: str,
                    hint: str, maker: str) -> tuple[dict, dict[str, np.ndarray]]:
    """The JSON header and ``keys`` arrays of a table file whose format, version and SHA-256
    match; ErrorTableError naming ``what`` and the rebuild ``hint`` otherwise, or, for a
    file that is no such table at all (a scene, an octree), the command that makes one
    (``maker``) rather than advice to write over it."""
    header = None
    try:
        with load_arrays(path) as data:
            header = json.loads(bytes(data["header"]).decode())
            arrays = {k: data[k] for k in keys}
    except Exception as exc:  # noqa: BLE001 - zip/zlib/json can fail many ways on a bad file
        if isinstance(header, dict) and header.get("format") == fmt:  # a damaged table
            raise ErrorTableError(f"{what} {path} is unreadable ({exc!r}); {hint}") from exc
        raise ErrorTableError(_not_a_table(path, what, maker, header)) from exc
    if not isinstance(header, dict) or header.get("format") != fmt:
        raise ErrorTableError(_not_a_table(path, what, maker, header))
    if header.get("version") != version:
        raise ErrorTableError(f"{path} is not a version-{version} {what}; {hint}")
    if _checksum(arrays) != header.get("sha256"):
        raise ErrorTableError(f"{what} {path} fails its checksum (corrupt?); {hint}")
    # The checksum covers the arrays, not the header, and proves only that they are what
    # was written: a table edited and re-summed must still hold numbers a lookup can use.
    for key, array in arrays.items():
        if array.dtype.kind not in "fiu" or (array.dtype.kind == "f"
                                             and not np.isfinite(array).all()):
            raise ErrorTableError(f"{what} {path} holds values that are not finite numbers in "
                                  f"{key!r}; {hint}")
    params = header.get("params", {})
    if not isinstance(params, dict) or not all(
            type(params.get(key, 0)) is int and params.get(key, 0) >= 0
            for key in ("n_directions", "resolution", "oct_resolution", "seed")):
        raise ErrorTableError(f"{what} {path} has a malformed header (its parameters); {hint}")
    return header, arrays


def _not_a_table(path: Path, what: str, maker: str, header=None) -> str:
    kind = TABLE_KINDS.get(header.get("format")) if isinstance(header, dict) else None
    if kind is not None:  # the other kind of table
        return f"{path} is {_article(kind)} {kind}, not {_article(what)} {what}"
    return f"{path} is not {_article(what)} {what}; make one with `{maker}`"


def _article(noun: str) -> str:
    return "an" if noun[0] in "aeiou" else "a"


def table_format(path: str | Path) -> str | None:
    """The format a table file's header names; None where it has no readable header."""
    try:
        with load_arrays(Path(path)) as data:
            header = json.loads(bytes(data["header"]).decode())
    except Exception:  # noqa: BLE001 - any unreadable file is simply no table's
        return None
    return header.get("format") if isinstance(header, dict) else None


def check_table_file(path: Path, what: str, hint: str) -> None:
    """A table path that names no file: a folder is said to be one, a missing file gets
    the rebuild ``hint``."""
    if path.is_dir():
        raise ErrorTableError(f"{path} is a folder, not {_article(what)} {what} file")
    if not path.is_file():
        raise ErrorTableError(f"{what} {path} is missing; {hint}")


def load_error_table(path: str | Path | None = None) -> ErrorTable:
    """Read a table (the packaged one by default, read and checksummed once per process),
    verifying its checksum."""
    if path is None:
        return _packaged_error_table()
    return _read_error_table(Path(path))


@functools.lru_cache(maxsize=1)
def _packaged_error_table() -> ErrorTable:
    return _read_error_table(DEFAULT_TABLE)


def _read_error_table(path: Path) -> ErrorTable:
    hint = f"rebuild it with `{REBUILD_COMMAND}`" if path == DEFAULT_TABLE else (
        f"rebuild it with `voxfield errors build --out {path}`"
    )
    check_table_file(path, "error table", hint)
    header, arrays = read_table_file(path, ("directions", "raw", "sh", "oct_map"), FORMAT,
                                     FORMAT_VERSION, "error table", hint,
                                     "voxfield errors build")
    n = len(arrays["directions"])
    if (arrays["directions"].shape != (n, 3) or n < 1 or arrays["raw"].shape != (256, n)
            or arrays["sh"].shape != (256, 9)):
        raise ErrorTableError(f"error table {path} has inconsistent array shapes; {hint}")
    oct_map = arrays["oct_map"]
    if (oct_map.ndim != 3 or oct_map.shape[0] != 256 or oct_map.shape[1] != oct_map.shape[2]
            or oct_map.shape[1] < 1):
        raise ErrorTableError(f"error table {path} has a malformed octahedral map; {hint}")
    if header.get("default_encoding", "oct") not in ENCODINGS:
        raise ErrorTableError(f"error table {path} names an unknown default encoding; {hint}")
    return ErrorTable(
        directions=arrays["directions"], raw=arrays["raw"].astype(np.float32), sh=arrays["sh"],
        oct_map=arrays["oct_map"], params=header.get("params", {}),
        default_encoding=header.get("default_encoding", "oct"),
    )


def fit_report(table: ErrorTable, n_holdout: int = 512, seed: int = 12345) -> dict:
    """Max and RMS difference of each encoding from fresh ray-cast errors at held-out random
    directions (same framebuffer resolution and seed as the table)."""
    dirs = random_directions(n_holdout, seed)
    truth = raycast_errors(dirs, table.params.get("resolution", 512), table.params.get("seed", 0))
    masks = np.arange(1, 256)  # mask 0 is no node at all
    report = {"n_holdout": n_holdout}
    for encoding in ENCODINGS:
        approx = table.error(masks[:, None], dirs[None, :, :], encoding)
        diff = approx - truth[1:]
        report[encoding] = {
            "max_abs": float(np.abs(diff).max()),
            "rms": float(np.sqrt(np.mean(diff**2))),
            "mean_abs": float(np.abs(diff).mean()),
        }
    return report
