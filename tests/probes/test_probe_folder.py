"""Probe-set folders: round trip, atomic writes, resume, and clear errors for bad folders."""

from __future__ import annotations

import json

import numpy as np
import pytest

from voxfield.errors import VoxfieldError
from voxfield.json_output import to_json
from voxfield.probes import probe_folder
from voxfield.probes.bake import bake_probe, bake_probes
from voxfield.probes.folder_bake import bake_to_folder
from voxfield.probes.grid import ProbeGrid
from voxfield.probes.probe_folder import (
    ProbeFileError,
    ProbeHeaderError,
    ProbeSetMismatchError,
    open_probe_set,
)
from voxfield.probes.probe_set import BakeOptions, ProbeMaps
from voxfield.scene.builtin import cornell
from voxfield.svo.build import build_octree

OPTIONS = BakeOptions(resolution=8, renderer="lod", lod=0)


@pytest.fixture(scope="module")
def grid(octree):
    lo, hi = octree.voxel_bounds
    return ProbeGrid.fit(lo, hi, (3, 1, 2))


@pytest.fixture(scope="module")
def local(octree, grid):
    """The plain in-memory loop: what every folder must read back as."""
    return bake_probes(octree, grid, OPTIONS)


class Counting:
    """``bake_probe`` that records which probes it baked (by position)."""

    def __init__(self, fail_after: int | None = None) -> None:
        self.positions: list[tuple] = []
        self.fail_after = fail_after

    def __call__(self, octree, position, options, threads=None) -> ProbeMaps:
        if self.fail_after is not None and len(self.positions) >= self.fail_after:
            raise KeyboardInterrupt  # a bake killed part-way
        self.positions.append(tuple(np.asarray(position).tolist()))
        return bake_probe(octree, position, options, threads=threads)

    def indices(self, grid) -> list[int]:
        positions = [tuple(p) for p in grid.positions.tolist()]
        return sorted(positions.index(p) for p in self.positions)


def assert_same(a, b) -> None:
    for name in ("radiance", "distance", "normal", "enabled", "positions"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name), err_msg=name)
    for key in a.cost:
        if not key.endswith("seconds"):
            np.testing.assert_array_equal(a.cost[key], b.cost[key], err_msg=key)
    assert a.fingerprint == b.fingerprint


def test_round_trip_and_format(tmp_path, octree, grid, local):
    folder = tmp_path / "probes"
    baked = bake_to_folder(octree, grid, OPTIONS, folder, scheduler="serial")
    assert_same(baked, local)
    assert_same(open_probe_set(folder), local)

    header = json.loads((folder / "probes.json").read_text())
    assert header["format"] == "voxfield-probes" and header["version"] == 1
    assert header["complete"] and header["probe_count"] == grid.count == 6
    assert ProbeGrid.from_dict(header["grid"]) == grid
    assert BakeOptions.from_dict(header["options"]) == OPTIONS
    assert header["encodings"]["normal"]["dtype"] == "int16"
    assert sorted(p.name for p in folder.glob("probe_*.npz")) == [
        f"probe_{i:05d}.npz" for i in range(6)]

    from voxfield.kernels.octahedral import add_border
    from voxfield.render.image_io import load_exr

    atlas = header["atlas"]
    assert (atlas["columns"], atlas["rows"], atlas["tile"]) == (3, 2, 10)
    distance = load_exr(folder / "distance.exr")["Z"]
    radiance = load_exr(folder / "radiance.exr")["RGB"]
    assert distance.shape == (20, 30) and radiance.dtype == np.float16
    # Probe 4 sits at tile (1, 1), with its octahedral border.
    np.testing.assert_array_equal(distance[10:20, 10:20], add_border(local.distance[4]))
    np.testing.assert_array_equal(radiance[10:20, 10:20, 1],
                                  add_border(local.radiance[4, ..., 1]))


def test_disabled_probes_have_no_file(tmp_path, octree, grid):
    enabled = np.ones(grid.count, bool)
    enabled[[1, 4]] = False
    sparse = grid.with_enabled(enabled)
    baked = bake_to_folder(octree, sparse, OPTIONS, tmp_path, scheduler="serial")
    assert not (tmp_path / "probe_00001.npz").exists()
    assert_same(open_probe_set(tmp_path), bake_probes(octree, sparse, OPTIONS))
    assert baked.enabled.tolist() == enabled.tolist()
    assert np.isinf(baked.distance[4]).all()


def test_resume_rebakes_only_missing_and_corrupt(tmp_path, octree, grid, local):
    bake_to_folder(octree, grid, OPTIONS, tmp_path, scheduler="serial")
    (tmp_path / "probe_00001.npz").unlink()
    (tmp_path / "probe_00004.npz").unlink()
    path = tmp_path / "probe_00002.npz"
    path.write_bytes(path.read_bytes()[:40])  # truncated
    with pytest.raises(ProbeFileError, match="missing"):
        open_probe_set(tmp_path)

    counting = Counting()
    resumed = bake_to_folder(octree, grid, OPTIONS, tmp_path, scheduler="serial",
                             baker=counting)
    assert counting.indices(grid) == [1, 2, 4]
    assert_same(resumed, local)
    header = json.loads((tmp_path / "probes.json").read_text())
    assert header["last_run"]["baked"] == 3 and header["last_run"]["reused"] == 3

    again = Counting()
    bake_to_folder(octree, grid, OPTIONS, tmp_path, scheduler="serial", baker=again)
    assert again.positions == []


def test_a_probe_damaged_in_its_record_or_shape_is_rebaked_by_a_resume_as_it_says(
        tmp_path, octree, grid, local):
    """A probe whose record is not an object, or whose maps have another shape than the
    header's, is one damaged probe: a resume re-bakes it (``verified_probes``), so its
    message says so, where it advised --fresh, which re-bakes every probe."""
    bake_to_folder(octree, grid, OPTIONS, tmp_path, scheduler="serial")
    header_path = tmp_path / "probes.json"
    header = json.loads(header_path.read_text())
    header["probes"]["3"] = "damaged"
    small = (np.zeros((4, 4, 3), np.float16), np.zeros((4, 4), np.float32),
             np.zeros((4, 4, 2), np.int16))
    np.savez(tmp_path / "probe_00001.npz", radiance=small[0], distance=small[1],
             normal=small[2])
    header["probes"]["1"]["checksum"] = probe_folder.maps_checksum(*small)
    header_path.write_text(json.dumps(header))
    with pytest.raises(ProbeFileError, match=r"radiance is float16 \(4, 4, 3\).*; resume the bake"):
        probe_folder.read_probe(tmp_path, 1, header, grid.positions)
    with pytest.raises(ProbeHeaderError, match="not an object; resume the bake"):
        probe_folder.read_probe(tmp_path, 3, header, grid.positions)

    counting = Counting()
    resumed = bake_to_folder(octree, grid, OPTIONS, tmp_path, scheduler="serial",
                             baker=counting)
    assert counting.indices(grid) == [1, 3]
    assert_same(resumed, local)


def test_killed_bake_leaves_whole_files_and_resumes(tmp_path, octree, grid, local):
    with pytest.raises(KeyboardInterrupt):
        bake_to_folder(octree, grid, OPTIONS, tmp_path, scheduler="serial",
                       baker=Counting(fail_after=2))
    names = sorted(p.name for p in tmp_path.iterdir())
    assert names == ["probe_00000.npz", "probe_00001.npz", "probes.json"]  # no temp files
    header = probe_folder.read_header(tmp_path)
    assert sorted(header["probes"]) == ["0", "1"] and not header["complete"]
    # what the run did, not what it set out to do (it said 6 baked)
    assert header["last_run"]["baked"] == 2 and header["last_run"]["reused"] == 0

    counting = Counting()
    assert_same(bake_to_folder(octree, grid, OPTIONS, tmp_path, scheduler="serial",
                               baker=counting), local)
    assert counting.indices(grid) == [2, 3, 4, 5]


def test_probes_the_header_missed_are_taken_back_not_rebaked(tmp_path, octree, grid, local):
    """A bake killed between writing probe files and rewriting the header (SIGKILL, a
    power cut): the files that verify are taken back on resume, only the rest are baked."""
    bake_to_folder(octree, grid, OPTIONS, tmp_path, scheduler="serial")
    header = probe_folder.read_header(tmp_path)
    for key in ("1", "3", "5"):
        del header["probes"][key]
    header["complete"] = False
    probe_folder.write_header(tmp_path, header)
    damaged = tmp_path / "probe_00005.npz"
    damaged.write_bytes(damaged.read_bytes()[:60])  # this one did not survive
    counting = Counting()
    resumed = bake_to_folder(octree, grid, OPTIONS, tmp_path, scheduler="serial",
                             baker=counting)
    assert counting.indices(grid) == [5]
    assert_same(resumed, local)
    header = json.loads((tmp_path / "probes.json").read_text())
    assert header["last_run"]["reused"] == 5 and header["complete"]


def test_failed_write_leaves_no_partial_file(tmp_path, monkeypatch, local):
    def broken(file, **arrays):
        file.write(b"PK\x03\x04 half a zip")
        raise OSError("disk full")

    monkeypatch.setattr(probe_folder.np, "savez_compressed", broken)
    with pytest.raises(OSError, match="disk full"):
        probe_folder.write_probe(tmp_path, 3, local.probe(3), local.positions[3])
    assert list(tmp_path.iterdir()) == []


def test_other_scene_or_options_refused_unless_fresh(tmp_path, octree, grid):
    bake_to_folder(octree, grid, OPTIONS, tmp_path, scheduler="serial")
    other_options = BakeOptions(resolution=8, renderer="lod", lod=1)
    with pytest.raises(ProbeSetMismatchError, match=r"bake options \(lod\)"):
        bake_to_folder(octree, grid, other_options, tmp_path, scheduler="serial")
    other_scene = build_octree(cornell(12))
    with pytest.raises(ProbeSetMismatchError, match="scene"):
        bake_to_folder(other_scene, grid, OPTIONS, tmp_path, scheduler="serial")
    moved = grid.with_offsets(np.full((grid.count, 3), 0.5))
    with pytest.raises(ProbeSetMismatchError, match="grid"):
        bake_to_folder(octree, moved, OPTIONS, tmp_path, scheduler="serial")

    fresh = bake_to_folder(octree, grid, other_options, tmp_path, scheduler="serial",
                           fresh=True)
    assert_same(fresh, bake_probes(octree, grid, other_options))


def test_options_the_octree_cannot_bake_are_refused_before_the_folder_is_written(
        tmp_path, octree, grid):
    """`voxfield bake --lod 99` was refused after it had written the folder's header, whose
    options then refused the corrected run (--lod 2: "holds probes baked with other bake
    options (lod)") until --fresh; now nothing is written and the corrected run bakes."""
    folder = tmp_path / "probes"
    too_deep = BakeOptions(resolution=8, renderer="lod", lod=octree.depth + 1)
    with pytest.raises(VoxfieldError, match="deeper than this octree allows"):
        bake_to_folder(octree, grid, too_deep, folder, scheduler="serial")
    assert not folder.exists()
    corrected = BakeOptions(resolution=8, renderer="lod", lod=1)
    baked = bake_to_folder(octree, grid, corrected, folder, scheduler="serial")
    assert_same(baked, bake_probes(octree, grid, corrected))


def test_bad_folders_give_clear_errors(tmp_path, octree, grid):
    with pytest.raises(ProbeHeaderError, match="no such probe-set folder"):
        open_probe_set(tmp_path / "nowhere")
    with pytest.raises(ProbeHeaderError, match="no probes.json"):
        open_probe_set(tmp_path)

    bake_to_folder(octree, grid, OPTIONS, tmp_path, scheduler="serial")
    header_path = tmp_path / "probes.json"
    good = header_path.read_text()

    header_path.write_text(good[: len(good) // 2])
    with pytest.raises(ProbeHeaderError, match="unreadable"):
        open_probe_set(tmp_path)
    with pytest.raises(ProbeHeaderError, match="unreadable"):  # a bake will not guess either
        bake_to_folder(octree, grid, OPTIONS, tmp_path, scheduler="serial")

    header = json.loads(good)
    header_path.write_text(json.dumps({**header, "version": 99}))
    with pytest.raises(ProbeHeaderError, match="version 99"):
        open_probe_set(tmp_path)
    header_path.write_text(json.dumps({**header, "format": "something-else"}))
    with pytest.raises(ProbeHeaderError, match="not a voxfield-probes header"):
        open_probe_set(tmp_path)
    header_path.write_text(good)

    # A whole, valid file with other content: caught by the checksum.
    probe0 = tmp_path / "probe_00000.npz"
    original = probe0.read_bytes()
    probe0.write_bytes((tmp_path / "probe_00001.npz").read_bytes())
    with pytest.raises(ProbeFileError, match="checksum"):
        open_probe_set(tmp_path)

    # Arrays of the wrong shape, even with a matching checksum: caught by the encodings.
    small = (np.zeros((4, 4, 3), np.float16), np.zeros((4, 4), np.float32),
             np.zeros((4, 4, 2), np.int16))
    np.savez(probe0, radiance=small[0], distance=small[1], normal=small[2])
    header["probes"]["0"]["checksum"] = probe_folder.maps_checksum(*small)
    header_path.write_text(json.dumps(header))
    with pytest.raises(ProbeFileError, match=r"radiance is float16 \(4, 4, 3\)"):
        open_probe_set(tmp_path)

    probe0.write_bytes(original[:-30])
    header_path.write_text(good)
    with pytest.raises(ProbeFileError, match="corrupt"):
        open_probe_set(tmp_path)
    # Not an archive at all: NumPy took it for a pickle and advised loading it "unsafely".
    for damaged, words in ((b"x", "not a NumPy .npz file"), (b"", "empty")):
        probe0.write_bytes(damaged)
        with pytest.raises(ProbeFileError, match=f"corrupt .*{words}") as caught:
            open_probe_set(tmp_path)
        assert "pickle" not in str(caught.value)


def _edit_grid(folder, **changes) -> None:
    """Rewrite ``probes.json`` with its grid changed, as an editor would (records kept)."""
    header = json.loads((folder / "probes.json").read_text())
    header["grid"].update(changes)
    (folder / "probes.json").write_text(json.dumps(header))


def test_records_hold_the_positions_the_probes_were_baked_at(tmp_path, octree, grid):
    bake_to_folder(octree, grid, OPTIONS, tmp_path, scheduler="serial")
    header = json.loads((tmp_path / "probes.json").read_text())
    recorded = [header["probes"][str(i)]["position"] for i in range(grid.count)]
    np.testing.assert_array_equal(recorded, grid.positions)
    with np.load(tmp_path / "probe_00004.npz") as data:  # the file's own copy, for resumes
        assert json.loads(str(data["record"]))["position"] == recorded[4]


@pytest.mark.parametrize("changes", [
    {"origin": [1e6, 8.0, 8.0]},  # the whole grid moved
    {"spacing": [1.0, 1.0, 1.0]},  # squeezed: probe 0 stays, the others move
    {"offsets": [[0.0, 0.0, 0.0]] * 5 + [[0.0, 0.25, 0.0]]},  # one probe nudged
])
def test_a_grid_edited_after_the_bake_is_refused(tmp_path, octree, grid, local, changes):
    """The maps hold what was seen from where each probe stood; read at another position
    they would draw a plausible, wrong image with exit 0."""
    bake_to_folder(octree, grid, OPTIONS, tmp_path, scheduler="serial")
    _edit_grid(tmp_path, **changes)
    with pytest.raises(ProbeHeaderError, match=r"was baked at \(.*\) but the grid puts it at"):
        open_probe_set(tmp_path)


def test_an_edited_grid_is_rebaked_on_resume_not_reused(tmp_path, octree, grid):
    """Resuming with the edited grid matches the header's identity, so only the recorded
    positions tell that every finished probe stood elsewhere."""
    bake_to_folder(octree, grid, OPTIONS, tmp_path, scheduler="serial")
    moved = ProbeGrid(grid.origin + np.array([0.5, 0.0, 0.0]), grid.spacing, grid.counts)
    _edit_grid(tmp_path, **json.loads(json.dumps(to_json(moved.to_dict(), finite=False))))
    counting = Counting()
    resumed = bake_to_folder(octree, moved, OPTIONS, tmp_path, scheduler="serial",
                             baker=counting)
    assert counting.indices(moved) == list(range(moved.count))
    assert_same(resumed, bake_probes(octree, moved, OPTIONS))


def test_folders_baked_before_positions_were_recorded_still_open(tmp_path, octree, grid,
                                                                  local):
    bake_to_folder(octree, grid, OPTIONS, tmp_path, scheduler="serial")
    header = json.loads((tmp_path / "probes.json").read_text())
    for record in header["probes"].values():
        del record["position"]
    (tmp_path / "probes.json").write_text(json.dumps(header))
    assert_same(open_probe_set(tmp_path), local)


@pytest.mark.parametrize("position", ["here", [1.0, 2.0], [float("nan"), 0.0, 0.0], None])
def test_a_position_that_is_not_three_numbers_is_a_header_error(tmp_path, octree, grid,
                                                                position):
    bake_to_folder(octree, grid, OPTIONS, tmp_path, scheduler="serial")
    header = json.loads((tmp_path / "probes.json").read_text())
    header["probes"]["2"]["position"] = position
    (tmp_path / "probes.json").write_text(json.dumps(header))
    with pytest.raises(ProbeHeaderError, match="probe 2's position .* is not three finite"):
        open_probe_set(tmp_path)


@pytest.mark.parametrize("call", ["open", "bake", "probe"])
def test_the_entry_points_name_a_path_or_octree_of_the_wrong_kind(call, tmp_path):
    """``open_probe_set(None)`` and ``bake_to_folder(..., None)`` raised pathlib's
    TypeError, ``bake_probe(None, ...)`` an AttributeError from inside."""
    from voxfield.probes import open_probe_set
    from voxfield.probes.probe_set import BakeOptions
    from voxfield.scene.builtin import builtin_scene
    from voxfield.svo import build_octree

    octree = build_octree(builtin_scene("sphere"))
    options = BakeOptions(resolution=8)
    grid = ProbeGrid(origin=np.zeros(3), spacing=np.ones(3), counts=(1, 1, 1))
    attempt, words = {
        "open": (lambda: open_probe_set(None), "probe-set folder must be a path"),
        "bake": (lambda: bake_to_folder(octree, grid, options, 3),
                 "probe-set folder must be a path"),
        "probe": (lambda: bake_probe(None, (1.0, 1.0, 1.0), options), "needs a voxfield Octree"),
    }[call]
    with pytest.raises(VoxfieldError, match=words):
        attempt()
    assert list(tmp_path.iterdir()) == []
