"""Error table files (``save_error_table`` / ``load_error_table``) and the packaged table.

Pins: save → load round trip (``raw`` to float16 precision, everything else exact, and a
second round trip bit-exact); a missing file names the rebuild command; truncated or
bit-flipped files raise ErrorTableError and nothing else, and a flip that loads changed
nothing; arrays altered under a kept header fail the checksum, and a table edited and summed
again must still hold finite numbers of the right shapes under a well-formed header; a file
that is no table is told how to make one, not to be written over; the packaged table records its
build parameters and is reproducible from them (checked on a slice of its directions and
texels, since the full 2048 directions × 512² rebuild takes ~15 s), and two small builds with
the same parameters are identical.
"""

from __future__ import annotations

import io
import json
import zipfile

import numpy as np
import pytest

from voxfield.error_table import (
    ErrorTableError,
    build_error_table,
    load_error_table,
    raycast_errors,
    save_error_table,
)
from voxfield.error_table.directions import fibonacci_directions
from voxfield.error_table.table import _checksum
from voxfield.errors import VoxfieldError
from voxfield.kernels.octahedral import texel_directions

SMALL = {"n_directions": 64, "resolution": 64, "oct_resolution": 8, "seed": 3}


@pytest.fixture(scope="module")
def small():
    return build_error_table(**SMALL)


@pytest.fixture(scope="module")
def small_file(small, tmp_path_factory):
    return save_error_table(small, tmp_path_factory.mktemp("table") / "small.npz")


@pytest.fixture(scope="module")
def packaged():
    return load_error_table()


def _same(a, b) -> bool:
    return (
        np.array_equal(a.directions, b.directions) and np.array_equal(a.raw, b.raw)
        and np.array_equal(a.sh, b.sh) and np.array_equal(a.oct_map, b.oct_map)
        and a.params == b.params and a.default_encoding == b.default_encoding
    )


def test_round_trip(small, small_file, tmp_path):
    loaded = load_error_table(small_file)
    assert np.array_equal(loaded.directions, small.directions)
    assert loaded.directions.dtype == np.float64
    assert np.array_equal(loaded.sh, small.sh)
    assert np.array_equal(loaded.oct_map, small.oct_map)
    assert loaded.params == small.params
    assert loaded.default_encoding == small.default_encoding
    # raw is stored as float16: within half a float16 ulp of values in [0, 1] (2^-12).
    assert loaded.raw.shape == small.raw.shape
    assert np.abs(loaded.raw - small.raw).max() <= 2.0**-12
    # A second round trip changes nothing at all.
    again = load_error_table(save_error_table(loaded, tmp_path / "again.npz"))
    assert _same(again, loaded)
    assert np.array_equal(
        again.error(np.arange(256)[:, None], small.directions[None, :8]),
        small.error(np.arange(256)[:, None], small.directions[None, :8]),
    )


def test_missing_file_names_the_rebuild_command(tmp_path):
    with pytest.raises(ErrorTableError, match="voxfield errors build") as info:
        load_error_table(tmp_path / "nope.npz")
    assert isinstance(info.value, VoxfieldError)
    assert "nope.npz" in str(info.value)


@pytest.mark.parametrize("fraction", [0.0, 0.001, 0.05, 0.5, 0.9, 0.999])
def test_truncated_copies_raise(small_file, tmp_path, fraction):
    data = small_file.read_bytes()
    cut = tmp_path / "cut.npz"
    cut.write_bytes(data[: int(len(data) * fraction)])
    with pytest.raises(ErrorTableError, match="voxfield errors build"):
        load_error_table(cut)


def _flip_positions(data: bytes) -> list[int]:
    """Byte offsets to corrupt: the start of every zip member (local header, deflate block
    header), a spread through the payload, and the central directory."""
    zf = zipfile.ZipFile(io.BytesIO(data))
    positions = set()
    for info in zf.infolist():
        start = info.header_offset
        positions.update(range(start, start + 30 + len(info.filename) + 48, 3))
    positions.update(np.linspace(0, len(data) - 1, 60).astype(int).tolist())
    central = data.rfind(b"PK\x01\x02", 0, len(data))
    first_central = data.find(b"PK\x01\x02")
    positions.update(range(first_central, central + 46, 2))
    positions.update(range(len(data) - 22, len(data)))
    return sorted(p for p in positions if 0 <= p < len(data))


def _load_flipped(data: bytes, positions, path):
    """(escapes, changed): non-ErrorTableError exceptions, and flips that loaded different
    contents than the original."""
    reference = load_error_table(path)
    escapes, changed = [], []
    flipped = path.with_name("flipped.npz")
    for pos in positions:
        corrupt = bytearray(data)
        corrupt[pos] ^= 0x01
        flipped.write_bytes(bytes(corrupt))
        try:
            loaded = load_error_table(flipped)
        except ErrorTableError:
            continue
        except Exception as exc:  # noqa: BLE001 - the point is to see any other kind
            escapes.append((pos, type(exc).__name__, str(exc)[:60]))
            continue
        if not _same(loaded, reference):
            changed.append(pos)
    return escapes, changed


@pytest.fixture(scope="module")
def flip_outcomes(small_file):
    data = small_file.read_bytes()
    return _load_flipped(data, _flip_positions(data), small_file)


def test_bit_flips_never_load_altered_contents(flip_outcomes):
    _, changed = flip_outcomes
    assert changed == []


def test_bit_flips_raise_only_error_table_error(flip_outcomes):
    escapes, _ = flip_outcomes
    assert escapes == [], f"{len(escapes)} escapes, e.g. {escapes[:4]}"


def _rewrite(path, out, **replace):
    with np.load(path) as data:
        arrays = {k: data[k] for k in data.files}
    arrays.update(replace)
    with open(out, "wb") as f:
        np.savez_compressed(f, **arrays)
    return out


def test_altered_arrays_under_a_kept_header_fail_the_checksum(small_file, tmp_path):
    with np.load(small_file) as data:
        oct_map = data["oct_map"].copy()
        raw = data["raw"].copy()
        header = json.loads(bytes(data["header"]).decode())
    assert len(header["sha256"]) == 64
    oct_map[17, 3, 4] += np.float32(0.125)
    raw[200, 5] = np.float16(0.5) if raw[200, 5] != 0.5 else np.float16(0.25)
    for name, arr in (("oct_map", oct_map), ("raw", raw)):
        altered = _rewrite(small_file, tmp_path / f"{name}.npz", **{name: arr})
        with pytest.raises(ErrorTableError, match="checksum") as info:
            load_error_table(altered)
        assert "voxfield errors build" in str(info.value)
    # Rewriting unchanged arrays keeps a loadable file (the checksum covers content only).
    assert _same(load_error_table(_rewrite(small_file, tmp_path / "same.npz")),
                 load_error_table(small_file))


def test_wrong_format_or_version_is_rejected(small_file, tmp_path):
    with np.load(small_file) as data:
        header = json.loads(bytes(data["header"]).decode())
    for key, value in (("version", header["version"] + 1), ("format", "something-else")):
        bad = dict(header, **{key: value})
        out = _rewrite(small_file, tmp_path / f"{key}.npz",
                       header=np.frombuffer(json.dumps(bad).encode(), np.uint8))
        with pytest.raises(ErrorTableError):
            load_error_table(out)
    not_a_table = tmp_path / "other.npz"
    np.savez(not_a_table, x=np.arange(3))
    with pytest.raises(ErrorTableError):
        load_error_table(not_a_table)


def _resummed(path, out, header_changes=None, **arrays):
    """``path`` with ``arrays`` replaced and its checksum made to match them again: what a
    hand-edited table looks like, which the checksum alone cannot refuse."""
    with np.load(path) as data:
        stored = {k: data[k] for k in data.files}
    header = json.loads(bytes(stored.pop("header")).decode())
    stored.update(arrays)
    header.update(header_changes or {})
    header["sha256"] = _checksum({k: stored[k] for k in ("directions", "raw", "sh", "oct_map")})
    np.savez_compressed(out, header=np.frombuffer(json.dumps(header).encode(), np.uint8),
                        **stored)
    return out


@pytest.mark.parametrize("change, words", [
    ({"oct_map": "nan"}, "not finite"),
    ({"sh": "inf"}, "not finite"),
    ({"oct_map": np.zeros((256, 0, 0), np.float32)}, "octahedral map"),
    ({"directions": np.zeros((64, 2))}, "inconsistent array shapes"),
    ({"header": {"params": [1, 2]}}, "malformed header"),
    ({"header": {"params": {"resolution": "x"}}}, "malformed header"),
    ({"header": {"params": {"seed": -1}}}, "malformed header"),
    ({"header": {"default_encoding": "zip"}}, "unknown default encoding"),
])
def test_a_table_edited_and_summed_again_is_refused(change, words, small_file, tmp_path):
    """Each of these loaded before and ended later in a traceback (an int() of the header's
    resolution, a list where a dict was read) or drew blank error spheres (NaN maps)."""
    arrays = {}
    with np.load(small_file) as data:
        for key, value in change.items():
            if isinstance(value, str):
                arrays[key] = np.full_like(data[key], np.float32(value))
            elif key != "header":
                arrays[key] = value
    out = _resummed(small_file, tmp_path / "edited.npz", change.get("header"), **arrays)
    with pytest.raises(ErrorTableError, match=words) as info:
        load_error_table(out)
    assert "voxfield errors build --out" in str(info.value)


def test_a_file_that_is_no_table_is_told_how_to_make_one_not_to_be_overwritten(tmp_path):
    for name, content in (("scene.vox", b"VOX \x96\x00\x00\x00"), ("octree.npz", None)):
        path = tmp_path / name
        if content is None:
            np.savez(path, header=np.frombuffer(b'{"format": "voxfield-octree"}', np.uint8))
        else:
            path.write_bytes(content)
        with pytest.raises(ErrorTableError, match="is not an error table") as info:
            load_error_table(path)
        assert "make one with `voxfield errors build`" in str(info.value)
        assert "--out" not in str(info.value)


def test_same_parameters_build_identical_tables(small, tmp_path):
    again = build_error_table(**SMALL)
    assert np.array_equal(again.raw, small.raw)
    assert np.array_equal(again.sh, small.sh)
    assert np.array_equal(again.oct_map, small.oct_map)
    assert again.params == small.params
    # a rebuilt table's file is the same bytes (a shipped table rebuilt leaves git clean)
    first, second = tmp_path / "first.npz", tmp_path / "second.npz"
    save_error_table(small, first)
    save_error_table(again, second)
    assert first.read_bytes() == second.read_bytes()
    other_seed = build_error_table(**dict(SMALL, seed=SMALL["seed"] + 1))
    assert not np.array_equal(other_seed.raw, small.raw)


def test_packaged_table_records_its_parameters(packaged):
    p = packaged.params
    assert p["n_directions"] >= 1024
    assert p["resolution"] == 512  # EA §3.2's framebuffer
    assert p["oct_resolution"] == packaged.oct_resolution >= 8
    assert isinstance(p["seed"], int)
    assert p["direction_set"] == "fibonacci"
    assert packaged.directions.shape == (p["n_directions"], 3)
    assert np.allclose(np.linalg.norm(packaged.directions, axis=1), 1.0)
    assert np.array_equal(packaged.directions, fibonacci_directions(p["n_directions"]))
    assert packaged.raw.shape == (256, p["n_directions"])
    assert packaged.sh.shape == (256, 9)
    r = p["oct_resolution"]
    assert packaged.oct_map.shape == (256, r + 2, r + 2)


def test_packaged_table_is_reproducible_from_its_parameters(packaged):
    """Re-ray-cast a slice of the recorded directions and texels at the recorded resolution and
    seed: raw must match to float16 rounding, the octahedral interior exactly (float32)."""
    p = packaged.params
    picks = np.linspace(0, p["n_directions"] - 1, 48).astype(int)
    fresh = raycast_errors(packaged.directions[picks], p["resolution"], p["seed"])
    stored = fresh.astype(np.float32).astype(np.float16)  # as build + save round them
    assert np.array_equal(stored.astype(np.float32), packaged.raw[:, picks])
    r = p["oct_resolution"]
    texel_picks = np.linspace(0, r * r - 1, 48).astype(int)
    fresh_oct = raycast_errors(texel_directions(r)[texel_picks], p["resolution"], p["seed"])
    interior = packaged.oct_map[:, 1:-1, 1:-1].reshape(256, -1)[:, texel_picks]
    assert np.array_equal(fresh_oct.astype(np.float32), interior)


def test_packaged_sh_is_the_fit_of_its_raw(packaged):
    """SH coefficients are the least-squares fit of the float64 raw errors; the file keeps raw
    as float16, so refitting the stored raw may differ by the fit of ≤2.4e-4 perturbations."""
    x, y, z = packaged.directions.T
    basis = np.stack([
        np.full_like(x, 0.5 / np.sqrt(np.pi)),
        *(np.sqrt(3 / (4 * np.pi)) * c for c in (y, z, x)),
        np.sqrt(15 / (4 * np.pi)) * x * y,
        np.sqrt(15 / (4 * np.pi)) * y * z,
        np.sqrt(5 / (16 * np.pi)) * (3 * z * z - 1),
        np.sqrt(15 / (4 * np.pi)) * x * z,
        np.sqrt(15 / (16 * np.pi)) * (x * x - y * y),
    ], axis=1)
    coeffs, *_ = np.linalg.lstsq(basis, packaged.raw.astype(np.float64).T, rcond=None)
    assert np.abs(coeffs.T - packaged.sh).max() < 1e-3, np.abs(coeffs.T - packaged.sh).max()
