"""A baked ProbeSet on disk: one folder, a JSON header, one file per probe, EXR atlases.

Layout of a probe-set folder (format ``voxfield-probes``, version 1)::

    DIR/
      probes.json        the header (below); written first, rewritten as probes complete
      probe_00000.npz    probe 0: arrays ``radiance``, ``distance``, ``normal`` (below)
      probe_00001.npz    ...
      radiance.exr       once complete: atlas of every probe's radiance, RGB half, linear
      distance.exr       once complete: atlas of radial distances, channel ``Z``, float32
      normal.exr         once complete: atlas of octahedral normals, channels ``U``, ``V``, float32

The header ``probes.json`` holds:

- ``format`` (``"voxfield-probes"``) and ``version`` (1): readers refuse anything else;
- ``scene``: ``fingerprint`` (a hash of the octree structure and the baked colour channel,
  ``Octree.fingerprint``), ``channel`` and ``name``;
- ``grid``: ``ProbeGrid.to_dict()`` (origin, spacing, counts, per-probe offsets, enabled);
- ``options``: ``BakeOptions.to_dict()`` (renderer, resolution, samples, threshold, seed, ...);
- ``resolution`` R and ``probe_count`` N;
- ``encodings``: per map its dtype, per-probe shape and meaning —
  ``radiance`` float16 (R, R, 3) linear RGB; ``distance`` float32 (R, R) radial distance from
  the probe centre in voxel units, ``inf`` where the ray escaped; ``normal`` int16 (R, R, 2)
  the surface normal octahedral-encoded, snorm16 (``value / 32767`` in [-1, 1]);
- ``mapping``: texel (row, col) of every map is octahedral texel (v, u), texel centres at
  ``(i + 0.5) / R``, y up (``voxfield.kernels.octahedral``);
- ``probes``: per finished probe (key: its index) the file name, a ``checksum`` of its three
  arrays (blake2b over dtype, shape and bytes), the ``position`` it was baked at (voxel
  units; folders baked before positions were recorded lack it and are read unchecked) and its
  cost (``BakeCost``: ``radiance_rays``, ``radiance_steps``, ``radiance_seconds``,
  ``geometry_rays``, ``geometry_steps``, ``geometry_seconds``). A reader refuses a probe whose
  recorded position is not where the header's grid puts it: the maps only hold what was seen
  from that point, so a grid edited after the bake would draw them somewhere else. Disabled
  probes (``grid.enabled`` false) have no file: they read back as ``ProbeMaps.empty`` (black,
  distance ``inf``, ``NO_NORMAL``);
- ``complete``: true once every probe is baked and the atlases are written; ``atlas`` then
  describes them: ``columns`` × ``rows`` tiles of ``tile`` = R + 2 texels, probe ``i`` at tile
  ``divmod(i, columns)`` (row, column), each tile the probe's map with a one-texel octahedral
  wrap border (``add_border``) so a bilinear fetch at a tile edge reads the right neighbour;
  unused tiles are zero (radiance, normal) or ``inf`` (distance).

Every file is written atomically (temporary file, then rename), so a killed bake leaves only
whole files. The per-probe ``.npz`` files are the source of truth; the atlases are derived
from them for engines. A probe counts as done only when its file exists, loads, and matches
the checksum the header recorded; ``probes.folder_bake.bake_to_folder`` re-run on the same
scene, grid and options bakes only the probes that are not done.
"""

from __future__ import annotations

import json
import math
import os
import zipfile
import zlib
from pathlib import Path

import numpy as np

from voxfield.array_files import load_arrays
from voxfield.atomic import atomic_path
from voxfield.checks import path_value
from voxfield.errors import VoxfieldError
from voxfield.fingerprint import array_fingerprint
from voxfield.json_output import to_json
from voxfield.kernels.octahedral import add_border
from voxfield.probes.grid import ProbeGrid
from voxfield.probes.probe_set import COST_FIELDS, BakeCost, BakeOptions, ProbeMaps, ProbeSet

FORMAT_NAME = "voxfield-probes"
FORMAT_VERSION = 1
HEADER_NAME = "probes.json"
ATLAS_FILES = {"radiance": "radiance.exr", "distance": "distance.exr", "normal": "normal.exr"}
MAP_NAMES = ("radiance", "distance", "normal")


class ProbeStorageError(VoxfieldError):
    """A probe-set folder is missing, corrupt, or inconsistent with its header."""


class ProbeHeaderError(ProbeStorageError):
    """``probes.json`` is missing, unreadable, or of another format or version."""


class ProbeFileError(ProbeStorageError):
    """A probe's file is missing, corrupt, has the wrong shapes, or fails its checksum."""


class ProbeSetMismatchError(ProbeStorageError):
    """An existing folder was baked from another scene, grid or options."""


def probe_file_name(index: int) -> str:
    return f"probe_{index:05d}.npz"


def owned_file(folder: str | os.PathLike, path: str | os.PathLike) -> bool:
    """Whether ``path`` is one of the files a probe-set folder keeps (its header, atlases
    or probes): an output written there would replace part of the bake."""
    path, folder = Path(os.path.realpath(path)), Path(folder)  # a link is written through
    if not path.parent.exists() or not folder.is_dir() or \
            not path.parent.resolve() == folder.resolve():
        return False
    return (path.name in (HEADER_NAME, *ATLAS_FILES.values())
            or (path.name.startswith("probe_") and path.suffix == ".npz"))


def encodings(resolution: int) -> dict:
    """The per-probe array layout recorded in (and checked against) the header."""
    r = int(resolution)
    return {
        "radiance": {"dtype": "float16", "shape": [r, r, 3],
                     "meaning": "linear RGB radiance arriving at the probe"},
        "distance": {"dtype": "float32", "shape": [r, r],
                     "meaning": "radial distance to the first hit in voxel units; inf: none"},
        "normal": {"dtype": "int16", "shape": [r, r, 2],
                   "meaning": "octahedral-encoded unit surface normal, snorm16 (value / 32767)"},
    }


def maps_checksum(radiance: np.ndarray, distance: np.ndarray, normal: np.ndarray) -> str:
    """A hash of one probe's three arrays (content, dtype and shape)."""
    return array_fingerprint(radiance, distance, normal)


# --------------------------------------------------------------------------- header


def new_header(*, grid, options, fingerprint: str, channel: str, scene_name: str) -> dict:
    """A header for a fresh bake: identity (scene, grid, options) and no probes yet."""
    resolution = int(options.resolution)
    return {
        "format": FORMAT_NAME,
        "version": FORMAT_VERSION,
        "scene": {"fingerprint": fingerprint, "channel": channel, "name": scene_name},
        "grid": to_json(grid.to_dict(), finite=False),
        "options": to_json(options.to_dict(), finite=False),
        "resolution": resolution,
        "probe_count": int(grid.count),
        "encodings": encodings(resolution),
        "mapping": "octahedral; texel (row, col) = (v, u), centres at (i + 0.5) / R; y up",
        "probes": {},
        "complete": False,
    }


def header_text(header: dict) -> str:
    """JSON with one line per top-level key and per probe record: readable in an editor and
    diff, yet compact for grids of thousands of probes."""
    def compact(value) -> str:
        return json.dumps(value, sort_keys=True, separators=(", ", ": "))

    lines = []
    for key in sorted(header):
        if key == "probes" and header[key]:
            records = sorted(header[key].items(), key=lambda kv: int(kv[0]))
            inner = ",\n".join(f"    {json.dumps(k)}: {compact(v)}" for k, v in records)
            lines.append(f'  "probes": {{\n{inner}\n  }}')
        else:
            lines.append(f"  {json.dumps(key)}: {compact(header[key])}")
    return "{\n" + ",\n".join(lines) + "\n}\n"


def write_header(folder: Path, header: dict) -> None:
    with atomic_path(Path(folder) / HEADER_NAME) as tmp:
        tmp.write_text(header_text(header))


def read_header(folder: str | os.PathLike) -> dict:
    """Load and check ``probes.json``: present, JSON, our format and version, sane fields."""
    folder = Path(folder)
    path = folder / HEADER_NAME
    if not folder.is_dir():
        raise ProbeHeaderError(f"{folder}: no such probe-set folder (bake one with voxfield bake)")
    if not path.is_file():
        raise ProbeHeaderError(f"{folder}: no {HEADER_NAME}; this is not a probe-set folder, "
                               "or its bake never started (run voxfield bake)")
    try:
        header = json.loads(path.read_text())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError, RecursionError) as exc:
        raise ProbeHeaderError(f"{path}: unreadable header ({exc}); re-bake with --fresh") from exc
    if not isinstance(header, dict) or header.get("format") != FORMAT_NAME:
        raise ProbeHeaderError(f"{path}: not a {FORMAT_NAME} header")
    if header.get("version") != FORMAT_VERSION:
        raise ProbeHeaderError(
            f"{path}: format version {header.get('version')!r}, this voxfield reads version "
            f"{FORMAT_VERSION}; re-bake with this version (--fresh)"
        )
    missing = [k for k in ("scene", "grid", "options", "resolution", "probe_count", "probes",
                           "encodings") if k not in header]
    if missing:
        raise ProbeHeaderError(f"{path}: header lacks {', '.join(missing)}; re-bake with --fresh")
    count = header["probe_count"]
    if not isinstance(count, int) or isinstance(count, bool) or count < 0:
        raise ProbeHeaderError(f"{path}: probe_count {count!r} is not a whole number; re-bake "
                               "with --fresh")
    r = header["resolution"]
    if not isinstance(r, int) or r < 1 or header["encodings"] != encodings(r):
        raise ProbeHeaderError(f"{path}: resolution {r!r} and encodings do not match this "
                               "format's; re-bake with --fresh")
    if not isinstance(header["probes"], dict):
        raise ProbeHeaderError(f"{path}: 'probes' must be an object")
    scene = header["scene"]
    if not isinstance(scene, dict) or not isinstance(scene.get("fingerprint"), str):
        raise ProbeHeaderError(f"{path}: 'scene' must be an object with the scene's "
                               "fingerprint; re-bake with --fresh")
    return header


def identity(header: dict) -> dict:
    """What must match for a folder to be resumed: scene, grid and bake options."""
    return {"scene": header["scene"]["fingerprint"], "grid": header["grid"],
            "options": header["options"]}


def differences(old: dict, new: dict) -> list[str]:
    """What differs between two identities, as phrases that follow "probes baked", e.g.
    ``["on another probe grid", "with other bake options (resolution)"]``."""
    out = []
    if old["scene"] != new["scene"]:
        out.append("from another scene (or colour channel)")
    if old["grid"] != new["grid"]:
        out.append("on another probe grid")
    if old["options"] != new["options"]:
        keys = sorted(k for k in set(old["options"]) | set(new["options"])
                      if old["options"].get(k) != new["options"].get(k))
        out.append("with other bake options (" + ", ".join(keys) + ")")
    return out


# --------------------------------------------------------------------------- probe files


def write_probe(folder: Path, index: int, maps, position) -> dict:
    """Write one probe's maps atomically; returns its header record (file, checksum, the
    position it was baked at, cost)."""
    radiance, distance, normal = _probe_arrays(maps)
    name = probe_file_name(index)
    cost = {k: getattr(maps.cost, k) for k in COST_FIELDS}
    record = {"file": name, "checksum": maps_checksum(radiance, distance, normal),
              "position": [float(v) for v in np.asarray(position, np.float64).reshape(3)],
              **{k: float(v) if k.endswith("seconds") else int(v) for k, v in cost.items()}}
    # The file carries its own record, so a bake killed before the header caught up can
    # take the probe back (``reconcile_probes``) instead of baking it again.
    with atomic_path(Path(folder) / name) as tmp, open(tmp, "wb") as f:
        np.savez_compressed(f, radiance=radiance, distance=distance, normal=normal,
                            record=np.array(json.dumps(record)))
    return record


def reconcile_probes(folder: Path, header: dict, positions: np.ndarray) -> list[int]:
    """Take into ``header`` every probe file on disk the header does not record yet whose own
    record verifies (shapes as the header's encodings, checksum of its maps, its position
    among ``positions``, those of the header's grid): a bake stopped between writing a probe
    and rewriting the header loses no finished probe. Returns the indices taken back."""
    taken = []
    for path in sorted(Path(folder).glob("probe_*.npz")):
        try:
            index = int(path.stem.split("_", 1)[1])
        except ValueError:
            continue
        if str(index) in header["probes"] or not 0 <= index < header["probe_count"]:
            continue
        try:
            with load_arrays(path) as data:
                record = json.loads(str(data["record"]))
            if not isinstance(record, dict) or record.get("file") != path.name:
                continue
            trial = {**header, "probes": {str(index): record}}
            read_probe(folder, index, trial, positions)
        except (OSError, ValueError, KeyError, EOFError, zipfile.BadZipFile, zlib.error,
                ProbeStorageError):
            continue
        header["probes"][str(index)] = record
        taken.append(index)
    return taken


def _probe_arrays(maps) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    return (np.ascontiguousarray(maps.radiance, np.float16),
            np.ascontiguousarray(maps.distance, np.float32),
            np.ascontiguousarray(maps.normal, np.int16))


def read_probe(folder: Path, index: int, header: dict,
               positions: np.ndarray) -> tuple[np.ndarray, ...]:
    """One probe's (radiance, distance, normal), checked against the header's record and
    against ``positions`` (those of the header's grid)."""
    record = header["probes"].get(str(index))
    if record is None:
        raise ProbeFileError(f"{folder}: probe {index} was never finished; resume the bake "
                             "(run the same voxfield bake again)")
    if not isinstance(record, dict):
        raise ProbeHeaderError(f"{Path(folder) / HEADER_NAME}: probe {index}'s record is "
                               f"{record!r}, not an object; resume the bake to re-bake it")
    name = str(record.get("file", probe_file_name(index)))
    if name != probe_file_name(index):  # records swapped or edited: another probe's maps
        raise ProbeFileError(f"{Path(folder) / HEADER_NAME}: probe {index}'s record names "
                             f"{name!r}, not its own file; resume the bake to re-bake it")
    check_position(folder, index, record, positions[index])
    path = Path(folder) / name
    if not path.is_file():
        raise ProbeFileError(f"{path}: probe {index}'s file is missing; resume the bake to "
                             "re-bake it")
    try:
        with load_arrays(path) as data:
            arrays = tuple(np.array(data[name]) for name in MAP_NAMES)
    except (OSError, ValueError, KeyError, EOFError, zipfile.BadZipFile, zlib.error) as exc:
        raise ProbeFileError(f"{path}: probe {index}'s file is corrupt ({exc}); resume the "
                             "bake to re-bake it") from exc
    for name, array in zip(MAP_NAMES, arrays, strict=True):
        spec = header["encodings"][name]
        if array.dtype != np.dtype(spec["dtype"]) or list(array.shape) != spec["shape"]:
            raise ProbeFileError(
                f"{path}: {name} is {array.dtype} {array.shape}, the header says "
                f"{spec['dtype']} {tuple(spec['shape'])}; resume the bake to re-bake it"
            )
    if maps_checksum(*arrays) != record.get("checksum"):
        raise ProbeFileError(f"{path}: probe {index}'s checksum does not match the header "
                             "(changed or damaged file); resume the bake to re-bake it")
    return arrays


def check_position(folder: Path, index: int, record: dict, expected: np.ndarray) -> None:
    """Refuse a probe recorded at another position than the grid's (within a rounding step
    of the coordinates: the header's JSON carries float64 exactly, but a grid rebuilt from
    its origin and spacing may round the last bit differently)."""
    if "position" not in record:  # baked before positions were recorded
        return
    try:
        recorded = np.asarray(record["position"], np.float64).reshape(3)
    except (TypeError, ValueError):
        recorded = None
    if recorded is None or not np.all(np.isfinite(recorded)):
        raise ProbeHeaderError(f"{Path(folder) / HEADER_NAME}: probe {index}'s position "
                               f"{record['position']!r} is not three finite numbers; re-bake "
                               "with --fresh")
    if not np.allclose(recorded, expected, rtol=1e-12, atol=1e-9):
        def shown(point) -> str:
            return "(" + ", ".join(f"{v:.6g}" for v in point) + ")"
        raise ProbeHeaderError(
            f"{Path(folder) / HEADER_NAME}: probe {index} was baked at {shown(recorded)} but "
            f"the grid puts it at {shown(expected)} (the grid was changed after the bake); "
            "re-bake with --fresh"
        )


def verified_probes(folder: Path, header: dict, positions: np.ndarray) -> set[int]:
    """Indices of the probes whose file exists, loads, matches its recorded checksum and was
    baked where the header's grid puts it (``positions``)."""
    done = set()
    for key in list(header["probes"]):
        try:
            index = int(key)
            if not 0 <= index < header["probe_count"]:
                raise ValueError(index)
            read_probe(folder, index, header, positions)
        except (ValueError, ProbeStorageError):  # a bad record is re-baked
            continue
        done.add(index)
    return done


# --------------------------------------------------------------------------- opening


def open_probe_set(path: str | os.PathLike):
    """Load a complete probe-set folder as a ``ProbeSet``, checking every file.

    Raises ``ProbeHeaderError`` for a missing or foreign header and ``ProbeFileError`` for a
    missing, corrupt or mismatched probe file, each saying how to recover.
    """

    folder = path_value(path, "a probe-set folder")
    header = read_header(folder)
    grid = header_grid(folder, header)
    try:
        options = BakeOptions.from_dict(header["options"])
    except VoxfieldError:
        raise
    except (KeyError, TypeError, ValueError) as exc:
        raise ProbeHeaderError(f"{folder / HEADER_NAME}: bad options ({exc}); "
                               "re-bake with --fresh") from exc
    n = int(header["probe_count"])
    if grid.count != n or int(options.resolution) != header["resolution"]:
        raise ProbeHeaderError(f"{folder / HEADER_NAME}: probe_count/resolution disagree "
                               "with the grid and options; re-bake with --fresh")
    enabled = np.asarray(grid.enabled, bool).reshape(-1)
    missing = [i for i in range(n) if enabled[i] and str(i) not in header["probes"]]
    if missing:
        shown = ", ".join(map(str, missing[:8])) + (" ..." if len(missing) > 8 else "")
        raise ProbeFileError(f"{folder}: {len(missing)} of {int(enabled.sum())} probes are not "
                             f"baked yet ({shown}); resume the bake (run the same voxfield "
                             "bake again)")
    positions = grid.positions
    probes = [_load_maps(folder, i, header, positions) if enabled[i] else None
              for i in range(n)]
    return ProbeSet.assemble(grid, options, probes, header["scene"]["fingerprint"])


def header_grid(folder: Path, header: dict) -> ProbeGrid:
    """The header's probe grid, or a ``ProbeHeaderError`` saying why it is not one."""
    try:
        return ProbeGrid.from_dict(header["grid"])
    except VoxfieldError:
        raise
    except (KeyError, TypeError, ValueError) as exc:
        raise ProbeHeaderError(f"{Path(folder) / HEADER_NAME}: bad grid ({exc}); "
                               "re-bake with --fresh") from exc


def _load_maps(folder: Path, index: int, header: dict, positions: np.ndarray):
    """Probe ``index`` as ``ProbeMaps``, its cost taken from the header's record."""
    record = header["probes"][str(index)]
    try:
        cost = BakeCost.from_record(record)
    except (KeyError, TypeError, ValueError) as exc:
        raise ProbeHeaderError(f"{Path(folder) / HEADER_NAME}: probe {index}'s record has no "
                               f"valid cost ({exc}); re-bake with --fresh") from exc
    return ProbeMaps(*read_probe(folder, index, header, positions), cost)


# --------------------------------------------------------------------------- atlases


def atlas_layout(count: int) -> tuple[int, int]:
    """(columns, rows) of a near-square atlas holding ``count`` tiles."""
    columns = max(1, math.ceil(math.sqrt(count)))
    return columns, max(1, math.ceil(count / columns))


def atlas(maps: np.ndarray, fill: float = 0.0) -> np.ndarray:
    """Tile (N, R, R[, C]) probe maps into one image of bordered (R + 2)² tiles."""
    n, r = maps.shape[0], maps.shape[1]
    channels = maps.shape[3:]
    # add_border works on the last two axes: move channels first and back again.
    bordered = np.moveaxis(add_border(np.moveaxis(maps, (1, 2), (-2, -1))), (-2, -1), (1, 2))
    columns, rows = atlas_layout(n)
    tile = r + 2
    out = np.full((rows * tile, columns * tile) + channels, fill, maps.dtype)
    for i in range(n):
        row, col = divmod(i, columns)
        out[row * tile:(row + 1) * tile, col * tile:(col + 1) * tile] = bordered[i]
    return out


def write_atlases(folder: Path, radiance, distance, normal) -> dict:
    """Write the engine-facing EXR atlases; returns their header description."""
    # optional: OpenEXR loads only when an EXR file is read or written
    import OpenEXR

    normal_float = normal.astype(np.float32) / np.float32(32767.0)
    images = {
        "radiance": {"RGB": atlas(np.asarray(radiance, np.float16))},
        "distance": {"Z": atlas(np.asarray(distance, np.float32), fill=np.inf)},
        "normal": {"U": atlas(normal_float[..., 0]), "V": atlas(normal_float[..., 1])},
    }
    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
    for name, channels in images.items():
        data = {k: np.ascontiguousarray(v) for k, v in channels.items()}
        with atomic_path(Path(folder) / ATLAS_FILES[name]) as tmp, \
                OpenEXR.File(header, data) as f:
            f.write(str(tmp))
    columns, rows = atlas_layout(radiance.shape[0])
    return {"columns": columns, "rows": rows, "tile": int(radiance.shape[1]) + 2, "border": 1,
            "files": dict(ATLAS_FILES),
            "channels": {"radiance": "RGB half", "distance": "Z float",
                         "normal": "U, V float (octahedral, [-1, 1])"}}


def clear_folder(folder: Path) -> None:
    """Remove what a bake wrote (header, probe files, atlases), nothing else."""
    if not folder.is_dir():
        return
    for path in folder.glob("probe_*.npz"):
        path.unlink()
    for name in (HEADER_NAME, *ATLAS_FILES.values()):
        (folder / name).unlink(missing_ok=True)
